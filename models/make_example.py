"""Generate the bundled example: a small right arm for ``fibres run`` with no arguments.

Run from the repository root (rewrites the committed files; the output is deterministic)::

    python models/make_example.py            # writes into models/
    python models/make_example.py OUTDIR     # writes a fresh copy elsewhere

What it writes (ground: y up, x anterior, z lateral; SI units):

- ``arm_example.osim``: OpenSim 4.0 model. ``humerus`` welded to ground with its frame equal to
  ground (shoulder at the origin); ``forearm`` on the ``elbow`` PinJoint (z axis through
  (0, -0.29, 0)), coordinate ``elbow_flexion`` in [0, 150] deg (flexion brings the hand forward,
  +x). A WrapCylinder ``elbow_wrap`` (radius 18 mm, axis z, quadrant -x) on the humerus at the
  elbow. Five Thelen2003Muscles: ``BIClong``, ``BICshort`` (biceps), ``BRA`` (brachialis),
  ``TRIlong``, ``TRIlat`` (triceps; both wrap ``elbow_wrap`` when the elbow flexes).
- ``meshes/humerus.stl``, ``meshes/forearm.stl``: bone surfaces in their body frames (displayed by
  OpenSim).
- ``meshes/biceps.ply``, ``meshes/brachialis.ply``, ``meshes/triceps.ply``: closed, smooth muscle
  surfaces (fusiform "spindles" with elliptic cross-sections) in ground at the rest pose
  (``elbow_flexion`` = 0), ~2k vertices each.
- ``<muscle>_origin.csv``, ``<muscle>_insertion.csv``: attachment landmarks (x, y, z; ground at
  rest): the surface vertices of each tip (pole and first two vertex rings).
- ``elbow_flexion.mot``: elbow flexion 0 -> 130 deg in 27 frames (inDegrees=yes, 0.05 s apart).
- ``arm_example.toml``: the fibre model (docs/INTERFACE.md): biceps ``parallel``, brachialis
  ``pennate``, triceps ``bipennate``.

The surfaces are swept tubes: rings of an ellipse along a (bowed) centre line, closed by one pole
vertex at each end; the radius profile ``(1 - |2 s - 1|^3)^0.4`` (s in [0, 1] along the muscle)
gives a full belly and blunt, rounded ends on which the attachment areas lie.
"""
from __future__ import annotations

import io
import math
import struct
import sys
from pathlib import Path

import numpy as np

from motion.osim.atomic_file import atomic_write

HERE = Path(__file__).resolve().parent
ELBOW = np.array([0.0, -0.29, 0.0])          # elbow axis position in humerus (= ground)
ELBOW_RANGE = (0.0, math.radians(150.0))
WRAP_RADIUS = 0.018
N_FRAMES = 27                                # 0, 5, ..., 130 degrees


