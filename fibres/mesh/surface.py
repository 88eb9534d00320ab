"""Muscle surfaces and attachment point sets: loading, unit conversion, safe repair, refusal.

Real surfaces segmented from MRI are imperfect (the LHDL hip muscles carry zero-area slivers,
non-manifold edges and unreferenced points). `as_surface` repairs what is safe to repair -- and
says so in ONE warning -- and refuses, with an `InputError` naming the file and the fix, what
cannot be repaired without guessing (open surfaces, point clouds, NaN coordinates).

I/O goes through trimesh (STL, OBJ, PLY, OFF) and `fibres.mesh.vtk_reader` (legacy ``.vtk``, ``.vtp``,
``.vtu``: a numpy reader that checks every count, offset and index before use, because VTK's own
readers crash the process on damaged cell arrays). Mesh files are untrusted input: whatever goes
wrong while reading one is an `InputError` naming the file, never another exception.
"""
from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .clean_check import clean_mesh_geometry, clean_topology  # noqa: F401 - re-exported

__all__ = ["Surface", "as_surface", "as_points", "read_mesh", "SurfaceRepairWarning", "UNITS",
           "check_muscle_scale", "MIN_MUSCLE_SIZE_M"]

#: accepted length units -> factor to metres
UNITS = {"m": 1.0, "mm": 1e-3}

_VTK_SUFFIXES = (".vtk", ".vtp", ".vtu")
_TRIMESH_SUFFIXES = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf")
_MESH_SUFFIXES = _VTK_SUFFIXES + _TRIMESH_SUFFIXES
_CLOSE_FIX = ("Close the holes (e.g. trimesh.repair.fill_holes, MeshLab 'Close Holes' or "
              "NMSBuilder) and save the surface again.")


class SurfaceRepairWarning(UserWarning):
    """A surface was repaired on loading; the message lists what was done."""


@dataclass(frozen=True)
class Surface:
    """A closed, consistently oriented triangle surface in metres.

    Parameters
    ----------
    vertices : (V, 3) float64
        Vertex coordinates in metres.
    faces : (T, 3) int64
        Triangles as vertex indices, wound so that normals point outwards.
    repairs : tuple of str
        What `as_surface` repaired (empty when the input was clean).
    """

    vertices: np.ndarray
    faces: np.ndarray
    repairs: tuple = field(default=())

    def __post_init__(self):
        v = np.array(self.vertices, dtype=np.float64, copy=True)
        f = np.array(self.faces, dtype=np.int64, copy=True)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"vertices must be (V, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"faces must be (T, 3), got {f.shape}")
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise ValueError("faces index vertices that do not exist")
        v.flags.writeable = False
        f.flags.writeable = False
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        object.__setattr__(self, "repairs", tuple(str(r) for r in self.repairs))

    @property
    def volume(self) -> float:
        """Enclosed volume in m^3 (divergence theorem over the triangles)."""
        tri = self.vertices[self.faces]
        return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)

    @property
    def size(self) -> float:
        """Diagonal of the axis-aligned bounding box, in metres."""
        return float(np.linalg.norm(np.ptp(self.vertices, axis=0)))

    def to_trimesh(self):
        """The surface as a `trimesh.Trimesh` (no processing)."""
        import trimesh

        return trimesh.Trimesh(np.array(self.vertices), np.array(self.faces), process=False)


# --------------------------------------------------------------------------------------------
# reading
# --------------------------------------------------------------------------------------------
def _unit_factor(units, file=None) -> float:
    if units not in UNITS:
        raise InputError(f"unknown units {units!r}", file=file, where="units",
                         fix="Use 'm' or 'mm'.")
    return UNITS[units]


