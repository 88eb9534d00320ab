"""The fast validation of a clean surface: would `fibres.mesh.surface.as_surface` return the mesh
unchanged with nothing to repair? Checked without building trimesh's structures (~20x faster
than the repair on a clean 15K-vertex mesh), mirroring each step of
`fibres.mesh.surface._repair` conservatively (when in doubt the mesh is not clean and the full
repair runs). The topology built by the check (`fibres.slicing.planes.MeshTopology`) and the faces'
mean edge length are kept for the decomposition.
"""
from __future__ import annotations

import numpy as np
from numba import njit


__all__ = ["clean_topology", "clean_mesh_geometry"]


def clean_topology(v, f):
    """The mesh topology of (v, f) if `fibres.mesh.surface.as_surface` would return it unchanged
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
    fibres.slicing.planes.MeshTopology or None

    Mirrors each step of `fibres.mesh.surface._repair` (conservatively: when in doubt, None and the full
    repair runs): every vertex referenced; no two vertices merged at trimesh's merge
    precision (rows of ``round(v * 10**digits)`` distinct); every triangle's edges and
    heights above trimesh's merge tolerance (with a factor 2 margin); no duplicate faces and
    one piece (edge-adjacent faces; a closed manifold mesh in one piece has no duplicate
    faces); closed, manifold and consistently wound (each edge used once in each
    direction); positive volume. The topology comes first (`fibres.slicing.planes.mesh_topology`),
    then one compiled pass over the faces measures their shape, the volume, the edge lengths
    and the pieces (`_face_sums`).
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
    topology : fibres.slicing.planes.MeshTopology or None
    mean_edge : float or None
        Mean over the 3 T directed face edges (None when the mesh is not clean).
    """
    from trimesh import tol, util

    from ..slicing.planes import mesh_topology

    n_v = len(v)
    if len(f) < 4:
        return None, None
    if f.min() < 0 or f.max() >= n_v or np.bincount(f.ravel(), minlength=n_v).min() == 0:
        return None, None
    if _has_merged_vertices(v, 10 ** util.decimal_to_digits(tol.merge)):
        return None, None
    try:
        topology = mesh_topology(f, n_v)
    except ValueError:
        return None, None
    if not topology.oriented:
        return None, None
    well_shaped, volume, edge_sum, n_pieces = _face_sums(
        np.ascontiguousarray(v, dtype=np.float64), topology.faces, topology.neighbours,
        2.0 * float(tol.merge))
    if not well_shaped or n_pieces != 1:
        return None, None
    extent = np.array([v[:, k].max() - v[:, k].min() for k in range(3)])   # column by column
    if not volume > 1e-9 * float(np.linalg.norm(extent)) ** 3:
        return None, None
    return topology, edge_sum / (3 * len(f))


@njit(cache=True, nogil=True, error_model="numpy")
def _face_sums(v, f, neighbours, limit):
    """(well shaped, 6 x volume, sum of the faces' edge lengths, pieces) of a closed,
    consistently wound mesh. Well shaped: every face's sides longer than ``limit`` and its
    heights over its longest side above ``limit`` (trimesh drops the faces whose edges from
    the first corner or heights are within its merge tolerance; ``limit`` is twice that).
    Volume: the sum of ``a . (b x c)`` over the faces (a, b, c their corners). Pieces: the
    edge-connected components of the faces, by union-find over the ``neighbours`` table."""
    ok = True
    volume, s_ab, s_bc, s_ac = 0.0, 0.0, 0.0, 0.0
    for t in range(f.shape[0]):
        a, b, c = v[f[t, 0]], v[f[t, 1]], v[f[t, 2]]
        ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
        ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
        bc0, bc1, bc2 = c[0] - b[0], c[1] - b[1], c[2] - b[2]
        lab = np.sqrt(ab0 * ab0 + ab1 * ab1 + ab2 * ab2)
        lbc = np.sqrt(bc0 * bc0 + bc1 * bc1 + bc2 * bc2)
        lac = np.sqrt(ac0 * ac0 + ac1 * ac1 + ac2 * ac2)
        n0, n1, n2 = ab1 * ac2 - ab2 * ac1, ab2 * ac0 - ab0 * ac2, ab0 * ac1 - ab1 * ac0
        area2 = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)                  # twice the area
        if not (min(min(lab, lbc), lac) > limit and area2 > limit * max(max(lab, lbc), lac)):
            ok = False
        volume += (a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2])
                   + a[2] * (b[0] * c[1] - b[1] * c[0]))
        s_ab += lab
        s_bc += lbc
        s_ac += lac
    root = np.arange(f.shape[0])
    for t in range(f.shape[0]):
        for k in range(3):
            x, y = t, neighbours[t, k]
            while root[x] != x:
                root[x] = root[root[x]]
                x = root[x]
            while root[y] != y:
                root[y] = root[root[y]]
                y = root[y]
            if x != y:
                root[max(x, y)] = min(x, y)
    pieces = 0
    for t in range(f.shape[0]):
        if root[t] == t:
            pieces += 1
    return ok, volume, s_ab + s_bc + s_ac, pieces


def _has_merged_vertices(v, scale):
    """Whether trimesh's merge would merge two vertices: two rows of
    ``(v * scale).round().astype(np.int64)`` equal (``scale = 10**digits``, an int).
    (`_has_duplicate_rows`)."""
    return _has_duplicate_rows((v * scale).round().astype(np.int64))


def _has_duplicate_rows(q):
    """Whether two rows of the (V, 3) int64 array are equal, in numpy: one sort of a row hash
    (instead of a lexsort of the rows), only rows of equal hashes compared row by row."""
    h = (q[:, 0] * np.int64(-7046029254386353131) + q[:, 1]) * np.int64(0x5851F42D4C957F2D) \
        + q[:, 2]                                            # wraps around: a hash, not a key
    if not (np.diff(np.sort(h)) == 0).any():
        return False
    order = np.argsort(h, kind="stable")
    same = np.flatnonzero(np.diff(h[order]) == 0)
    sub = np.unique(np.concatenate([order[same], order[same + 1]]))
    qs = q[sub][np.lexsort(q[sub].T)]
    return bool((np.diff(qs, axis=0) == 0).all(axis=1).any())
