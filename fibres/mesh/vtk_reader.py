"""Reading VTK surface files (legacy ``.vtk``; XML ``.vtp`` and ``.vtu``) without VTK.

Why not VTK's own readers: mesh files come from other people. A legacy binary ``.vtk`` whose
cell OFFSETS array is corrupted made VTK's reader kill the whole process (SIGSEGV, or abort on
``std::bad_alloc``), with nothing on stderr, and a truncated ``.vtp`` printed 25 lines of VTK
error dump. These readers are numpy only: every count, offset and index is checked against the
bytes actually present *before* anything is allocated or indexed, so a damaged file can only
raise `InputError` (one line naming the file and what is wrong).

Formats (VTK User's Guide, "VTK File Formats", and VTK 9's writers):

- legacy ``.vtk``, ASCII or BINARY (big-endian), versions 2-5: ``DATASET POLYDATA`` (``POINTS``,
  ``VERTICES``, ``LINES``, ``POLYGONS``, ``TRIANGLE_STRIPS``) or ``UNSTRUCTURED_GRID``
  (``POINTS``, ``CELLS``, ``CELL_TYPES``); cell arrays in the classic layout (``n i0 i1 ...`` per
  cell) or the 5.x layout (``OFFSETS`` + ``CONNECTIVITY``); ``FIELD`` and ``METADATA`` blocks are
  skipped; reading stops at ``POINT_DATA``/``CELL_DATA`` (attributes are not needed).
- XML ``PolyData`` / ``UnstructuredGrid`` (`fibres.mesh.vtk_xml`), every data mode: ``ascii``, inline ``binary``
  (base64) and ``appended`` (raw or base64), header ``UInt32``/``UInt64``, either byte order,
  uncompressed or compressed with ``vtkZLibDataCompressor`` or ``vtkLZMADataCompressor``; several
  pieces are concatenated. The XML (everything before the appended data) is parsed with
  defusedxml (no entity expansion).

Faces: triangles as they are; polygons and quads fanned from their first point; triangle strips
split with VTK's alternating orientation; pixels reordered as quads. Vertices and lines carry no
faces (their points are still returned: a point cloud). 3D cells are refused (export the surface).
"""
from __future__ import annotations


import numpy as np

from ..errors import InputError

__all__ = ["read_vtk_file", "MAX_ARRAY_BYTES"]

#: largest array a file may declare (uncompressed); a larger declaration is a damaged file
MAX_ARRAY_BYTES = 2**31
#: big-endian types of the legacy format; ``vtkIdType`` arrays are stored as 32-bit integers by
#: VTK's legacy writer (``vtkDataWriter``), whatever the build's id size
_LEGACY_TYPES = {"bit": None, "unsigned_char": "u1", "char": "i1", "unsigned_short": "u2",
                 "short": "i2", "unsigned_int": "u4", "int": "i4", "unsigned_long": "u8",
                 "long": "i8", "vtktypeint64": "i8", "vtktypeuint64": "u8", "vtkidtype": "i4",
                 "float": "f4", "double": "f8"}
#: VTK cell types: surface cells kept, 0D/1D cells ignored, anything else refused
_TRIANGLE, _STRIP, _POLYGON, _PIXEL, _QUAD = 5, 6, 7, 8, 9
_NO_FACES = {0, 1, 2, 3, 4}


class _Bad(Exception):
    """A structural problem; `read_vtk_file` turns it into one InputError naming the file."""


def read_vtk_file(path, data: bytes | None = None):
    """Points and triangles of a legacy or XML VTK file.

    Parameters
    ----------
    path : str or os.PathLike
        The file (named in errors).
    data : bytes, optional
        Its content, if already read.

    Returns
    -------
    points : (V, 3) float64
    faces : (T, 3) int64
        Every index in ``0..V-1``; (0, 3) for a point cloud.

    Raises
    ------
    InputError
        Anything that does not add up (counts, offsets, indices, sizes, encodings).
    """
    if data is None:
        with open(path, "rb") as fh:
            data = fh.read()
    try:
        head = data[:256].lstrip()
        if head.startswith(b"# vtk DataFile"):
            points, cells = _legacy(data)
        elif head.startswith(b"<"):
            from .vtk_xml import read_xml

            points, cells = read_xml(data)
        else:
            raise _Bad("neither a legacy VTK file ('# vtk DataFile ...') nor a VTK XML file")
        return points, _triangles(cells, len(points))
    except _Bad as exc:
        raise InputError(str(exc), file=path,
                         fix="The file is damaged or not a VTK surface; re-export it (e.g. as .vtp "
                             "or .stl).") from None


