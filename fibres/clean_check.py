"""The fast validation of a clean surface: would `fibres.surface.as_surface` return the mesh
unchanged with nothing to repair? Checked without building trimesh's structures (~20x faster
than the repair on a clean 15K-vertex mesh), mirroring each step of
`fibres.surface._repair` conservatively (when in doubt the mesh is not clean and the full
repair runs). The topology built by the check (`fibres.slicing.MeshTopology`) and the faces'
mean edge length are kept for the decomposition.
"""
from __future__ import annotations

import numpy as np

# called by the compiled _geometry_loop (numba resolves its globals when compiling it)
from .slicing import _face_measure, _vertex_bounds  # noqa: F401

__all__ = ["clean_topology", "clean_mesh_geometry"]


def clean_topology(v, f):
    """The mesh topology of (v, f) if `fibres.surface.as_surface` would return it unchanged
    with nothing to repair, else None -- checked without building the trimesh structures
    (~20x faster than the repair on a clean 15K-vertex mesh).

    Parameters
    ----------
    v : (V, 3) float64
        Vertices in metres.
    f : (T, 3) int64
        Faces, indices already checked to lie in ``[0, V)``.

    Returns
    -------
    fibres.slicing.MeshTopology or None

    Mirrors each step of `fibres.surface._repair` (conservatively: when in doubt, None and the full
    repair runs): every vertex referenced; no two vertices merged at trimesh's merge
    precision (rows of ``round(v * 10**digits)`` distinct); every triangle's edges and
    heights above trimesh's merge tolerance (with a factor 2 margin); no duplicate faces and
    one piece (edge-adjacent faces; a closed manifold mesh in one piece has no duplicate
    faces); closed, manifold and consistently wound (each edge used once in each
    direction); positive volume. The geometry runs component-wise on (3, T) corner arrays
    (numpy's cross and norm over a size-3 axis are ~10x slower).
    """
    return clean_mesh_geometry(v, f)[0]


def clean_mesh_geometry(v, f):
    """`clean_topology` and, for a clean mesh, the mean length of the faces' edges (the
    edge lengths are computed by the check anyway).

    Parameters
    ----------
    v : (V, 3) float64
    f : (T, 3) int64

    Returns
    -------
    topology : fibres.slicing.MeshTopology or None
    mean_edge : float or None
        Mean over the 3 T directed face edges (None when the mesh is not clean).
    """
    from trimesh import tol, util

    from .slicing import _closed_topology

    n_v = len(v)
    if len(f) < 4:
        return None, None
    kernel = _geometry_kernel()
    # topology, pieces, all vertices used; and the faces measured in the same pass
    closed = _closed_topology(f, n_v, np.ascontiguousarray(v) if kernel is not None else None,
                              2 * tol.merge)
    if closed is None and (f.min() < 0 or f.max() >= n_v
                           or np.bincount(f.ravel(), minlength=n_v).min() == 0):
        return None, None
    if closed is not None and not closed[2]:
        return None, None
    f = closed[0].faces if closed is not None else f   # the kernel's C-contiguous copy
    if _has_merged_vertices(v, 10 ** util.decimal_to_digits(tol.merge)):
        return None, None
    if kernel is not None:
        ok, volume, edge_sum, lo, hi = closed[3] if closed is not None else kernel(
            np.ascontiguousarray(v), np.ascontiguousarray(f), 2 * tol.merge)
        if not ok:
            return None, None
        return _clean_topology_rest(v, f, volume, edge_sum / (3 * len(f)), closed,
                                    extent=hi - lo)
    vt = np.ascontiguousarray(v.T)                                 # (3, V)
    a, b, c = np.take(vt, np.ascontiguousarray(f.T), axis=1).transpose(1, 0, 2)  # (3, T) each
    ab, ac, bc = b - a, c - a, c - b
    lab, lbc, lac = np.sqrt(_dot3(ab, ab)), np.sqrt(_dot3(bc, bc)), np.sqrt(_dot3(ac, ac))
    n = _cross3(ab, ac)                                             # (3, T), |n| = 2 area
    area2 = np.sqrt(_dot3(n, n))
    # trimesh: both edges from the first corner and the heights over them > tol.merge
    if not ((np.minimum(np.minimum(lab, lbc), lac) > 2 * tol.merge)
            & (area2 > 2 * tol.merge * np.maximum(np.maximum(lab, lbc), lac))).all():
        return None, None
    return _clean_topology_rest(v, f, float(_dot3(a, _cross3(b, c)).sum()),
                                float((lab.sum() + lbc.sum() + lac.sum()) / (3 * len(f))),
                                closed)


def _clean_topology_rest(v, f, volume, mean_edge, closed=None, extent=None):
    """The topological steps of `clean_mesh_geometry` and the volume check; ``closed``:
    `fibres.slicing._closed_topology` of the faces when at hand, ``extent`` the vertices'
    bounding-box sides when known."""
    from .slicing import mesh_topology

    if closed is not None:
        topology, n_pieces = closed[0], closed[1]
    else:
        try:
            topology = mesh_topology(f, len(v))
        except ValueError:
            return None, None
        n_pieces = _n_pieces(topology.neighbours) if topology.oriented else 0
    if not topology.oriented or n_pieces != 1:
        return None, None
    if extent is None:
        vt = np.ascontiguousarray(v.T)
        extent = vt.max(axis=1) - vt.min(axis=1)
    size = float(np.linalg.norm(extent))
    if not volume > 1e-9 * size ** 3:
        return None, None
    return topology, float(mean_edge)


