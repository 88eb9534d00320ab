"""Analytic validation models: a cylindrical muscle across a pin joint, straight or over a pulley.

Not committed: tests generate them into a temporary folder (they are cheap: ~0.1 s), so the
geometry parameters can vary per test. From the command line::

    python models/make_cylinders.py OUTDIR      # writes OUTDIR/straight/ and OUTDIR/pulley/

Each folder holds ``<name>.osim``, ``meshes/cylinder.ply``, ``cylinder_origin.csv``,
``cylinder_insertion.csv``, ``sweep.mot`` and ``<name>.toml`` (fibre model ``cylinder``, template
``parallel``, action line ``cyl``), all in SI units, mesh and landmarks in ground at q = 0.

Geometry (both models): body ``proximal`` welded to ground with its frame equal to ground, body
``distal`` on the PinJoint ``joint`` (axis z through the origin), coordinate ``q``. The muscle is a
cylinder of radius ``rho`` (flat end caps) whose axis runs parallel to y at x = ``d`` from
(d, a, 0) on ``proximal`` to (d, -b, 0) on ``distal`` (rest pose q = 0).

(a) ``straight``: the action line is that axis, ``L(q) = |Rz(q) (d, -b) - (d, a)|``,
    ``r(q) = -dL/dq = ((a b - d^2) sin q + (a + b) d cos q) / L`` (:func:`straight_length`,
    :func:`straight_moment_arm`; r(0) = d).
(b) ``pulley``: d = -R and a WrapCylinder of radius ``R`` (quadrant -x) on ``proximal`` at the
    joint: for q >= 0 the action line is tangent + arc + tangent, ``L(q) = a + b + R q`` and
    ``r = -R``; a straight fibre of the surface at x = -(R + e) keeps to radius R + e, so its
    length is ``a + b + (R + e) q`` (the textbook pulley: moment arm = radius + fibre offset;
    :func:`pulley_fibre_length`). The WrapCylinder is the *centre line's* pulley: the muscle
    surface straddles it (its inner half lies inside radius R; think of the bone as radius
    R - rho). Surface-wrapping code that pushes vertices out of wrap objects will flatten that half.
"""
from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def _example_module():
    name = "make_example"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, HERE / "make_example.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def cylinder_mesh(top, bottom, radius, *, n_rings=30, n_cap=4, n_around=32):
    """A closed circular cylinder with flat caps from ``top`` to ``bottom`` (points (3,)).

    The caps are ``n_cap`` concentric rings around a centre (pole) vertex; the side has
    ``n_rings`` rings. Returns ``(vertices (V, 3), faces (T, 3), cap_indices (2, K))``, the
    last listing the vertices of the top and bottom caps (rim included).
    """
    me = _example_module()
    top, bottom = np.asarray(top, float), np.asarray(bottom, float)
    cap_r = radius * np.arange(1, n_cap + 1) / n_cap                      # inner -> rim
    side_s = np.linspace(0.0, 1.0, n_rings)[1:-1]
    s = np.concatenate([np.zeros(n_cap), side_s, np.ones(n_cap)])
    r = np.concatenate([cap_r, np.full(len(side_s), radius), cap_r[::-1]])
    centres = top + s[:, None] * (bottom - top)
    tangent = np.broadcast_to(bottom - top, centres.shape)
    hint = np.array([1.0, 0.0, 0.0]) if abs((bottom - top)[0]) < 0.9 * np.linalg.norm(
        bottom - top) else np.array([0.0, 0.0, 1.0])
    u, w = me._frames_along(tangent, hint)
    v, f = me.tube_mesh(centres, np.stack([r, r], axis=1), u, w, np.stack([top, bottom]),
                        n_around=n_around)
    n_r = len(s)
    top_idx = np.concatenate([[n_r * n_around], np.arange(n_cap * n_around)])
    bot_idx = np.concatenate([[n_r * n_around + 1], np.arange((n_r - n_cap) * n_around,
                                                              n_r * n_around)])
    return v, f, np.stack([top_idx, bot_idx])


def straight_length(q, *, a, b, d):
    """Action line length of model (a): ``|Rz(q) (d, -b) - (d, a)|`` (q in rad, (F,))."""
    q = np.asarray(q, float)
    c, s = np.cos(q), np.sin(q)
    return np.hypot(d * c + b * s - d, d * s - b * c - a)


def straight_moment_arm(q, *, a, b, d):
    """``-dL/dq`` of :func:`straight_length`, exact: ``-(p2 - p1) . dp2/dq / L``."""
    q = np.asarray(q, float)
    c, s = np.cos(q), np.sin(q)
    dx, dy = d * c + b * s - d, d * s - b * c - a
    ddx, ddy = -d * s + b * c, d * c + b * s
    return -(dx * ddx + dy * ddy) / np.hypot(dx, dy)