# ---------------------------------------------------------------------------- shared checks
def _count(text, what) -> int:
    try:
        n = int(text)
    except (TypeError, ValueError):
        raise _Bad(f"{what}: {text!r} is not a whole number") from None
    if n < 0:
        raise _Bad(f"{what}: negative count {n}")
    return n


def _check_bytes(n_bytes, what):
    if n_bytes > MAX_ARRAY_BYTES:
        raise _Bad(f"{what}: declares {n_bytes} bytes, more than a surface file can hold")


def _cells_from_offsets(offsets, conn, n_points, what, *, leading_zero):
    """Validated (starts (K,), sizes (K,), conn (L,)) from an offsets array."""
    offsets = np.asarray(offsets).astype(np.int64, copy=False)
    conn = np.asarray(conn).astype(np.int64, copy=False)
    if leading_zero:
        if offsets.size == 0:
            raise _Bad(f"{what}: empty OFFSETS array")
        if offsets[0] != 0:
            raise _Bad(f"{what}: the cell OFFSETS must start at 0, got {offsets[0]}")
        ends = offsets[1:]
    else:
        ends = offsets
    starts = np.concatenate([[0], ends[:-1]]) if ends.size else np.zeros(0, np.int64)
    if ends.size and (np.any(np.diff(np.concatenate([[0], ends])) < 0) or ends[-1] != conn.size):
        raise _Bad(f"{what}: the cell OFFSETS are not increasing or do not end at the "
                   f"connectivity size {conn.size}")
    if not ends.size and conn.size:
        raise _Bad(f"{what}: connectivity without offsets")
    if conn.size and (conn.min() < 0 or conn.max() >= n_points):
        raise _Bad(f"{what}: a cell refers to point {int(conn.max() if conn.max() >= n_points else conn.min())}"
                   f" but there are {n_points} points")
    return starts, ends - starts, conn


def _cells_from_classic(arr, n_cells, n_points, what):
    """The classic layout ``n i0 .. i(n-1)`` per cell, validated, as (starts, sizes, conn)."""
    arr = np.asarray(arr).astype(np.int64, copy=False)
    if n_cells == 0:
        if arr.size:
            raise _Bad(f"{what}: data for 0 cells")
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    k = int(arr[0]) if arr.size else -1
    if k >= 0 and arr.size == n_cells * (k + 1) and np.all(arr[:: k + 1] == k):
        starts = np.arange(n_cells, dtype=np.int64) * (k + 1) + 1            # uniform (triangles)
        sizes = np.full(n_cells, k, np.int64)
    else:                                                                     # mixed sizes: walk
        starts, sizes = np.empty(n_cells, np.int64), np.empty(n_cells, np.int64)
        pos = 0
        for c in range(n_cells):
            if pos >= arr.size or arr[pos] < 0 or pos + 1 + arr[pos] > arr.size:
                raise _Bad(f"{what}: cell {c} runs past the end of the cell array")
            starts[c], sizes[c] = pos + 1, arr[pos]
            pos += 1 + int(arr[pos])
        if pos != arr.size:
            raise _Bad(f"{what}: {arr.size - pos} values left over after {n_cells} cells")
    index = np.repeat(starts, sizes) + (np.arange(sizes.sum()) - np.repeat(np.cumsum(sizes) - sizes, sizes))
    conn = arr[index]
    if conn.size and (conn.min() < 0 or conn.max() >= n_points):
        raise _Bad(f"{what}: a cell refers to a point outside 0..{n_points - 1}")
    return np.cumsum(sizes) - sizes, sizes, conn


