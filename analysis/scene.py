"""The 3D scene of a run for ParaView / pyvista: bones, wrapped muscle surfaces, action lines and
fibres, frame by frame, in ONE collection (``scene/scene.pvd``) that a ParaView user opens once.

Files (`write_scene`; ``<frame>`` the 0-based frame index of the run, zero-padded to 4 digits):

- ``scene/scene.pvd``: a VTK collection; each ``timestep`` (the motion's time) has four parts
  (``part`` 0..3), read by ParaView and ``pyvista.PVDReader`` as one multiblock per frame:
- ``scene/bones_<frame>.vtp``: every bone mesh posed at the frame; cell data ``body`` (index into
  ``names.json`` ``bodies``). Meshes are the model's own geometry files (``mesh_file`` of each
  body, searched like OpenSim: the model's folder, then its ``Geometry``/``geometry`` subfolder;
  scaled by ``scale_factors``) where they are found, else the bone meshes the fibre model names
  (``bones = [...]`` of its muscles, placed by the muscle's rest pose). Only the bodies the run's
  muscles attach to or wrap over are drawn.
- ``scene/surfaces_<frame>.vtp``: the wrapped muscle surfaces; cell data ``muscle``.
- ``scene/lines_<frame>.vtp``: the action lines as OpenSim draws them, in path order, with the
  arcs over their wrap objects (`motion.surface.current_lines.current_polylines`), one polyline
  each; cell data ``muscle``, ``action_line`` (index into ``action_lines``).
- ``scene/fibres_<frame>.vtp``: every fibre; cell data ``muscle``, ``fibre`` (its id in the
  muscle), ``length`` (m).
- ``scene/names.json``: ``muscles``, ``bodies``, ``action_lines`` (the names of the ids above),
  ``frames`` (the frames written) and ``times``.

A run of many frames writes every ``step``-th frame (default: so that at most `MAX_FRAMES` frames
are written; bones are most of the bytes).
"""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from motion.osim.reader import ModelFileWarning

from .output_files import atomic_path, write_text
from .vtk_files import _write_polydata

__all__ = ["write_scene", "scene_frames", "bone_meshes", "MAX_FRAMES", "PARTS"]

#: default most frames written to the scene
MAX_FRAMES = 100
#: the parts of every timestep, in ``part`` order
PARTS = ("bones", "surfaces", "lines", "fibres")


def _find_geometry(model_file, name):
    base = Path(model_file).resolve().parent
    rel = str(name).strip().replace("\\", "/")
    for folder in (base, base / "Geometry", base / "geometry"):
        cand = folder / rel
        if cand.is_file():
            return cand
        cand = folder / Path(rel).name
        if cand.is_file():
            return cand
    return None