def pulley_length(q, *, a, b, radius):
    """Action line length of model (b) for q >= 0: ``a + b + R q``."""
    q = np.asarray(q, float)
    if np.any(q < 0):
        raise ValueError("the pulley formula holds for q >= 0 (the path wraps)")
    return a + b + radius * q


def pulley_fibre_length(q, offset, *, a, b, radius):
    """Length of a straight surface fibre of model (b) at x = -(radius + offset), for q >= 0.

    It wraps concentrically at radius ``radius + offset``: ``a + b + (radius + offset) q``
    (shape: broadcast of q and offset), so its moment arm is ``-(radius + offset)``.
    """
    q, offset = np.asarray(q, float), np.asarray(offset, float)
    if np.any(q < 0) or np.any(radius + offset <= 0):
        raise ValueError("needs q >= 0 and radius + offset > 0")
    return a + b + (radius + offset) * q


def _write_set(out, name, builder, *, top, bottom, rho, q_deg, me):
    out.mkdir(parents=True, exist_ok=True)
    paths = {"model": builder.write(out / f"{name}.osim")}
    v, f, caps = cylinder_mesh(top, bottom, rho)
    v = v.astype(np.float32)
    paths["mesh"] = me.write_ply(out / "meshes" / "cylinder.ply", v, f)
    paths["origin"] = me.write_points_csv(out / "cylinder_origin.csv", v[caps[0]])
    paths["insertion"] = me.write_points_csv(out / "cylinder_insertion.csv", v[caps[1]])
    q_deg = np.asarray(q_deg, float)
    paths["motion"] = me.write_mot(out / "sweep.mot", "sweep", "q", 0.1 * np.arange(len(q_deg)),
                                   q_deg)
    toml = "\n".join([
        f"# analytic validation model '{name}' (models/make_cylinders.py)",
        f'model = "{name}.osim"', 'motion = "sweep.mot"', 'units = "m"', "",
        "[muscles.cylinder]", 'action_lines = ["cyl"]', 'template = "parallel"',
        'mesh = "meshes/cylinder.ply"', 'frame = "ground"', "rest_pose = { q = 0.0 }",
        'origin = { body = "proximal", file = "cylinder_origin.csv" }',
        'insertion = { body = "distal", file = "cylinder_insertion.csv" }', ""])
    paths["spec"] = me._atomic_bytes(out / f"{name}.toml", toml.encode("ascii"))
    return paths


def _pin_model(name, q_range):
    from motion.osim.builder import ModelBuilder

    return (ModelBuilder(name)
            .add_body("proximal", mass=1.0)
            .add_weld_joint("fix", "ground", "proximal")
            .add_body("distal", mass=1.0)
            .add_pin_joint("joint", "proximal", "distal", "q", range=q_range))


def make_straight(out_dir, *, a=0.12, b=0.10, d=0.015, rho=0.008,
                  q_deg=np.arange(0.0, 91.0, 5.0)) -> dict:
    """Model (a) into ``out_dir``; returns ``{"model", "mesh", "origin", "insertion", "motion",
    "spec"}`` paths."""
    me = _example_module()
    b_ = (_pin_model("straight", (-math.pi / 2, math.pi))
          .add_muscle("cyl", [("proximal", (d, a, 0.0)), ("distal", (d, -b, 0.0))]))
    return _write_set(Path(out_dir), "straight", b_, top=(d, a, 0.0), bottom=(d, -b, 0.0),
                      rho=rho, q_deg=q_deg, me=me)


def make_pulley(out_dir, *, a=0.12, b=0.10, radius=0.02, rho=0.008,
                q_deg=np.arange(0.0, 91.0, 5.0)) -> dict:
    """Model (b) into ``out_dir`` (action line at x = -radius, wrapping the pulley)."""
    if not rho < radius:
        raise ValueError("the muscle radius rho must be smaller than the pulley radius")
    me = _example_module()
    b_ = (_pin_model("pulley", (0.0, math.pi))
          .add_wrap_cylinder("proximal", "pulley", radius=radius, length=0.1, quadrant="-x")
          .add_muscle("cyl", [("proximal", (-radius, a, 0.0)), ("distal", (-radius, -b, 0.0))],
                      wraps=["pulley"]))
    return _write_set(Path(out_dir), "pulley", b_, top=(-radius, a, 0.0),
                      bottom=(-radius, -b, 0.0), rho=rho, q_deg=q_deg, me=me)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python models/make_cylinders.py OUTDIR", file=sys.stderr)
        return 2
    out = Path(argv[0])
    make_straight(out / "straight")
    make_pulley(out / "pulley")
    print(f"wrote {out / 'straight'} and {out / 'pulley'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