def _triangles(cells, n_points):
    """(T, 3) triangles from the validated cell groups [(kind, starts, sizes, conn), ...]."""
    out = []
    for kind, starts, sizes, conn in cells:
        if kind == "strip":
            for s, n in zip(starts[sizes >= 3], sizes[sizes >= 3]):     # loop over strips (few)
                idx = conn[s:s + n]
                tri = np.stack([idx[:-2], idx[1:-1], idx[2:]], axis=1)
                tri[1::2, :2] = tri[1::2, 1::-1]
                out.append(tri)
            continue
        if kind == "pixel":
            keep = sizes == 4
            base = starts[keep]
            quad = conn[base[:, None] + np.array([0, 1, 3, 2])]
            out.append(quad[:, [0, 1, 2]])
            out.append(quad[:, [0, 2, 3]])
            continue
        for n in np.unique(sizes[sizes >= 3]):                              # fan per polygon size
            base = starts[sizes == n]
            ring = conn[base[:, None] + np.arange(n)]
            j = np.arange(1, n - 1)
            out.append(np.stack([np.repeat(ring[:, :1], n - 2, axis=1), ring[:, j], ring[:, j + 1]],
                                axis=2).reshape(-1, 3))
    faces = np.concatenate(out).astype(np.int64) if out else np.zeros((0, 3), np.int64)
    if faces.size and (faces.min() < 0 or faces.max() >= n_points):   # pragma: no cover - checked
        raise _Bad("a face refers to a point that does not exist")
    return faces


def _unstructured(starts, sizes, conn, types, what):
    """Cell groups of an unstructured grid by VTK cell type (surface cells only)."""
    types = np.asarray(types).astype(np.int64, copy=False)
    if types.size != starts.size:
        raise _Bad(f"{what}: {types.size} cell types for {starts.size} cells")
    bad = ~np.isin(types, [_TRIANGLE, _STRIP, _POLYGON, _PIXEL, _QUAD, *_NO_FACES])
    if bad.any():
        raise _Bad(f"{what}: cell type {int(types[bad][0])} is not a surface cell (3D or "
                   "higher-order cells cannot be read as a muscle surface; export the surface)")
    groups = []
    for kind, codes in (("poly", (_TRIANGLE, _POLYGON, _QUAD)), ("strip", (_STRIP,)),
                        ("pixel", (_PIXEL,))):
        m = np.isin(types, codes)
        if m.any():
            groups.append((kind, starts[m], sizes[m], conn))
    return groups


# ---------------------------------------------------------------------------- legacy .vtk
class _Legacy:
    """A cursor over a legacy file: keyword lines, and ASCII or big-endian binary arrays."""

    def __init__(self, data: bytes):
        self.data, self.pos = data, 0

    def line(self, *, skip_blank=True):
        data = self.data
        while True:
            if self.pos >= len(data):
                return None
            end = data.find(b"\n", self.pos)
            end = len(data) if end < 0 else end
            text = data[self.pos:end].strip()
            self.pos = end + 1
            if text or not skip_blank:
                return text.decode("latin-1")

    def words(self):
        text = self.line()
        return None if text is None else text.split()

    def array(self, n, vtype, binary, what):
        dt = _LEGACY_TYPES.get(vtype.lower())
        if dt is None:
            raise _Bad(f"{what}: unsupported data type {vtype!r}")
        dtype = np.dtype(dt).newbyteorder(">")
        _check_bytes(n * dtype.itemsize, what)
        if binary:
            end = self.pos + n * dtype.itemsize
            if end > len(self.data):
                raise _Bad(f"{what}: the file ends inside the binary data ({n} values declared)")
            out = np.frombuffer(self.data, dtype=dtype, count=n, offset=self.pos)
            self.pos = end
            return out
        if n == 0:
            return np.zeros(0, dtype)
        parts = self.data[self.pos:].split(None, n)
        if len(parts) < n:
            raise _Bad(f"{what}: {len(parts)} values where {n} are declared")
        self.pos = len(self.data) - (len(parts[n]) if len(parts) > n else 0)
        try:
            return np.array(parts[:n]).astype(dtype.newbyteorder("="))
        except ValueError:
            raise _Bad(f"{what}: a value is not a number") from None


