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
    a = f.reshape(-1)
    b = np.empty_like(f)                                   # each half-edge's end: the next corner
    b[:, :2], b[:, 2] = f[:, 1:], f[:, 0]
    b = b.reshape(-1)
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    key = lo * np.int64(n_vertices) + hi
    order, ks = _stable_order(key)
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


def _stable_order(key):
    """(order, key[order]): the stable ascending order of the non-negative int64 ``key``. When
    each key shifted left by the bits of ``key.size`` fits in int64, one value sort of the keys
    with their index in the low bits (distinct numbers: numpy's vectorised sort, the order
    of its stable argsort), else the stable argsort."""
    bits = max(int(key.size).bit_length(), 1)
    if key.size == 0 or int(key.max()) >= 1 << (62 - bits):
        order = np.argsort(key, kind="stable")
        return order, key[order]
    packed = np.sort((key << bits) | np.arange(key.size, dtype=np.int64))
    return packed & ((1 << bits) - 1), packed >> bits


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


@dataclass(frozen=True)
class Sections:
    """All closed loops cut from a mesh by parallel planes.

    Loops are stored back to back; loop ``l`` is ``points[loop_start[l]:loop_start[l+1]]``
    in chain order (not repeated at the end). Orientation: counter-clockwise in the
    (u, v) plane frame for an outward-wound mesh (the raw chaining order; see
    `fibres.slicing.contours` for the clockwise orientation of the paper).

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
    node_face, node_slice, down, nxt = _crossings(d, faces, topology.neighbours, h)
    order, loop_start = _loop_order(nxt, node_slice, h.size)
    node_face = node_face[order]
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

    A lexsort of the cycles' labels and ranks.
    """
    label, rank = _cycles(nxt)
    order = np.lexsort((rank, label, node_slice))
    lab_sorted = label[order]
    new_loop = np.ones(nxt.size, dtype=bool)
    new_loop[1:] = lab_sorted[1:] != lab_sorted[:-1]
    return order, np.append(np.flatnonzero(new_loop), nxt.size).astype(np.int64)


def _crossings(d, faces, neighbours, h):
    """Every (plane, face) crossing as a node of the chaining: its face, plane, "down"
    half-edge (above -> below) and the node its "up" half-edge leads to.

    Returns
    -------
    node_face, node_slice, down, nxt : (Q,) int64
        Nodes ordered by face, then plane.
    """
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
    """Cycle label (smallest member) and position after it, for a permutation ``nxt`` (n,):
    ``label, rank`` (n,) int64, by pointer doubling (`_cycles_doubling`)."""
    return _cycles_doubling(nxt)
