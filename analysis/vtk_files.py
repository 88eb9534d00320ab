"""3D output for ParaView / pyvista: fibre polylines (and wrapped surfaces) per frame.

Files (docs/INTERFACE.md): ``fibres/<muscle>.pvd`` (a ParaView collection, ``timestep`` = the
motion's time) and ``fibres/<muscle>_<frame>.vtp`` per frame: one polyline cell per fibre, in fibre
order, with cell data ``fibre`` (its id). `write_surface_frames` writes ``<muscle>_surface.pvd``
and ``<muscle>_surface_<frame>.vtp`` (a wrapped muscle surface; ``fibres run`` leaves the surfaces
to its scene). ``<frame>`` is the 0-based frame
index, zero-padded to 4 digits.

Written by hand in VTK's XML format (VTK file formats, "XML File Formats": PolyData with
``<AppendedData encoding="raw">``, each array preceded by its UInt64 byte count), little-endian,
float32 points (``POINT_TYPE``: a relative precision of 6e-8, 0.06 um at 1 m from the origin,
for drawing; the numbers themselves are in the tables at full precision), int32 topology
(int64 beyond 2^31 points), cell data as given (float64 lengths); every file is written
atomically. No VTK import is needed to write; pyvista/VTK read them (tested).
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .output_files import atomic_path

__all__ = ["write_polylines_vtp", "write_surface_vtp", "write_pvd", "write_fibre_frames",
           "write_surface_frames", "frame_file_name"]

#: the type of the points written (module docstring)
POINT_TYPE = np.dtype("<f4")
_TYPES = {np.dtype("<f8"): "Float64", np.dtype("<f4"): "Float32", np.dtype("<i8"): "Int64",
          np.dtype("<i4"): "Int32", np.dtype("<u1"): "UInt8"}


def frame_file_name(muscle: str, frame: int, kind: str = "") -> str:
    """``<muscle>_<frame>.vtp`` or ``<muscle>_<kind>_<frame>.vtp`` (frame zero-padded to 4)."""
    middle = f"_{kind}" if kind else ""
    return f"{muscle}{middle}_{int(frame):04d}.vtp"


def _le(a, dtype):
    return np.ascontiguousarray(a, dtype=np.dtype(dtype).newbyteorder("<"))


def _polydata(points, *, lines=None, polys=None, cell_data=None, point_data=None):
    """One VTK XML PolyData file with raw appended arrays, in three parts: the XML before the
    appended data, the arrays in the order they are appended (each to be preceded by its UInt64
    byte count), and the XML after. Frames of the same shape share the two XML parts."""
    arrays, offset = [], 0

    def array(parent, name, a, ncomp=1):
        nonlocal offset
        a = _le(a, a.dtype)
        attrs = {"type": _TYPES[a.dtype], "Name": name, "format": "appended",
                 "offset": str(offset)}
        if ncomp != 1:
            attrs["NumberOfComponents"] = str(ncomp)
        ET.SubElement(parent, "DataArray", attrs)
        arrays.append(a)
        offset += 8 + a.nbytes

    root = ET.Element("VTKFile", type="PolyData", version="1.0", byte_order="LittleEndian",
                      header_type="UInt64")
    pdata = ET.SubElement(root, "PolyData")
    n_lines = 0 if lines is None else len(lines[1])
    n_polys = 0 if polys is None else len(polys[1])
    piece = ET.SubElement(pdata, "Piece", NumberOfPoints=str(len(points)), NumberOfVerts="0",
                          NumberOfLines=str(n_lines), NumberOfStrips="0",
                          NumberOfPolys=str(n_polys))
    if point_data:
        pd = ET.SubElement(piece, "PointData")
        for name, values in point_data.items():
            array(pd, name, np.asarray(values))
    if cell_data:
        cd = ET.SubElement(piece, "CellData")
        for name, values in cell_data.items():
            array(cd, name, np.asarray(values))
    pts = ET.SubElement(piece, "Points")
    array(pts, "Points", _le(points, POINT_TYPE).reshape(-1, 3), ncomp=3)
    for tag, topo in (("Lines", lines), ("Polys", polys)):
        if topo is not None:
            el = ET.SubElement(piece, tag)
            index = "<i4" if max(len(points), len(topo[0])) < 2**31 - 1 else "<i8"
            array(el, "connectivity", _le(topo[0], index))
            array(el, "offsets", _le(topo[1], index))
    ET.SubElement(root, "AppendedData", encoding="raw").text = "_"
    head = ET.tostring(root, encoding="unicode")
    marker = '<AppendedData encoding="raw">_'
    cut = head.index(marker) + len(marker)
    return (b'<?xml version="1.0"?>\n' + head[:cut].encode("ascii"), arrays,
            head[cut:].encode("ascii") + b"\n")


def _write_parts(path, head, arrays, tail) -> Path:
    """Write the parts of `_polydata` as one file (atomic)."""
    blobs = [b for a in arrays for b in (np.uint64(a.nbytes).astype("<u8").tobytes(), a.tobytes())]
    path = Path(path)
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(b"".join([head, *blobs, tail]))
    return path


def _write_polydata(path, points, *, lines=None, polys=None, cell_data=None, point_data=None):
    """Write one VTK XML PolyData file with raw appended arrays (atomic)."""
    return _write_parts(path, *_polydata(points, lines=lines, polys=polys, cell_data=cell_data,
                                         point_data=point_data))


def write_polylines_vtp(path, points, *, cell_data=None) -> Path:
    """One frame's fibres as polylines.

    Parameters
    ----------
    path : str or Path
    points : (N, P, 3) float
        Fibre ``k`` is cell ``k``: its P points in order, origin to insertion.
    cell_data : mapping of str -> (N,) array, optional
        Extra per-fibre values; ``fibre`` (0..N-1, int64) is always written first.

    Returns
    -------
    Path
    """
    return _write_parts(path, *_polylines(points, cell_data))


def _polylines(points, cell_data):
    """`_polydata` parts of `write_polylines_vtp`."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 3 or pts.shape[2] != 3 or pts.shape[1] < 2:
        raise ValueError(f"points must be (N, P, 3) with P >= 2, got shape {pts.shape}")
    n, p = pts.shape[:2]
    data = {"fibre": np.arange(n, dtype=np.int64)}
    for name, values in (cell_data or {}).items():
        values = np.asarray(values)
        if values.shape != (n,):
            raise ValueError(f"cell_data[{name!r}] must have shape ({n},), got {values.shape}")
        if name == "fibre":
            raise ValueError("cell_data 'fibre' is reserved (the fibre id)")
        data[name] = values.astype(np.int64 if values.dtype.kind in "iub" else np.float64)
    conn = np.arange(n * p, dtype=np.int64)
    offsets = p * np.arange(1, n + 1, dtype=np.int64)
    return _polydata(pts.reshape(-1, 3), lines=(conn, offsets), cell_data=data)