# --------------------------------------------------------------------------- file writing
def _atomic_bytes(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (`motion.osim.atomic_file`), creating its folder."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path) as tmp:
        tmp.write_bytes(data)
    return path


def write_ply(path, vertices, faces) -> Path:
    """Binary little-endian PLY: float32 x y z, faces as uchar-counted int32 lists."""
    v = np.ascontiguousarray(vertices, dtype="<f4")
    f = np.asarray(faces, dtype="<i4")
    header = ("ply\nformat binary_little_endian 1.0\ncomment musclefibres example surface (m)\n"
              f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
              f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    rec = np.zeros(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rec["n"], rec["i"] = 3, f
    return _atomic_bytes(path, header.encode("ascii") + v.tobytes() + rec.tobytes())


def write_stl(path, vertices, faces) -> Path:
    """Binary STL (float32; facet normals from the vertex order)."""
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    rec = np.zeros(len(tri), dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = n, tri
    head = b"musclefibres example bone (m)".ljust(80, b" ")
    return _atomic_bytes(path, head + struct.pack("<I", len(tri)) + rec.tobytes())


def write_points_csv(path, points) -> Path:
    """CSV with header x,y,z; 9 significant digits (exact for float32 values)."""
    buf = io.StringIO()
    np.savetxt(buf, np.asarray(points, dtype=float).reshape(-1, 3), fmt="%.9g", delimiter=",",
               header="x,y,z", comments="")
    return _atomic_bytes(path, buf.getvalue().encode("ascii"))


def write_mot(path, name, coordinate, times, values_deg) -> Path:
    """OpenSim motion file (version 1 header, inDegrees=yes, tab separated)."""
    header = "\n".join([name, "version=1", f"nRows={len(times)}", "nColumns=2", "inDegrees=yes",
                        "endheader", f"time\t{coordinate}"])
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack([times, values_deg]), fmt=["%.8f", "%.10f"], delimiter="\t",
               header=header, comments="")
    return _atomic_bytes(path, buf.getvalue().encode("ascii"))


# --------------------------------------------------------------------------- surfaces
def tube_mesh(centres, radii, u, w, poles, *, n_around: int):
    """A closed tube: elliptic rings around a centre line, closed by two pole vertices.

    Parameters
    ----------
    centres : (S, 3) float
        Ring centres from the first pole to the last.
    radii : (S, 2) float
        Semi-axes of each ring along ``u`` and ``w``.
    u, w : (S, 3) float
        Orthonormal ring axes (perpendicular to the centre line); ``u x w`` points from the
        first pole towards the last, which makes the faces wind outward.
    poles : (2, 3) float
        First and last tip vertices.
    n_around : int
        Vertices per ring.

    Returns
    -------
    vertices : (S * n_around + 2, 3) float
    faces : (2 * S * n_around, 3) int
        Counter-clockwise seen from outside (outward normals).
    """
    s_count = len(centres)
    phi = 2.0 * np.pi * np.arange(n_around) / n_around
    ring = (centres[:, None, :] + radii[:, None, 0:1] * np.cos(phi)[None, :, None] * u[:, None, :]
            + radii[:, None, 1:2] * np.sin(phi)[None, :, None] * w[:, None, :])
    vertices = np.concatenate([ring.reshape(-1, 3), poles], axis=0)
    first, last = s_count * n_around, s_count * n_around + 1
    k = np.arange(n_around)
    k1 = (k + 1) % n_around
    j = np.arange(s_count - 1)[:, None]
    a, b = j * n_around + k, j * n_around + k1               # ring j
    c, d = a + n_around, b + n_around                        # ring j + 1
    quads = np.stack([np.stack([a, b, d], -1), np.stack([a, d, c], -1)], axis=2).reshape(-1, 3)
    cap0 = np.stack([np.full(n_around, first), k1, k], -1)
    cap1 = np.stack([np.full(n_around, last), (s_count - 1) * n_around + k,
                     (s_count - 1) * n_around + k1], -1)
    faces = np.concatenate([cap0, quads, cap1]).astype(np.int64)
    return vertices, faces


def _ring_params(n_rings: int):
    """Ring positions in (0, 1), somewhat denser at the tips (half uniform, half cosine)."""
    t = np.arange(1, n_rings + 1) / (n_rings + 1)
    return 0.5 * t + 0.25 * (1.0 - np.cos(np.pi * t))


def _frames_along(tangent, normal_hint):
    """Orthonormal (u, w) per ring with u closest to ``normal_hint`` and u x w = tangent."""
    t = tangent / np.linalg.norm(tangent, axis=1, keepdims=True)
    u = normal_hint - (t @ normal_hint)[:, None] * t
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(t, u)
    return u, w


def spindle(origin, insertion, *, r_max, aspect=1.0, bow=0.0, bow_dir=(1.0, 0.0, 0.0),
            n_rings=40, n_around=48):
    """A fusiform muscle surface from ``origin`` to ``insertion`` (tips at those points).

    ``r_max`` is the belly semi-axis along the bow direction, ``aspect`` the ratio of the other
    semi-axis to it; ``bow`` displaces the centre line by ``bow * sin(pi s)`` along ``bow_dir``.
    Returns ``(vertices (V, 3), faces (T, 3))``.
    """
    o, i = np.asarray(origin, float), np.asarray(insertion, float)
    axis = i - o
    hint = np.asarray(bow_dir, float)
    hint = hint - (hint @ axis) / (axis @ axis) * axis
    hint /= np.linalg.norm(hint)
    s = _ring_params(n_rings)
    centres = o + s[:, None] * axis + (bow * np.sin(np.pi * s))[:, None] * hint
    tangent = axis + (bow * np.pi * np.cos(np.pi * s))[:, None] * hint
    u, w = _frames_along(tangent, hint)
    rho = r_max * (1.0 - np.abs(2.0 * s - 1.0) ** 3) ** 0.4
    radii = np.stack([rho, aspect * rho], axis=1)
    return tube_mesh(centres, radii, u, w, np.stack([o, i]), n_around=n_around)


def bone(top, bottom, knots, *, n_rings=24, n_around=20):
    """A bone-like closed tube from ``top`` to ``bottom`` (both on the y axis of its body).

    ``knots`` is (K, 3): rows ``(s, r_x, r_z)``; radii are interpolated linearly in s and
    rounded to zero at the tips (within 8 % of the length) by a square-root factor.
    """
    top, bottom = np.asarray(top, float), np.asarray(bottom, float)
    s = _ring_params(n_rings)
    centres = top + s[:, None] * (bottom - top)
    knots = np.asarray(knots, float)
    rx = np.interp(s, knots[:, 0], knots[:, 1])
    rz = np.interp(s, knots[:, 0], knots[:, 2])
    tip = np.sqrt(np.clip(np.sin(np.pi * s) / np.sin(np.pi * 0.08), 0.0, 1.0))
    radii = np.stack([rx * tip, rz * tip], axis=1)
    tangent = np.broadcast_to(bottom - top, centres.shape)
    u, w = _frames_along(tangent, np.array([1.0, 0.0, 0.0]))
    return tube_mesh(centres, radii, u, w, np.stack([top, bottom]), n_around=n_around)


def tip_landmarks(vertices, n_around, n_rings, end: str, *, rings: int = 2):
    """The pole vertex and the first ``rings`` rings at one end of a ``tube_mesh``."""
    if end == "first":
        idx = [n_rings * n_around] + list(range(rings * n_around))
    else:
        idx = [n_rings * n_around + 1] + list(range((n_rings - rings) * n_around,
                                                    n_rings * n_around))
    return np.asarray(vertices)[idx]


# --------------------------------------------------------------------------- the arm
#: OpenSim muscles: name -> (origin on humerus, insertion on forearm, wraps, F_max, l_opt, l_ts).
#: The triceps lines lie in the plane z = 0, perpendicular to the wrap cylinder, so their wrapped
#: lengths have a closed form (tangent + arc + tangent) that the tests check OpenSim against.
#: The example's muscle surfaces span each line from origin to insertion (no tendon beside them),
#: so the tendons are short (l_ts 1 cm) and l_opt is the line's length midway through the
#: motion less l_ts: fibres and lines then both stay near l / l_opt = 1 (0.8-1.2).
ACTION_LINES = {
    "BIClong": ((0.024, -0.03, 0.007), (0.016, -0.055, 0.0), (), 624.3, 0.254, 0.01),
    "BICshort": ((0.026, -0.045, -0.008), (0.016, -0.055, 0.0), (), 435.6, 0.239, 0.01),
    "BRA": ((0.012, -0.15, 0.0), (0.010, -0.035, 0.0), (), 987.3, 0.133, 0.01),
    "TRIlong": ((-0.022, -0.03, 0.0), (-0.024, 0.006, 0.0), ("elbow_wrap",), 798.5, 0.267, 0.01),
    "TRIlat": ((-0.016, -0.10, 0.0), (-0.024, 0.006, 0.0), ("elbow_wrap",), 624.3, 0.197, 0.01),
}

#: surfaces: name -> (action lines, template, r_max, aspect, bow, bow_dir)
MUSCLES = {
    "biceps": (("BIClong", "BICshort"), "parallel", 0.011, 1.35, 0.006, (1.0, 0.0, 0.0)),
    "brachialis": (("BRA",), "pennate", 0.009, 1.6, 0.004, (1.0, 0.0, 0.0)),
    "triceps": (("TRIlong", "TRIlat"), "bipennate", 0.012, 1.3, 0.007, (-1.0, 0.0, 0.0)),
}
N_RINGS, N_AROUND = 40, 48


def build_model():
    """The example's :class:`motion.osim.builder.ModelBuilder` (not yet written)."""
    from motion.osim.builder import ModelBuilder

    b = (ModelBuilder("arm_example", credits="musclefibres bundled example (generated by "
                                             "models/make_example.py)")
         .add_body("humerus", mass=1.86, mass_center=(0, -0.16, 0),
                   inertia=(0.0148, 0.0046, 0.0132, 0, 0, 0), meshes=["meshes/humerus.stl"])
         .add_weld_joint("shoulder", "ground", "humerus")
         .add_body("forearm", mass=1.53, mass_center=(0, -0.18, 0),
                   inertia=(0.0193, 0.0016, 0.0201, 0, 0, 0), meshes=["meshes/forearm.stl"])
         .add_pin_joint("elbow", "humerus", "forearm", "elbow_flexion",
                        location_in_parent=tuple(ELBOW), range=ELBOW_RANGE)
         .add_wrap_cylinder("humerus", "elbow_wrap", radius=WRAP_RADIUS, length=0.08,
                            translation=tuple(ELBOW), quadrant="-x"))
    for name, (o, i, wraps, fmax, lopt, lts) in ACTION_LINES.items():
        b.add_muscle(name, [("humerus", o), ("forearm", i)], wraps=wraps,
                     max_isometric_force=fmax, optimal_fiber_length=lopt, tendon_slack_length=lts)
    return b


def _toml_text() -> str:
    lines = ['# The bundled example fibre model (generated by models/make_example.py; see',
             '# docs/INTERFACE.md). Meshes and landmarks are in ground at elbow_flexion = 0.',
             'model = "arm_example.osim"', 'motion = "elbow_flexion.mot"', 'units = "m"', '',
             '[defaults]', 'fibres = 100', 'resolution = 19', 'frame = "ground"',
             'rest_pose = { elbow_flexion = 0.0 }', '']
    for name, (lines_, template, *_rest) in MUSCLES.items():
        al = ", ".join(f'"{a}"' for a in lines_)
        lines += [f"[muscles.{name}]", f"action_lines = [{al}]", f'template = "{template}"',
                  f'mesh = "meshes/{name}.ply"',
                  f'origin = {{ body = "humerus", file = "{name}_origin.csv" }}',
                  f'insertion = {{ body = "forearm", file = "{name}_insertion.csv" }}', ""]
    return "\n".join(lines)


def generate(out_dir=HERE) -> list:
    """Write every example file into ``out_dir``; returns the written paths (sorted)."""
    out = Path(out_dir)
    (out / "meshes").mkdir(parents=True, exist_ok=True)
    written = [build_model().write(out / "arm_example.osim")]

    hv, hf = bone((0, 0.012, 0), (0, -0.302, 0),
                  [(0.0, 0.02, 0.02), (0.08, 0.021, 0.021), (0.2, 0.011, 0.012),
                   (0.8, 0.011, 0.013), (0.93, 0.014, 0.027), (1.0, 0.014, 0.027)])
    fv, ff = bone((0, 0.022, 0), (0, -0.25, 0),
                  [(0.0, 0.012, 0.013), (0.12, 0.014, 0.02), (0.3, 0.01, 0.02),
                   (0.9, 0.009, 0.024), (1.0, 0.01, 0.026)])
    written += [write_stl(out / "meshes/humerus.stl", hv, hf),
                write_stl(out / "meshes/forearm.stl", fv, ff)]

    for name, (lines_, _template, r_max, aspect, bow, bow_dir) in MUSCLES.items():
        origin = np.mean([ACTION_LINES[a][0] for a in lines_], axis=0)
        insertion = np.mean([ACTION_LINES[a][1] for a in lines_], axis=0) + ELBOW  # rest pose
        v, f = spindle(origin, insertion, r_max=r_max, aspect=aspect, bow=bow, bow_dir=bow_dir,
                       n_rings=N_RINGS, n_around=N_AROUND)
        v = v.astype(np.float32)      # what the PLY stores; landmarks are exactly its vertices
        written.append(write_ply(out / f"meshes/{name}.ply", v, f))
        for end, which in (("origin", "first"), ("insertion", "last")):
            pts = tip_landmarks(v, N_AROUND, N_RINGS, which)
            written.append(write_points_csv(out / f"{name}_{end}.csv", pts))

    deg = np.linspace(0.0, 130.0, N_FRAMES)
    written.append(write_mot(out / "elbow_flexion.mot", "elbow_flexion", "elbow_flexion",
                             0.05 * np.arange(N_FRAMES), deg))
    written.append(_atomic_bytes(out / "arm_example.toml", _toml_text().encode("ascii")))
    return sorted(Path(p) for p in written)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    paths = generate(argv[0] if argv else HERE)
    total = sum(p.stat().st_size for p in paths)
    print(f"wrote {len(paths)} files, {total / 1024:.0f} KiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