def _pyvista_arrays(mesh):
    """(points (V,3), triangles (T,3)) of any pyvista dataset; polygons are triangulated."""
    import pyvista as pv

    if not isinstance(mesh, pv.PolyData):
        mesh = mesh.extract_surface()
    points = np.asarray(mesh.points, dtype=np.float64).reshape(-1, 3)
    if mesh.n_points == 0 or mesh.GetNumberOfPolys() + mesh.GetNumberOfStrips() == 0:
        return points, np.zeros((0, 3), np.int64)
    tri = mesh.triangulate()
    faces = np.asarray(tri.faces, dtype=np.int64)
    return np.asarray(tri.points, dtype=np.float64), faces.reshape(-1, 4)[:, 1:]


def _read_trimesh(path: Path):
    import trimesh

    try:
        loaded = trimesh.load(str(path), process=False)
    except Exception as exc:
        raise InputError(f"cannot read the file ({type(exc).__name__}: {exc})", file=path,
                         fix="Check that it is a valid mesh file.") from None
    if isinstance(loaded, trimesh.Scene):
        geoms = [g for g in loaded.geometry.values() if hasattr(g, "vertices")]
        meshes = [g for g in geoms if isinstance(g, trimesh.Trimesh)]
        if meshes:
            loaded = trimesh.util.concatenate(meshes)
        elif geoms:
            loaded = geoms[0]
        else:
            return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    points = np.asarray(loaded.vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
    return points, faces


def read_mesh(path):
    """Vertices and triangles of a mesh file, never trusting its content.

    Parameters
    ----------
    path : str or os.PathLike
        STL, OBJ, PLY, OFF, GLB/GLTF (trimesh) or legacy VTK, VTP, VTU (`fibres.mesh.vtk_reader`).

    Returns
    -------
    vertices : (V, 3) float64
    faces : (T, 3) int64
        Not validated beyond the format (see `as_surface`); (0, 3) for a point cloud.

    Raises
    ------
    InputError
        Missing, unsupported or unreadable file; any failure inside a reader (a truncated OBJ
        used to raise ``ValueError: cannot reshape ...``) becomes one line naming the file.
    """
    path = Path(path)
    try:
        return _read_mesh_file(path)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - untrusted file: any reader failure is bad input
        raise InputError(f"cannot read the mesh ({type(exc).__name__}: {exc})", file=path,
                         fix="The file is damaged or not a mesh; re-export it (STL, PLY, OBJ, VTK, "
                             "VTP).") from None


def _read_mesh_file(path: Path):
    if not path.is_file():
        raise InputError("file not found", file=path, fix="Check the path.")
    suffix = path.suffix.lower()
    if suffix in _VTK_SUFFIXES:
        from .vtk_reader import read_vtk_file

        return read_vtk_file(path)
    if suffix in _TRIMESH_SUFFIXES:
        return _read_trimesh(path)
    raise InputError(f"unsupported mesh file type {suffix!r}", file=path,
                     fix="Save the surface as STL, OBJ, PLY, VTK or VTP.")


def _raw_arrays(mesh):
    """(vertices, faces, label for messages) from any accepted mesh input."""
    if isinstance(mesh, (str, os.PathLike)):
        path = Path(mesh)
        v, f = read_mesh(path)
        return v, f, str(path)
    if isinstance(mesh, Surface):
        return np.array(mesh.vertices), np.array(mesh.faces), None
    if isinstance(mesh, tuple) and len(mesh) == 2:
        v = np.asarray(mesh[0], dtype=np.float64)
        f = np.asarray(mesh[1])
        if v.ndim != 2 or v.shape[-1] != 3:
            raise InputError(f"vertices must be a (V, 3) array, got shape {v.shape}",
                             where="mesh vertices", fix="Pass (vertices (V,3), faces (T,3)).")
        if f.size == 0:
            f = np.zeros((0, 3), np.int64)
        if f.ndim != 2 or f.shape[-1] != 3 or not np.issubdtype(f.dtype, np.integer):
            raise InputError(f"faces must be a (T, 3) integer array, got {f.dtype} {f.shape}",
                             where="mesh faces", fix="Pass triangles as vertex indices.")
        return v, f.astype(np.int64), None
    mod = type(mesh).__module__
    if mod.startswith("trimesh"):
        v = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
        return v, f, None
    if mod.startswith("pyvista") or mod.startswith("vtkmodules"):
        import pyvista as pv

        v, f = _pyvista_arrays(pv.wrap(mesh))
        return v, f, None
    raise InputError(f"cannot use a {type(mesh).__name__} as a surface", where="mesh",
                     fix="Pass a file path, a (vertices, faces) tuple, a trimesh.Trimesh "
                         "or a pyvista mesh.")


# --------------------------------------------------------------------------------------------
# repair
# --------------------------------------------------------------------------------------------
def _repair(v, f, label, *, quiet_merge=False):
    """Merge duplicates, drop degenerate/duplicate faces and stray pieces; list what was done.

    ``quiet_merge``: merging duplicate vertices is not reported (STL stores every triangle's
    corners separately, so merging them is reading the format, not repairing the mesh)."""
    import trimesh
    from trimesh.graph import connected_components

    repairs = []
    n_unref = len(v) - len(np.unique(f))
    if n_unref:
        repairs.append(f"dropped {n_unref} unreferenced point{'s' * (n_unref > 1)}")
    m = trimesh.Trimesh(v, f, process=False, validate=False)
    m.remove_unreferenced_vertices()
    n_before = len(m.vertices)
    m.merge_vertices(merge_tex=True, merge_norm=True)
    if n_before - len(m.vertices) and not quiet_merge:
        repairs.append(f"merged {n_before - len(m.vertices)} duplicate vertices")
    keep = m.nondegenerate_faces()
    if not keep.all():
        repairs.append(f"dropped {int((~keep).sum())} degenerate (zero-area) faces")
        m.update_faces(keep)
    uniq = m.unique_faces()
    if not uniq.all():
        repairs.append(f"dropped {int((~uniq).sum())} duplicate faces")
        m.update_faces(uniq)
    if len(m.faces):
        comps = connected_components(m.face_adjacency, nodes=np.arange(len(m.faces)),
                                     min_len=1)
        if len(comps) > 1:
            sizes = np.array([len(c) for c in comps])
            big = comps[int(np.argmax(sizes))]
            mask = np.zeros(len(m.faces), bool)
            mask[big] = True
            repairs.append(f"kept the largest piece ({len(big)} faces) and dropped "
                           f"{len(comps) - 1} stray pieces ({int(sizes.sum() - len(big))} faces)")
            m.update_faces(mask)
    m.remove_unreferenced_vertices()
    if len(m.faces) < 4:
        raise InputError(f"only {len(m.faces)} usable triangles", file=label, where="faces",
                         fix="A closed surface needs at least 4 triangles; pass the muscle's "
                             "closed surface mesh.")
    if not m.is_watertight:
        edges = trimesh.grouping.group_rows(m.edges_sorted, require_count=1)
        raise InputError(f"the surface is open ({len(edges)} boundary edges remain after "
                         "repair)", file=label, where="faces", fix=_CLOSE_FIX)
    if not m.is_winding_consistent:
        m.fix_normals()
        repairs.append("made the triangle winding consistent")
    if m.volume < 0:
        m.invert()
        repairs.append("flipped the faces so that normals point outwards")
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64), repairs