def write_surface_vtp(path, vertices, faces) -> Path:
    """A triangle surface: vertices (V, 3) float, faces (T, 3) int."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices must be (V, 3), got shape {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or f.dtype.kind not in "iu":
        raise ValueError(f"faces must be (T, 3) integers, got shape {f.shape} {f.dtype}")
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError("faces index vertices that do not exist")
    offsets = 3 * np.arange(1, len(f) + 1, dtype=np.int64)
    return _write_polydata(path, v, polys=(f.reshape(-1), offsets))


def write_pvd(path, files, times) -> Path:
    """A ParaView collection of ``files`` (names relative to the PVD) at ``times`` (seconds)."""
    files = [str(f) for f in files]
    times = np.asarray(times, dtype=float).reshape(-1)
    if len(files) != len(times):
        raise ValueError(f"{len(files)} files but {len(times)} times")
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    coll = ET.SubElement(root, "Collection")
    for f, t in zip(files, times):
        ET.SubElement(coll, "DataSet", timestep=repr(float(t)), group="", part="0", file=f)
    ET.indent(root, space="  ")
    text = '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
    path = Path(path)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text)
    return path


def _frames_and_times(n_frames, times, frames):
    t = np.asarray(times, dtype=float).reshape(-1)
    if len(t) != n_frames:
        raise ValueError(f"times has {len(t)} values for {n_frames} frames")
    fr = np.arange(n_frames) if frames is None else np.asarray(frames).reshape(-1)
    if len(fr) != n_frames or fr.dtype.kind not in "iu":
        raise ValueError(f"frames must be {n_frames} integers")
    return t, fr


def write_fibre_frames(out_dir, muscle: str, fibre_points, *, times, frames=None,
                       cell_data=None) -> Path:
    """``<muscle>_<frame>.vtp`` for every frame, then ``<muscle>.pvd``; returns the PVD path.

    Parameters
    ----------
    out_dir : str or Path
        The ``fibres/`` folder (created if missing).
    fibre_points : (F, N, P, 3) float
    times : (F,) float
    frames : (F,) int, optional
        Frame indices used in the file names (default 0..F-1).
    cell_data : mapping of str -> (F, N) array, optional
        Per-frame, per-fibre values (e.g. ``length``).
    """
    pts = np.asarray(fibre_points, dtype=float)
    if pts.ndim != 4 or pts.shape[3] != 3:
        raise ValueError(f"fibre_points must be (F, N, P, 3), got shape {pts.shape}")
    t, fr = _frames_and_times(pts.shape[0], times, frames)
    extra = {k: np.asarray(v) for k, v in (cell_data or {}).items()}
    for k, v in extra.items():
        if v.shape != pts.shape[:2]:
            raise ValueError(f"cell_data[{k!r}] must have shape {pts.shape[:2]}, got {v.shape}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = [frame_file_name(muscle, f) for f in fr]
    head = tail = layout = None
    for i, name in enumerate(names):                      # one file per frame (I/O loop)
        cells = {k: v[i] for k, v in extra.items()}
        if head is None:    # the XML of the first frame serves them all (same shapes and types)
            head, layout, tail = _polylines(pts[i], cells)
            arrays = layout
        else:               # the arrays in `_polylines`' order: fibre, cell data, points, topology
            arrays = [layout[0], *(_le(np.asarray(v), layout[1 + j].dtype) for j, v in enumerate(cells.values())),
                      _le(pts[i], POINT_TYPE).reshape(-1, 3), *layout[-2:]]
        _write_parts(out / name, head, arrays, tail)
    return write_pvd(out / f"{muscle}.pvd", names, t)


def write_surface_frames(out_dir, muscle: str, vertices, faces, *, times, frames=None) -> Path:
    """``<muscle>_surface_<frame>.vtp`` per frame and ``<muscle>_surface.pvd``; returns the PVD.

    ``vertices`` is (F, V, 3) (the wrapped surface per frame), ``faces`` (T, 3) (fixed topology).
    """
    v = np.asarray(vertices, dtype=float)
    if v.ndim != 3 or v.shape[2] != 3:
        raise ValueError(f"vertices must be (F, V, 3), got shape {v.shape}")
    t, fr = _frames_and_times(v.shape[0], times, frames)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = [frame_file_name(muscle, f, "surface") for f in fr]
    head = tail = layout = None
    for i, name in enumerate(names):
        if head is None:    # the XML and topology of the first frame serve them all
            write_surface_vtp(out / name, v[i], faces)
            head, layout, tail = _polydata(v[i], polys=(np.asarray(faces).reshape(-1),
                                                        3 * np.arange(1, len(faces) + 1, dtype=np.int64)))
        else:
            _write_parts(out / name, head, [_le(v[i], POINT_TYPE), *layout[1:]], tail)
    return write_pvd(out / f"{muscle}_surface.pvd", names, t)