def _warn_missing(missing: dict, model_file) -> None:
    """One warning naming the bodies drawn without a bone (body -> a missing file name)."""
    if not missing:
        return
    from .errors import FibreWarning

    names = sorted(missing)
    shown = ", ".join(f"{b} ({missing[b]})" for b in names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")
    warnings.warn(f"{model_file}: the 3D scene has no bone for {shown}: the model's geometry files are not "
                  "beside it nor in its Geometry folder; copy that folder next to the .osim file to see "
                  "the bones", FibreWarning, stacklevel=3)


def _read_mesh(path):
    """(V, 3) vertices, (T, 3) faces of a mesh file (.vtp, .vtk, .stl, .obj, .ply): read with
    `fibres.mesh.surface.read_mesh`, which validates the file before use (model geometry is untrusted
    input; VTK's own readers crash the process on damaged cell arrays)."""
    from fibres.mesh.surface import read_mesh

    v, f = read_mesh(path)
    return np.asarray(v, dtype=float), np.asarray(f, dtype=np.int64)


def _apply(tf, p):
    return p @ tf[:3, :3].T + tf[:3, 3]


def bone_meshes(model, spec=None, bodies=None) -> list:
    """Bone meshes in their body frames: list of (body index, vertices (V, 3), faces (T, 3)).

    The model's geometry files where found (module docstring), else the fibre model's ``bones``.
    ``bodies``: body names to keep (default all). Bodies whose geometry files are all missing and
    that no ``bones`` mesh stands in for are named in one `FibreWarning` (the scene shows no bone
    there; OpenSim, too, only warns)."""
    keep = set(model.body_names if bodies is None else bodies)
    out, covered, missing = [], set(), {}
    for b, body in enumerate(model.bodies):
        if body.name not in keep:
            continue
        for geom in body.geometry:
            path = _find_geometry(model.file, geom.mesh_file)
            if path is None:
                missing.setdefault(body.name, geom.mesh_file)
                continue
            try:
                v, f = _read_mesh(path)
            except Exception:   # noqa: BLE001 - an unreadable display mesh is skipped, not fatal
                continue
            v = _apply(geom.tf_body_geometry, v * geom.scale_factors)
            out.append((b, v, f))
            covered.add(body.name)
    if spec is not None:
        from fibres import as_surface
        from motion.surface.rest import rest_pose

        from .muscle_chain import surface_spec

        for mspec in spec.muscles:
            if not mspec.bones:
                continue
            pose = None
            for body, path in mspec.bones:
                if body in covered or body not in keep:
                    continue
                pose = pose or rest_pose(model, surface_spec(mspec))
                surf = as_surface(path, units=mspec.units)
                b = model.body_index(body)
                tf_body_data = np.linalg.inv(pose.tf_ground_body[b]) @ pose.tf_ground_data
                out.append((b, _apply(tf_body_data, np.asarray(surf.vertices, dtype=float)),
                            np.asarray(surf.faces, dtype=np.int64)))
            covered.update(body for body, _ in mspec.bones)
    _warn_missing({b: f for b, f in missing.items() if b not in covered}, model.file)
    return out


def _write_pvd_parts(path, frames_files, times):
    import xml.etree.ElementTree as ET

    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    coll = ET.SubElement(root, "Collection")
    for files, t in zip(frames_files, times):
        for part, f in enumerate(files):
            ET.SubElement(coll, "DataSet", timestep=repr(float(t)), group="", part=str(part), file=f)
    ET.indent(root, space="  ")
    with atomic_path(path) as tmp:
        Path(tmp).write_text('<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n")


def _merge(meshes):
    """Concatenate (vertices, faces, id) triples: points, connectivity, offsets, cell ids."""
    if not meshes:
        return np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    pts, conn, ids, start = [], [], [], 0
    for v, f, i in meshes:
        pts.append(v)
        conn.append(f.reshape(-1) + start)
        ids.append(np.full(len(f), i, dtype=np.int64))
        start += len(v)
    conn = np.concatenate(conn)
    return np.vstack(pts), conn, 3 * np.arange(1, len(conn) // 3 + 1, dtype=np.int64), np.concatenate(ids)


def _polylines(curves):
    """(points, connectivity, offsets) of a list of (P_k, 3) curves."""
    if not curves:
        return np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64)
    sizes = np.array([len(c) for c in curves], dtype=np.int64)
    pts = np.vstack(curves)
    return pts, np.arange(len(pts), dtype=np.int64), np.cumsum(sizes)


def scene_frames(n_frames: int, step=None) -> np.ndarray:
    """The frames the scene shows: every ``step``-th, by default so that at most `MAX_FRAMES`."""
    step = int(step) if step else max(1, -(-int(n_frames) // MAX_FRAMES))
    return np.arange(0, int(n_frames), step)


def write_scene(folder, result, spec, *, step=None, progress=None) -> Path:
    """Write the scene of a run (module docstring) into ``folder``; return ``scene.pvd``.

    Needs the run's fibre points (``keep_points``) and, for surfaces, its wrapped surfaces
    (``keep_surfaces``), at every frame or at the scene's frames only (`scene_frames`, as
    ``fibres run`` keeps them); a muscle without them contributes nothing to that part."""
    import motion as motion_pkg
    from motion.surface.current_lines import current_polylines

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    model = spec.model
    n_f = len(result.time)
    frames = scene_frames(n_f, step)

    def at(array, i, f):       # the array's row of scene frame i (= motion frame f)
        return array[f] if array.shape[0] == n_f else array[i]
    muscles = list(result.muscles)
    line_names = list(dict.fromkeys(n for m in muscles for n in m.action_lines))
    line_muscle = {n: k for k, m in enumerate(muscles) for n in m.action_lines}
    q = np.asarray(result.q)[frames]
    with warnings.catch_warnings():   # the run has said it over all its frames
        warnings.filterwarnings("ignore", message=".*wrap objects in series", category=ModelFileWarning)
        lines = motion_pkg.action_lines(model, q, muscles=line_names)
    bodies = set()
    for m in muscles:
        mspec = spec.muscle(m.name)
        for n in m.action_lines:
            path = model.path(n)
            bodies.update(path.bodies)
            bodies.update(model.wrap_object(w.wrap_object).body for w in path.wraps)
        bodies.update((mspec.origin.body, mspec.insertion.body))
    bones = bone_meshes(model, spec, bodies)
    tf = motion_pkg.body_poses(model, q).tf_ground_body                         # (F', B, 4, 4)
    # the paths as OpenSim draws them, with their arcs over the wrap objects
    drawn = current_polylines(model, q, line_names, lines, tf)
    files_per_frame = []
    iterator = progress(range(len(frames)), desc="3D scene", unit="frame") if progress else range(len(frames))
    for i in iterator:
        f = int(frames[i])
        names = [f"{part}_{f:04d}.vtp" for part in PARTS]
        pts, conn, offs, ids = _merge([(_apply(tf[i, b], v), faces, b) for b, v, faces in bones])
        _write_polydata(folder / names[0], pts, polys=(conn, offs), cell_data={"body": ids})
        surf = [(at(m.surface_vertices, i, f), m.surface_faces, k) for k, m in enumerate(muscles)
                if m.surface_vertices is not None]
        pts, conn, offs, ids = _merge(surf)
        _write_polydata(folder / names[1], pts, polys=(conn, offs), cell_data={"muscle": ids})
        curves, cm, cl = [], [], []
        for j, n in enumerate(line_names):
            curve = drawn[n][0][i]
            curves.append(curve[np.isfinite(curve).all(axis=1)])
            cm.append(line_muscle[n])
            cl.append(j)
        pts, conn, offs = _polylines(curves)
        _write_polydata(folder / names[2], pts, lines=(conn, offs),
                        cell_data={"muscle": np.array(cm, np.int64), "action_line": np.array(cl, np.int64)})
        fib = [(k, m) for k, m in enumerate(muscles) if m.fibre_points is not None]
        curves = [c for _, m in fib for c in at(m.fibre_points, i, f)]
        pts, conn, offs = _polylines(curves)
        cell = {"muscle": np.concatenate([np.full(m.n_fibres, k, np.int64) for k, m in fib]) if fib else np.zeros(0, np.int64),
                "fibre": np.concatenate([np.arange(m.n_fibres, dtype=np.int64) for _, m in fib]) if fib else np.zeros(0, np.int64),
                "length": np.concatenate([m.fibre_lengths[f] for _, m in fib]) if fib else np.zeros(0)}
        _write_polydata(folder / names[3], pts, lines=(conn, offs), cell_data=cell)
        files_per_frame.append(names)
    _write_pvd_parts(folder / "scene.pvd", files_per_frame, result.time[frames])
    write_text(json.dumps({"parts": list(PARTS), "muscles": [m.name for m in muscles],
                           "bodies": list(model.body_names), "action_lines": line_names,
                           "frames": frames.tolist(), "times": [float(t) for t in result.time[frames]]},
                          indent=1) + "\n", folder / "names.json")
    return folder / "scene.pvd"
