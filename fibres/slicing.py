"""Many parallel planes cut a closed triangle mesh into closed 2D loops, all at once.

The sweep of Kohout et al. (GRAPP 2012, section 3.3) cuts the muscle surface with planes
perpendicular to its principal axis. Here every plane of the sweep is cut in one pass:

1. Heights of all vertices along the axis are computed once (one matrix product); each
   plane is a shift of them.
2. An edge crosses plane ``s`` when ``min(d_a, d_b) <= h_s < max(d_a, d_b)`` (a vertex
   exactly on a plane counts as below it), so the planes an edge crosses are a contiguous
   run of the sorted heights: two ``searchsorted`` calls enumerate every (plane, edge)
   crossing without looping over planes. Faces are enumerated the same way.
3. Chaining: each crossed face holds one segment between its two crossed edges. With the
   faces wound consistently, the face's half-edge going from above to below is followed by
   its half-edge going from below to above; this defines a permutation ``next`` over all
   crossings of all planes whose cycles are the loops. The cycles are found by pointer
   doubling (log2 of the largest loop size array passes), then sorted into loop order.
   The mesh topology (unique edges, face-to-edge table) is computed once per mesh by
   `mesh_topology` and reused for every plane, frame and perturbed pose.

Each section is returned as 2D points in the plane frame (the first two frame axes); the
frame's 4x4 matrix maps ``(u, v, h, 1)`` back to 3D.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MeshTopology", "Sections", "mesh_topology", "slice_mesh"]


def _readonly(*arrays):
    for a in arrays:
        a.flags.writeable = False


@dataclass(frozen=True)
class MeshTopology:
    """Edge/face tables of a closed triangle mesh (computed once, reused for every frame).

    Attributes
    ----------
    faces : (T, 3) int64
    edges : (E, 2) int64
        Unique undirected edges, ``edges[:, 0] < edges[:, 1]``.
    face_edges : (T, 3) int64
        ``face_edges[t, j]`` is the edge of half-edge ``faces[t, j] -> faces[t, (j+1) % 3]``.
    neighbours : (T, 3) int64
        The other face sharing ``face_edges[t, j]``.
    n_vertices : int
    oriented : bool
        Whether the faces are wound consistently (each edge used once in each direction).
    """

    faces: np.ndarray
    edges: np.ndarray
    face_edges: np.ndarray
    neighbours: np.ndarray
    n_vertices: int
    oriented: bool = True

    def __post_init__(self):
        _readonly(self.faces, self.edges, self.face_edges, self.neighbours)


def mesh_topology(faces, n_vertices: int) -> MeshTopology:
    """Build the unique edges and face-to-edge table of a closed (watertight) mesh.

    Parameters
    ----------
    faces : (T, 3) int
    n_vertices : int

    Returns
    -------
    MeshTopology

    Raises
    ------
    ValueError
        If some edge is not shared by exactly two faces (the surface is not closed and
        manifold, so plane sections would not be closed loops).
    """
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must have shape (T, 3), got {f.shape}")
    kernel = _topology_kernel()
    if kernel is not None and f.size:
        out = kernel(f, np.int64(n_vertices), False, _NO_VERTICES, 0.0)
        if out[0]:                                          # every edge exactly twice
            return MeshTopology(f, out[1], out[2], out[3], int(n_vertices), bool(out[4]))
    a = f.reshape(-1)
    b = np.roll(f, -1, axis=1).reshape(-1)
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    key = lo * np.int64(n_vertices) + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    if ks.size % 2 == 0 and ks.size and (ks[0::2] == ks[1::2]).all() \
            and (ks[2::2] != ks[1:-1:2]).all():
        # the common case, every edge twice: sorted half-edges pair up as (2e, 2e+1)
        return _paired_topology(f, a, b, lo, hi, order, int(n_vertices))
    first = np.ones(ks.size, dtype=bool)
    first[1:] = ks[1:] != ks[:-1]
    edge_of_sorted = np.cumsum(first) - 1
    counts = np.bincount(edge_of_sorted)
    if counts.size == 0 or np.any(counts != 2):
        raise ValueError("faces: every edge must be shared by exactly two faces "
                         f"({int(np.sum(counts != 2))} edges are not); the surface is not closed")
    face_edges = np.empty(a.size, dtype=np.int64)
    face_edges[order] = edge_of_sorted
    firsts = order[first]
    edges = np.stack([lo[firsts], hi[firsts]], axis=1)
    # sorted half-edges come in twin pairs (positions 2e, 2e+1): swap to get the neighbour.
    twin = np.empty(a.size, dtype=np.int64)
    twin[order[0::2]] = order[1::2]
    twin[order[1::2]] = order[0::2]
    neighbours = (twin // 3).reshape(-1, 3)
    oriented = bool(np.array_equal(a[order[0::2]], b[order[1::2]]))
    return MeshTopology(f, edges, face_edges.reshape(-1, 3), neighbours, int(n_vertices),
                        oriented)


def _closed_topology(f, n_vertices, vertices=None, tol2=0.0):
    """`mesh_topology` of (T, 3) int64 faces with its indices in range, with the number of
    edge-connected pieces and whether every vertex is used -- in one compiled pass (for
    `fibres.clean_check.clean_mesh_geometry`), or None without numba or when some edge is not
    shared by exactly two faces. With ``vertices`` (V, 3) float64 C-contiguous, the same
    pass measures the faces as `fibres.clean_check._geometry_loop` (threshold ``tol2``).

    Returns
    -------
    (MeshTopology, n_pieces, all_used, geometry) or None
        ``geometry``: (every edge and height above tol2, 6 x signed volume, sum of the edge
        lengths, vertex minimum (3,), maximum (3,)) -- `fibres.clean_check._geometry_loop`'s
        results -- or None without ``vertices``.
    """
    kernel = _topology_kernel()
    if kernel is None or not f.size:
        return None
    measure = vertices is not None
    out = kernel(f, np.int64(n_vertices), True, vertices if measure else _NO_VERTICES,
                 float(tol2))
    if not out[0]:
        return None
    return (MeshTopology(out[7], out[1], out[2], out[3], int(n_vertices), bool(out[4])),
            int(out[5]), bool(out[6]),
            (bool(out[8]), out[9], out[10], out[11], out[12]) if measure else None)


#: no vertices: the topology pass measures no geometry
_NO_VERTICES = np.zeros((0, 3))


def _paired_topology(f, a, b, lo, hi, order, n_vertices):
    """`mesh_topology` when the sorted half-edge keys come in pairs (each edge shared by
    exactly two faces): edge ``e`` is the pair of sorted positions ``2e, 2e+1``."""
    even, odd = order[0::2], order[1::2]
    face_edges = np.empty(a.size, dtype=np.int64)
    e = np.arange(even.size, dtype=np.int64)
    face_edges[even] = e
    face_edges[odd] = e
    twin = np.empty(a.size, dtype=np.int64)
    twin[even] = odd
    twin[odd] = even
    oriented = bool(np.array_equal(a[even], b[odd]))
    return MeshTopology(f, np.stack([lo[even], hi[even]], axis=1), face_edges.reshape(-1, 3),
                        (twin // 3).reshape(-1, 3), n_vertices, oriented)


def _vertex_bounds(v, lo, hi):  # pragma: no cover - compiled by numba
    """Coordinate-wise min (max) of the vertices (V, 3) into lo (hi) (3,), in place."""
    lx, ly, lz = lo[0], lo[1], lo[2]
    hx, hy, hz = hi[0], hi[1], hi[2]
    for i in range(v.shape[0]):
        x, y, z = v[i, 0], v[i, 1], v[i, 2]
        lx, ly, lz = min(lx, x), min(ly, y), min(lz, z)
        hx, hy, hz = max(hx, x), max(hy, y), max(hz, z)
    lo[0], lo[1], lo[2] = lx, ly, lz
    hi[0], hi[1], hi[2] = hx, hy, hz


def _face_measure(v, i, j, k, tol2):  # pragma: no cover - compiled by numba
    """Face (i, j, k) of vertices v: (every edge and the height over the first corner's
    edges above ``tol2``, the signed volume term x 6, the sum of its edge lengths)."""
    ax, ay, az = v[i, 0], v[i, 1], v[i, 2]
    bx, by, bz = v[j, 0], v[j, 1], v[j, 2]
    cx, cy, cz = v[k, 0], v[k, 1], v[k, 2]
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    bcx, bcy, bcz = cx - bx, cy - by, cz - bz
    lab = np.sqrt(abx * abx + aby * aby + abz * abz)
    lbc = np.sqrt(bcx * bcx + bcy * bcy + bcz * bcz)
    lac = np.sqrt(acx * acx + acy * acy + acz * acz)
    nx = aby * acz - abz * acy
    ny = abz * acx - abx * acz
    nz = abx * acy - aby * acx
    area2 = np.sqrt(nx * nx + ny * ny + nz * nz)
    ok = min(lab, lbc, lac) > tol2 and area2 > tol2 * max(lab, lbc, lac)
    return ok, ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx), lab + lbc + lac


def compile_with_measures(fn):
    """``fn`` compiled by numba with `_vertex_bounds`, `_face_measure` and
    `fibres.sort_networks._sort_small` inlined into it (numba resolves the globals a compiled
    function calls when it compiles it)."""
    import types

    import numba

    from .sort_networks import _sort_small

    inline = numba.njit(inline="always", nogil=True)
    glb = dict(fn.__globals__, _vertex_bounds=inline(_vertex_bounds),
               _face_measure=inline(_face_measure), _sort_small=inline(_sort_small))
    return numba.njit(cache=True, nogil=True)(types.FunctionType(fn.__code__, glb, fn.__name__))


_TOPOLOGY = []


def _topology_kernel():
    """`_topology_loop` compiled with numba, or None (then the array version)."""
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)


def _topology_loop(f, n_vertices, pieces, v, tol2):  # pragma: no cover - compiled by numba
    """`mesh_topology` of a mesh whose edges are each shared by exactly two faces, in
    O(T + V): the half-edges are bucketed by their smaller vertex (a counting sort in
    half-edge order; Cormen et al., Introduction to Algorithms, §8.2) and each bucket (a
    vertex's few edges) is sorted by the larger vertex, stably. So the order is that of a
    stable argsort of the keys ``min * V + max`` and edge ``e`` is the pair of sorted
    positions ``2e, 2e+1``, exactly as in the array version. A half-edge is one int64
    ``max << 32 | (2 h + (runs min -> max))`` (T < 2**29): sorting these distinct keys by
    value in a bucket is the stable sort by the larger vertex (ties in half-edge order), with
    one array to move, by a sorting network for 4, 6 or 8 keys (`fibres.sort_networks`:
    nearly every bucket; no data-dependent branches) or else by insertion; the pairing reads
    them in order. With ``pieces``, the edge-connected pieces are counted by a flood fill
    over the face neighbours (depth-first, an explicit stack) and the used vertices marked.
    With vertices ``v`` (V, 3) (else (0, 3)), the first pass also measures each face as
    `fibres.clean_check._geometry_loop` (the same operations in the same order).

    Returns (ok, edges, face_edges, neighbours, oriented, n_pieces, all_used, faces,
    geometry_ok, volume, edge_sum, lo, hi); ``ok``
    is False (and nothing else meaningful) when a vertex index is out of range, an edge is
    not used exactly twice or the mesh is too large for the int32 tables; ``n_pieces``
    is 0 and ``all_used`` False without ``pieces``; ``faces`` is a C-contiguous copy of
    ``f`` (which may be strided) made by the first pass; ``geometry_ok``, ``volume`` and
    ``edge_sum``, ``lo``, ``hi`` are `_geometry_loop`'s (True, 0, 0, inf, -inf without
    vertices)."""
    n_t = f.shape[0]
    n = 3 * n_t
    n_e = n // 2
    edges = np.empty((n_e, 2), dtype=np.int64)
    face_edges = np.empty((n_t, 3), dtype=np.int64)
    neighbours = np.empty((n_t, 3), dtype=np.int64)
    fc = np.empty((n_t, 3), dtype=np.int64)
    v_lo = np.full(3, np.inf)
    v_hi = np.full(3, -np.inf)
    if n % 2 or n_t >= 2 ** 29 or n_vertices >= 2 ** 31:
        return (False, edges, face_edges, neighbours, False, 0, False, fc, False, 0.0, 0.0,
                v_lo, v_hi)
    start = np.zeros(n_vertices + 1, dtype=np.int32)
    measure = v.shape[0] > 0
    volume = 0.0
    edge_sum = 0.0
    geometry_ok = True
    if measure:  # the vertices' bounds (`fibres.clean_check._geometry_loop`)
        _vertex_bounds(v, v_lo, v_hi)
    used = np.zeros(n_vertices if pieces else 0, dtype=np.bool_)
    for t in range(n_t):
        a0, a1, a2 = f[t, 0], f[t, 1], f[t, 2]
        fc[t, 0], fc[t, 1], fc[t, 2] = a0, a1, a2
        if min(a0, min(a1, a2)) < 0 or max(a0, max(a1, a2)) >= n_vertices:
            return (False, edges, face_edges, neighbours, False, 0, False, fc, False, 0.0,
                    0.0, v_lo, v_hi)
        start[min(a0, a1) + 1] += 1
        start[min(a1, a2) + 1] += 1
        start[min(a2, a0) + 1] += 1
        if pieces:
            used[a0] = True
            used[a1] = True
            used[a2] = True
        if measure:  # `fibres.clean_check._geometry_loop`, face t
            face_ok, vol, edges_t = _face_measure(v, a0, a1, a2, tol2)
            if not face_ok:
                geometry_ok = False
            volume += vol
            edge_sum += edges_t
    for q in range(n_vertices):
        start[q + 1] += start[q]
    fill = start[:n_vertices].copy()
    key = np.empty(n, dtype=np.int64)
    for t in range(n_t):  # (from the contiguous copy)
        for j in range(3):
            a = fc[t, j]
            b = fc[t, j + 1] if j < 2 else fc[t, 0]
            lo = min(a, b)
            p = fill[lo]
            fill[lo] = p + 1
            key[p] = (max(a, b) << 32) | (2 * (3 * t + j) + (a < b))
    for vb in range(n_vertices):  # each bucket sorted by key: a network for 4, 6 or 8
        s0 = start[vb]            # keys (nearly all buckets), else insertion
        if _sort_small(key, s0, start[vb + 1] - s0):
            continue
        for i in range(s0 + 1, start[vb + 1]):
            x = key[i]
            m = i - 1
            while m >= s0 and key[m] > x:
                key[m + 1] = key[m]
                m -= 1
            key[m + 1] = x
    fe = face_edges.ravel()
    nb = neighbours.ravel()
    oriented = True
    vb = 0
    for e in range(n_e):  # edge e: sorted positions p = 2e, p + 1, in bucket vb
        p = 2 * e
        while start[vb + 1] <= p:
            vb += 1
        k0 = key[p]
        k1 = key[p + 1]
        hi = k0 >> 32
        if start[vb + 1] == p + 1 or hi != (k1 >> 32) or (
                p > start[vb] and (key[p - 1] >> 32) == hi):
            return (False, edges, face_edges, neighbours, False, 0, False, fc, False, 0.0,
                    0.0, v_lo, v_hi)
        x0 = k0 & 0xFFFFFFFF
        x1 = k1 & 0xFFFFFFFF
        h0 = x0 >> 1
        h1 = x1 >> 1
        edges[e, 0] = vb
        edges[e, 1] = hi
        fe[h0] = e
        fe[h1] = e
        nb[h0] = h1 // 3
        nb[h1] = h0 // 3
        if (x0 & 1) == (x1 & 1) and hi != vb:   # not one each way
            oriented = False
    n_pieces = 0
    if pieces:  # edge-connected pieces: a flood fill over the face neighbours
        seen = np.zeros(n_t, dtype=np.bool_)
        stack = np.empty(n_t, dtype=np.int32)
        for t in range(n_t):
            if seen[t]:
                continue
            n_pieces += 1
            seen[t] = True
            stack[0] = t
            top = 1
            while top > 0:
                top -= 1
                x = stack[top]
                for j in range(3):
                    y = nb[3 * x + j]
                    if not seen[y]:
                        seen[y] = True
                        stack[top] = y
                        top += 1
    all_used = pieces
    if pieces:
        for vb in range(n_vertices):
            all_used &= used[vb]
    return (True, edges, face_edges, neighbours, oriented, n_pieces, all_used, fc,
            geometry_ok, volume, edge_sum, v_lo, v_hi)


@dataclass(frozen=True)
class Sections:
    """All closed loops cut from a mesh by parallel planes.

    Loops are stored back to back; loop ``l`` is ``points[loop_start[l]:loop_start[l+1]]``
    in chain order (not repeated at the end). Orientation: counter-clockwise in the
    (u, v) plane frame for an outward-wound mesh (the raw chaining order; see
    `fibres.contours` for the clockwise orientation of the paper).

    Attributes
    ----------
    heights : (S,) float
        Plane heights along the frame's third axis.
    points : (K, 2) float
        Loop vertices (u, v) in the plane frame.
    edge : (K,) int64
        Mesh edge (index into ``MeshTopology.edges``) that each vertex lies on.
    t : (K,) float
        Parameter along that edge from ``edges[:, 0]`` to ``edges[:, 1]``.
    loop_start : (L+1,) int64
    loop_slice : (L,) int64
        Plane index of each loop, nondecreasing.
    tf_world_plane : (4, 4) float
        ``world = tf_world_plane @ (u, v, h, 1)``.
    """

    heights: np.ndarray
    points: np.ndarray
    edge: np.ndarray
    t: np.ndarray
    loop_start: np.ndarray
    loop_slice: np.ndarray
    tf_world_plane: np.ndarray

    def __post_init__(self):
        _readonly(self.heights, self.points, self.edge, self.t, self.loop_start,
                  self.loop_slice, self.tf_world_plane)

    def loops_of_slice(self, s: int) -> np.ndarray:
        """Loop indices of plane ``s``: (L_s,) int64."""
        lo, hi = np.searchsorted(self.loop_slice, [s, s + 1])
        return np.arange(lo, hi)

    def loop_points(self, loop: int) -> np.ndarray:
        """(K_l, 2) vertices of one loop."""
        return self.points[self.loop_start[loop]:self.loop_start[loop + 1]]

    def to_world(self, uv, h) -> np.ndarray:
        """Map in-plane points at height ``h`` to 3D.

        Parameters
        ----------
        uv : (..., 2) float
        h : float or (...) float

        Returns
        -------
        (..., 3) float
        """
        uv = np.asarray(uv, dtype=float)
        local = np.concatenate([uv, np.broadcast_to(h, uv.shape[:-1])[..., None]], axis=-1)
        return local @ self.tf_world_plane[:3, :3].T + self.tf_world_plane[:3, 3]


def slice_mesh(vertices, topology: MeshTopology, tf_world_plane, heights, *,
               local_t=None) -> Sections:
    """Cut a closed mesh with the planes ``h = heights[s]`` of a frame, all at once.

    Parameters
    ----------
    vertices : (V, 3) float
    topology : MeshTopology
        From `mesh_topology` on the same faces (any vertex positions).
    tf_world_plane : (4, 4) float
        Rigid frame; its third axis is the plane normal, its first two span the planes.
    heights : (S,) float
        Strictly increasing plane heights along the third axis.
    local_t : (3, V) float, optional
        The vertices already in the plane frame (rows u, v, height), if known.

    Returns
    -------
    Sections
        Every loop of every plane (planes that miss the mesh have none).
    """
    v = np.asarray(vertices, dtype=float)
    tf = np.array(tf_world_plane, dtype=float)
    h = np.asarray(heights, dtype=float)
    if h.ndim != 1 or h.size == 0 or np.any(np.diff(h) <= 0):
        raise ValueError("heights must be a non-empty strictly increasing (S,) array")
    if local_t is None:
        local_t = tf[:3, :3].T @ (v - tf[:3, 3]).T               # (3, V): u, v, height
    d = local_t[2]
    faces, face_edges = topology.faces, topology.face_edges

    # (plane, face) crossings: face crosses plane s iff min d <= h_s < max d. Each is one
    # node of the chaining, standing for the crossing of its "down" half-edge (above ->
    # below); the "up" half-edge's twin is the down half-edge of the next node.
    kernel = _crossings_kernel(3)
    if kernel is not None and local_t.dtype == np.float64:
        pts, node_edge, t, loop_start, loop_slice = kernel(
            np.ascontiguousarray(d), faces, topology.neighbours, face_edges, local_t,
            np.ascontiguousarray(h))
        return Sections(h.copy(), pts, node_edge, t, loop_start, loop_slice, tf)
    node_face, node_slice, down, nxt = _crossings(d, faces, topology.neighbours, h)
    order, loop_start = _loop_order(nxt, node_slice, h.size)
    node_face = node_face[order]                            # pragma: no cover - optional
    node_slice = node_slice[order]
    down = down[order]
    node_edge = face_edges[node_face, down]

    a = faces[node_face, down]                                 # above end of the edge
    b = faces[node_face, (down + 1) % 3]                       # below end
    t = (h[node_slice] - d[a]) / (d[b] - d[a])
    ua, va = local_t[0, a], local_t[1, a]
    pts = np.stack([ua + t * (local_t[0, b] - ua), va + t * (local_t[1, b] - va)], axis=1)
    flip = a > b                                               # t measured from edges[:, 0]
    t = np.where(flip, 1.0 - t, t)
    return Sections(h.copy(), pts, node_edge, t, loop_start, node_slice[loop_start[:-1]], tf)


def _loop_order(nxt, node_slice, n_s):
    """Nodes in loop order: by plane, then by loop (smallest node first), then along the
    loop from its smallest node; and the start of every loop in that order (L+1,).

    Compiled when numba is installed (the cycle walk visits loops by smallest node and
    along each loop; a stable bucketing by plane keeps that order), else a lexsort.
    """
    kernel = _crossings_kernel(1)
    if kernel is not None:
        return kernel(np.ascontiguousarray(nxt, dtype=np.int64),
                      np.ascontiguousarray(node_slice, dtype=np.int64), int(n_s))
    label, rank = _cycles(nxt)                              # pragma: no cover - optional
    order = np.lexsort((rank, label, node_slice))
    lab_sorted = label[order]
    new_loop = np.ones(nxt.size, dtype=bool)
    new_loop[1:] = lab_sorted[1:] != lab_sorted[:-1]
    return order, np.append(np.flatnonzero(new_loop), nxt.size).astype(np.int64)


def _crossings(d, faces, neighbours, h):
    """Every (plane, face) crossing as a node of the chaining: its face, plane, "down"
    half-edge (above -> below) and the node its "up" half-edge leads to.

    Compiled when numba is installed (one pass over the faces, binary searches on the
    heights: the same integers as the array version), else arrays.

    Returns
    -------
    node_face, node_slice, down, nxt : (Q,) int64
        Nodes ordered by face, then plane.
    """
    kernel = _crossings_kernel(0)
    if kernel is not None:
        return kernel(np.ascontiguousarray(d), faces, neighbours, np.ascontiguousarray(h))
    return _crossings_numpy(d, faces, neighbours, h)            # pragma: no cover


def _crossings_numpy(d, faces, neighbours, h):
    """`_crossings` with arrays (no numba)."""
    df = d[faces]                                              # (T, 3)
    f_lo = np.minimum(np.minimum(df[:, 0], df[:, 1]), df[:, 2])
    f_hi = np.maximum(np.maximum(df[:, 0], df[:, 1]), df[:, 2])
    fs0 = _first_at_or_above(h, f_lo)
    n_f = _first_at_or_above(h, f_hi) - fs0
    cf = np.flatnonzero(n_f > 0)
    nfc = n_f[cf]
    n_nodes = int(nfc.sum())
    pair_start = np.zeros(faces.shape[0], dtype=np.int64)
    pair_start[cf] = np.cumsum(nfc) - nfc
    node_face = np.repeat(cf, nfc)
    node_slice = fs0[node_face] + (np.arange(n_nodes) - pair_start[node_face])
    above = df[node_face] > h[node_slice][:, None]             # (Q, 3)
    above_next = above[:, [1, 2, 0]]
    down = np.argmax(above & ~above_next, axis=1)
    up = np.argmax(~above & above_next, axis=1)
    nbr = neighbours[node_face, up]
    nxt = pair_start[nbr] + node_slice - fs0[nbr]
    return node_face, node_slice, down, nxt


_CROSSINGS = []


def _crossings_kernel(which):
    """Compiled `fibres.slice_kernels._crossings_loop` (0), ``_loop_order_loop`` (1),
    ``_points_loop`` (2) or ``_slice_pass`` (3, the three in one call), or None without
    numba."""
    if not _CROSSINGS:
        from .slice_kernels import kernels
        _CROSSINGS.append(kernels())
    return None if _CROSSINGS[0] is None else _CROSSINGS[0][which]


def _first_at_or_above(h, x):
    """``searchsorted(h, x, side="left")``, with an exact arithmetic fast path.

    Parameters
    ----------
    h : (S,) float, strictly increasing
    x : (n,) float

    Returns
    -------
    (n,) int64: the first ``s`` with ``h[s] >= x`` (``S`` if none).
    """
    s = h.size
    if s < 3:
        return np.searchsorted(h, x, side="left")
    step = (h[-1] - h[0]) / (s - 1)
    if not np.allclose(np.diff(h), step, rtol=1e-9, atol=0.0):
        return np.searchsorted(h, x, side="left")
    idx = np.clip(np.ceil((x - h[0]) / step), 0, s).astype(np.int64)
    # exact fix-up: the guess is off by at most one either way.
    hp = np.append(h, np.inf)
    idx -= (idx > 0) & (hp[np.maximum(idx - 1, 0)] >= x)
    idx += hp[idx] < x
    return idx


def _cycles_doubling(nxt):
    """Cycle label (smallest member) and position after it, for a permutation.

    Pointer doubling: after k passes ``jump = nxt^(2^k)`` and ``win[i]`` is the smallest
    node among the 2^k successors of ``i``; descending the stored levels counts the
    steps from each node to its cycle's smallest node.

    Parameters
    ----------
    nxt : (n,) int64 permutation

    Returns
    -------
    label, rank : (n,) int64
    """
    n = nxt.size
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    jumps, wins = [nxt], [nxt.copy()]
    while (1 << len(jumps)) < 2 * n:
        j, w = jumps[-1], wins[-1]
        jumps.append(j[j])
        wins.append(np.minimum(w, w[j]))
    label = np.minimum(np.arange(n), wins[-1])      # the window covers every cycle
    # steps from i forward to its label (0 for the label itself).
    cur = np.arange(n)
    steps = np.zeros(n, dtype=np.int64)
    for level in range(len(jumps) - 1, -1, -1):
        move = wins[level][cur] > label
        move &= cur != label
        cur = np.where(move, jumps[level][cur], cur)
        steps += move.astype(np.int64) << level
    steps = np.where(np.arange(n) == label, 0, steps + 1)
    size = np.bincount(label, minlength=n)[label]
    rank = np.where(steps == 0, 0, size - steps)
    return label, rank


def _cycles(nxt):
    """Cycle label (smallest member) and position after it, for a permutation.

    A compiled walk over the cycles when numba is installed (scanning nodes in increasing
    order, the first unvisited node of a cycle is its smallest member, so the result is
    the same as `_cycles_doubling`), else pointer doubling.

    Parameters
    ----------
    nxt : (n,) int64 permutation

    Returns
    -------
    label, rank : (n,) int64
    """
    walk = _walk_kernel()
    if walk is None:                                        # pragma: no cover - optional
        return _cycles_doubling(nxt)
    label = np.empty(nxt.size, dtype=np.int64)
    rank = np.empty(nxt.size, dtype=np.int64)
    walk(np.ascontiguousarray(nxt, dtype=np.int64), label, rank)
    return label, rank


_WALK = []


def _walk_kernel():
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)


def _walk_loop(nxt, label, rank):  # pragma: no cover - compiled by numba
    label[:] = -1
    for start in range(nxt.size):
        if label[start] >= 0:
            continue
        node = start
        k = 0
        while label[node] < 0:
            label[node] = start
            rank[node] = k
            k += 1
            node = nxt[node]