def _legacy(data):
    cur = _Legacy(data)
    cur.line()                                                   # '# vtk DataFile Version x.y'
    cur.line(skip_blank=False)                                   # the title (may be empty)
    mode = (cur.line() or "").upper()
    if mode not in ("ASCII", "BINARY"):
        raise _Bad(f"line 3 must be ASCII or BINARY, got {mode[:40]!r}")
    binary = mode == "BINARY"
    words = cur.words() or []
    if len(words) != 2 or words[0].upper() != "DATASET":
        raise _Bad("line 4 must be 'DATASET <type>'")
    kind = words[1].upper()
    if kind not in ("POLYDATA", "UNSTRUCTURED_GRID"):
        raise _Bad(f"dataset type {kind} is not a surface (POLYDATA or UNSTRUCTURED_GRID)")
    points, cells, ugrid, types = None, [], None, None
    while True:
        words = cur.words()
        if words is None:
            break
        key = words[0].upper()
        if key in ("POINT_DATA", "CELL_DATA"):
            break
        if key == "METADATA":
            while cur.line(skip_blank=False):                   # up to the blank line
                pass
        elif key == "FIELD":
            if len(words) != 3:
                raise _Bad("FIELD needs a name and an array count")
            for k in range(_count(words[2], "FIELD")):
                spec = cur.words()
                if spec is None or len(spec) != 4:
                    raise _Bad(f"FIELD array {k}: expected 'name components tuples type'")
                n = _count(spec[1], "FIELD components") * _count(spec[2], "FIELD tuples")
                cur.array(n, spec[3], binary, f"FIELD array {spec[0]}")
        elif key == "POINTS":
            if len(words) != 3:
                raise _Bad("POINTS needs a count and a type")
            n = _count(words[1], "POINTS")
            points = cur.array(3 * n, words[2], binary, "POINTS").astype(np.float64).reshape(n, 3)
        elif key in ("VERTICES", "LINES", "POLYGONS", "TRIANGLE_STRIPS", "CELLS"):
            if points is None:
                raise _Bad(f"{key} before POINTS")
            if len(words) != 3:
                raise _Bad(f"{key} needs two counts")
            got = _legacy_cells(cur, key, _count(words[1], key), _count(words[2], key), binary,
                                len(points))
            if key == "CELLS":
                ugrid = got
            elif key in ("POLYGONS", "TRIANGLE_STRIPS"):
                cells.append(("strip" if key == "TRIANGLE_STRIPS" else "poly",) + got)
        elif key == "CELL_TYPES":
            if len(words) != 2:
                raise _Bad("CELL_TYPES needs a count")
            types = cur.array(_count(words[1], "CELL_TYPES"), "int", binary, "CELL_TYPES")
        else:
            raise _Bad(f"unexpected keyword {key[:40]!r}")
    if points is None:
        raise _Bad("no POINTS section")
    if kind == "UNSTRUCTURED_GRID" and ugrid is not None:
        if types is None:
            raise _Bad("CELLS without CELL_TYPES")
        cells = _unstructured(*ugrid, types, "CELLS")
    return points, cells


def _legacy_cells(cur, key, a, b, binary, n_points):
    """One cell section: the 5.x layout (``key n_offsets n_conn`` + OFFSETS + CONNECTIVITY) or
    the classic one (``key n_cells size`` + size ints)."""
    save = cur.pos
    words = cur.words()
    if words and words[0].upper() == "OFFSETS":
        if len(words) != 2:
            raise _Bad(f"{key}: OFFSETS needs a type")
        offsets = cur.array(a, words[1], binary, f"{key} OFFSETS")
        words = cur.words()
        if not words or words[0].upper() != "CONNECTIVITY" or len(words) != 2:
            raise _Bad(f"{key}: CONNECTIVITY missing after OFFSETS")
        conn = cur.array(b, words[1], binary, f"{key} CONNECTIVITY")
        return _cells_from_offsets(offsets, conn, n_points, key, leading_zero=True)
    cur.pos = save
    arr = cur.array(b, "int", binary, key)
    return _cells_from_classic(arr, a, n_points, key)