def as_surface(mesh, *, units: str = "m") -> Surface:
    """Load, validate and (safely) repair a closed muscle surface.

    Parameters
    ----------
    mesh : str or os.PathLike or (V,3) float & (T,3) int tuple or trimesh.Trimesh or pyvista mesh
        The surface. Files: STL, OBJ, PLY, OFF (trimesh) or legacy VTK, VTP, VTU (pyvista).
    units : {"m", "mm"}, keyword-only
        Units of the coordinates; the result is always in metres.

    Returns
    -------
    Surface
        Closed, outward-oriented; ``repairs`` lists what was repaired.

    Raises
    ------
    InputError
        Unreadable file, NaN/inf coordinates, points without triangles, fewer than 4 faces,
        or a surface still open after the safe repairs.

    Warns
    -----
    SurfaceRepairWarning
        Once, listing every repair (merged duplicate vertices, dropped degenerate or duplicate
        faces, dropped stray pieces, dropped unreferenced points, fixed winding).
    """
    if isinstance(mesh, Surface) and units == "m":
        return mesh
    factor = _unit_factor(units, file=mesh if isinstance(mesh, (str, os.PathLike)) else None)
    v, f, label = _raw_arrays(mesh)
    if len(v) == 0:
        raise InputError("the mesh has no points", file=label, where="points",
                         fix="Pass the muscle's closed triangle surface.")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise InputError(f"{int(bad.sum())} vertices have NaN or infinite coordinates "
                         f"(first: vertex {int(np.flatnonzero(bad)[0])})", file=label,
                         where="points", fix="Repair or re-export the mesh.")
    if len(f) == 0:
        raise InputError(f"the mesh has {len(v)} points but no triangles (a point cloud)",
                         file=label, where="faces",
                         fix="Pass the muscle's closed triangle surface, not its points; "
                             "reconstruct a surface first (e.g. pyvista reconstruct_surface).")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError("faces refer to vertices that do not exist", file=label,
                         where="faces", fix="Re-export the mesh.")
    v = v * factor
    if clean_topology(v, f) is not None:
        return Surface(v, f, ())
    quiet_merge = label is not None and Path(label).suffix.lower() == ".stl"
    v, f, repairs = _repair(v, f, label, quiet_merge=quiet_merge)
    if repairs:
        warnings.warn(f"{label or 'surface'}: repaired: " + "; ".join(repairs) + ".",
                      SurfaceRepairWarning, stacklevel=2)
    return Surface(v, f, tuple(repairs))