_GEOMETRY = []


def _geometry_kernel():
    """`_geometry_loop` compiled with numba, or None (then numpy, component-wise)."""
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)


def _geometry_loop(v, f, tol2):  # pragma: no cover - compiled by numba
    """One pass over the faces: (every edge and the height over the first corner's edges
    above ``tol2``, signed volume x 6, sum of the edge lengths, min and max (3,) of the
    vertices' coordinates)."""
    volume = 0.0
    edge_sum = 0.0
    ok = True
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    _vertex_bounds(v, lo, hi)
    for t in range(f.shape[0]):
        face_ok, vol, edges_t = _face_measure(v, f[t, 0], f[t, 1], f[t, 2], tol2)
        if not face_ok:
            ok = False
        volume += vol
        edge_sum += edges_t
    return ok, volume, edge_sum, lo, hi


def _dot3(p, q):
    """Dot product of (3, T) arrays along axis 0."""
    return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]


def _cross3(p, q):
    """Cross product of (3, T) arrays along axis 0."""
    return np.stack([p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2],
                     p[0] * q[1] - p[1] * q[0]])


def _has_merged_vertices(v, scale):
    """Whether trimesh's merge would merge two vertices: two rows of
    ``(v * scale).round().astype(np.int64)`` equal (``scale = 10**digits``, an int).
    Compiled, one pass that rounds the rows itself (`_duplicates_loop`, no (V, 3)
    temporaries); in numpy (`_has_duplicate_rows`) without numba or when a coordinate rounds
    beyond the int64 range (numpy's cast decides those)."""
    kernel = _duplicates_kernel()
    if kernel is not None:
        out = kernel(np.ascontiguousarray(v, dtype=np.float64), float(scale))
        if out >= 0:
            return bool(out)
    return _has_duplicate_rows((v * scale).round().astype(np.int64))


_DUPLICATES = []


def _duplicates_kernel():
    """`_duplicates_loop` compiled with numba, or None (then the sort of the row hashes)."""
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)


def _duplicates_loop(v, scale):  # pragma: no cover - compiled by numba
    """1 if two rows of ``q = rint(v * scale)`` (v (V, 3) float64; rint rounds half to even
    as numpy's round) are equal, else 0, in O(V); -1 (undecided) when some ``|q|`` is not
    below 2**63 (or NaN), where numpy's int64 cast is not exact. A row hash of the int64
    rows picks a slot of a table of >= 4 V slots (linear probing; Knuth, TAOCP vol. 3, §6.4,
    algorithm L; at most a quarter full, so few rows probe twice: on the 15K bench mesh
    0.126 -> 0.074 ms against 2 V slots, 8 V no faster); rows meeting in a probe sequence
    are compared exactly (equal int64 rows are equal rounded rows, -0.0 == 0.0 included;
    the answer does not depend on the hash)."""
    n = v.shape[0]
    size = 1
    while size < 4 * n:
        size *= 2
    mask = size - 1
    slot = np.full(size, -1, np.int32)  # (V < 2**31 rows: a vertex index)
    big = 9.223372036854775808e18  # 2**63
    for i in range(n):
        x = np.rint(v[i, 0] * scale)
        y = np.rint(v[i, 1] * scale)
        z = np.rint(v[i, 2] * scale)
        if not (abs(x) < big and abs(y) < big and abs(z) < big):
            return -1
        h = (np.int64(x) * np.int64(-7046029254386353131) + np.int64(y)) \
            * np.int64(0x5851F42D4C957F2D) + np.int64(z)
        k = (h ^ (h >> 29)) & mask
        while slot[k] >= 0:
            r = slot[k]
            if (np.rint(v[r, 0] * scale) == x and np.rint(v[r, 1] * scale) == y
                    and np.rint(v[r, 2] * scale) == z):
                return 1
            k = (k + 1) & mask
        slot[k] = i
    return 0


def _has_duplicate_rows(q):
    """Whether two rows of the (V, 3) int64 array are equal, in numpy: one sort of a row hash
    (~4x faster than a lexsort of the rows), only rows of equal hashes compared row by row."""
    h = (q[:, 0] * np.int64(-7046029254386353131) + q[:, 1]) * np.int64(0x5851F42D4C957F2D) \
        + q[:, 2]                                            # wraps around: a hash, not a key
    if not (np.diff(np.sort(h)) == 0).any():
        return False
    order = np.argsort(h, kind="stable")
    same = np.flatnonzero(np.diff(h[order]) == 0)
    sub = np.unique(np.concatenate([order[same], order[same + 1]]))
    qs = q[sub][np.lexsort(q[sub].T)]
    return bool((np.diff(qs, axis=0) == 0).all(axis=1).any())


def _n_pieces(neighbours):
    """Number of edge-connected pieces of a closed mesh from its (T, 3) face neighbours
    (scipy's connected components). Only the path without the compiled topology pass needs
    it: that pass counts the pieces itself (`fibres.slicing._topology_loop`)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n_f = len(neighbours)
    rows = np.repeat(np.arange(n_f), 3)
    graph = coo_matrix((np.ones(rows.size), (rows, neighbours.ravel())), shape=(n_f, n_f))
    return connected_components(graph, directed=False, return_labels=False)