#: Smallest plausible bounding-box diagonal of one muscle surface, in metres. A mesh in metres
#: declared as millimetres is a thousand times too small (a 0.3 m biceps becomes 0.3 mm); the
#: smallest human muscle, the stapedius, is about 6 mm long.
MIN_MUSCLE_SIZE_M = 2e-3


def check_muscle_scale(surface: Surface, *, file=None, max_size_m: float = 3.0,
                       min_size_m: float = MIN_MUSCLE_SIZE_M):
    """Refuse a "muscle" larger than ``max_size_m`` metres (almost surely mm declared as m) or
    smaller than ``min_size_m`` (almost surely m declared as mm).

    Parameters
    ----------
    surface : Surface
    file : str, optional
        Named in the message.
    max_size_m : float
        Largest plausible bounding-box diagonal of one muscle, in metres (3 m; the longest
        human muscle, sartorius, is about 0.6 m).
    min_size_m : float
        Smallest plausible bounding-box diagonal, in metres (`MIN_MUSCLE_SIZE_M`).
    """
    size = surface.size
    if size < min_size_m:
        raise InputError(f"the surface is {size * 1e3:.4g} mm across, too small for a muscle; it "
                         "is probably in metres", file=file, where="units",
                         fix="Declare the units as m (--units m, units='m').")
    if size > max_size_m:
        raise InputError(f"the surface is {size:.4g} m across, too large for a muscle; it is "
                         "probably in millimetres", file=file, where="units",
                         fix="Declare the units as mm (--units mm, units='mm').")


# --------------------------------------------------------------------------------------------
# attachment points
# --------------------------------------------------------------------------------------------
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_TRIPLETS = re.compile(rf"^\s*{_NUM}\s*,\s*{_NUM}\s*,\s*{_NUM}\s*(?:;\s*{_NUM}\s*,\s*{_NUM}"
                       rf"\s*,\s*{_NUM}\s*)*;?\s*$")


def _read_points_csv(path: Path, units: str):
    import pandas as pd

    first = path.read_text().lstrip().splitlines()[:1]
    if not first:
        raise InputError("the file is empty", file=path, fix="Add rows of x,y,z.")
    has_header = re.search(r"[A-DF-Za-df-z_]", first[0]) is not None
    try:
        table = pd.read_csv(path, header=0 if has_header else None, skipinitialspace=True)
    except Exception as exc:
        raise InputError(f"cannot read the CSV ({exc})", file=path,
                         fix="Use a CSV with columns x,y,z.") from None
    if has_header:
        cols = {str(c).strip().lower(): c for c in table.columns}
        if all(c in cols for c in "xyz"):
            picked = [cols[c] for c in "xyz"]
        elif all(f"{c}_mm" in cols for c in "xyz"):
            if units != "mm":
                raise InputError("the columns are x_mm, y_mm, z_mm but the units are 'm'",
                                 file=path, where="header",
                                 fix="Declare the units as mm (--units mm, units='mm').")
            picked = [cols[f"{c}_mm"] for c in "xyz"]
        else:
            raise InputError(f"no x, y, z columns (found {', '.join(map(str, table.columns))})",
                             file=path, where="header", fix="Name the columns x,y,z.")
        table = table[picked]
    elif table.shape[1] != 3:
        raise InputError(f"{table.shape[1]} columns without a header", file=path,
                         where="line 1", fix="Use three columns x,y,z (header optional).")
    try:
        return table.to_numpy(dtype=np.float64)
    except ValueError:
        raise InputError("non-numeric coordinates", file=path,
                         fix="Use numbers in the x,y,z columns.") from None


def as_points(points, *, units: str = "m", name: str = "points") -> np.ndarray:
    """An attachment landmark set as a (K, 3) float64 array in metres.

    Parameters
    ----------
    points : array-like (K,3) or (3,) or str or os.PathLike
        An array; a string ``"x,y,z;x,y,z"``; a CSV file with columns x,y,z (header row
        optional; ``x_mm,y_mm,z_mm`` accepted with ``units="mm"``); or a mesh/point-cloud file
        (VTK, VTP, PLY, STL, OBJ) whose points are the landmarks.
    units : {"m", "mm"}, keyword-only
    name : str, keyword-only
        What the set is (``"origin"``, ``"insertion"``) for error messages.

    Returns
    -------
    (K, 3) float64, read-only
    """
    label = None
    if isinstance(points, str) and _TRIPLETS.match(points):
        arr = np.array([[float(x) for x in p.split(",")] for p in points.strip().strip(";")
                        .split(";")], dtype=np.float64)
    elif isinstance(points, (str, os.PathLike)):
        path = Path(points)
        label = str(path)
        _unit_factor(units, file=path)
        if not path.is_file():
            raise InputError("file not found", file=path, where=name,
                             fix="Pass a CSV with x,y,z columns, a point-cloud mesh file or "
                                 "'x,y,z;x,y,z'.")
        if path.suffix.lower() in _MESH_SUFFIXES:
            arr, _ = read_mesh(path)
        else:
            arr = _read_points_csv(path, units)
    else:
        try:
            arr = np.asarray(points, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"cannot read the {name} points", where=name,
                             fix="Pass (K,3) numbers, 'x,y,z;x,y,z', a CSV or a mesh file.") \
                from None
        if arr.ndim == 1 and arr.shape[0] == 3:
            arr = arr[None, :]
    factor = _unit_factor(units, file=label)
    if arr.ndim != 2 or (arr.size and arr.shape[1] != 3):
        raise InputError(f"the {name} points must be (K, 3), got shape {arr.shape}",
                         file=label, where=name, fix="Give three coordinates per point.")
    if arr.shape[0] == 0:
        raise InputError(f"the {name} set is empty", file=label, where=name,
                         fix="Give at least one landmark of the attachment area.")
    if not np.isfinite(arr).all():
        raise InputError(f"the {name} points contain NaN or infinite values", file=label,
                         where=name, fix="Give finite coordinates.")
    out = arr.reshape(-1, 3) * factor
    out.flags.writeable = False
    return out
