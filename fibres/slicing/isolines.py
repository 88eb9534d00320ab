"""Isolines of a piecewise linear field on a closed triangle surface, as ordered closed loops.

A vertex is *above* level ``t`` when ``u >= t``. An edge whose two ends differ is crossed once,
at ``p = (1 - s) V_a + s V_b`` with ``s = (t - u_a) / (u_b - u_a)``; every triangle has zero or
two crossed sides, joined by one segment (marching triangles). Walking each face's sides in
their winding order, one crossed side goes from below to above (*rising*), the other from
above to below (*falling*); the segment runs from the falling side's crossing to the rising
side's. On an outward-wound surface every loop then runs the same way round the field's
gradient (``grad u x n`` direction, n the outward normal): consecutive isolines of a field
between two patches turn the same way, which `fibres.slicing.harmonic` relies on.

The crossed edges and their parameters ``s`` depend on the field only, not on the vertex
positions: a loop is a fixed linear combination of the vertices, a material curve that moves
with a deformed copy of the surface (`Loop.points`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

__all__ = ["Loop", "isoline_loops"]


@dataclass(frozen=True)
class Loop:
    """One closed isoline: point k is ``(1 - s[k]) V[a[k]] + s[k] V[b[k]]``, in loop order;
    the segment from point k to k + 1 lies in face ``face[k]``."""

    a: np.ndarray
    b: np.ndarray
    s: np.ndarray
    face: np.ndarray

    def points(self, vertices) -> np.ndarray:
        """(M, 3) loop points on the surface ``vertices`` (any copy with the same faces)."""
        s = self.s[:, None]
        return (1.0 - s) * vertices[self.a] + s * vertices[self.b]

    def __len__(self):
        return int(self.a.size)


def isoline_loops(u, faces, level: float, edges, face_edges, vertices=None) -> list:
    """Closed loops of the isoline ``u = level`` (module docstring).

    Parameters
    ----------
    u : (V,) float
        Field values at the vertices.
    faces : (T, 3) int
        A closed, consistently outward-wound surface.
    level : float
    edges, face_edges
        `fibres.slicing.harmonic_field.mesh_edges` of the faces.
    vertices : (V, 3) float, optional
        When given, loops are sorted longest first (else in discovery order).

    Returns
    -------
    list of Loop
    """
    above = np.asarray(u) >= level
    cross = above[edges[:, 0]] != above[edges[:, 1]]                  # (E,)
    fc = cross[face_edges]                                            # (T, 3)
    hit = np.flatnonzero(fc.any(axis=1))
    if hit.size == 0:
        return []
    f = faces[hit]
    fe = face_edges[hit]
    ab = above[f]                                                     # (H, 3)
    # side k runs corner k -> k + 1; rising: below -> above
    rising = ~ab & np.roll(ab, -1, axis=1)
    falling = ab & ~np.roll(ab, -1, axis=1)
    src = fe[np.arange(len(hit)), falling.argmax(axis=1)]
    dst = fe[np.arange(len(hit)), rising.argmax(axis=1)]
    nodes = np.flatnonzero(cross)
    index = np.full(len(edges), -1, dtype=np.int64)
    index[nodes] = np.arange(nodes.size)
    nxt = np.empty(nodes.size, dtype=np.int64)
    nxt[index[src]] = index[dst]
    seg_face = np.empty(nodes.size, dtype=np.int64)
    seg_face[index[src]] = hit
    m = nodes.size
    graph = coo_matrix((np.ones(m), (np.arange(m), nxt)), shape=(m, m))
    n_loops, label = connected_components(graph, directed=True, connection="weak")
    ea, eb = edges[nodes, 0], edges[nodes, 1]
    ua, ub = u[ea], u[eb]
    s = (level - ua) / (ub - ua)
    loops = []
    for lab in range(n_loops):
        members = np.flatnonzero(label == lab)
        order = np.empty(members.size, dtype=np.int64)
        k = members[0]
        for i in range(members.size):
            order[i] = k
            k = nxt[k]
        loops.append(Loop(ea[order], eb[order], s[order], seg_face[order]))
    if vertices is not None and len(loops) > 1:
        loops.sort(key=lambda lp: -_length(lp.points(vertices)))
    return loops


def _length(points) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0, append=points[:1]), axis=1).sum())


def isoline_moments(u, vertices, faces, levels):
    """Length, centroid and vector area of the whole isoline at each of many levels at once
    (all loops of a level together; no loop ordering needed: a closed curve's vector area
    ``1/2 sum a x b`` over its oriented segments does not depend on where it starts).

    Returns
    -------
    length : (L,) float
    centroid : (L, 3) float
        Length-weighted mean of the segment midpoints (NaN where the level has no isoline).
    area : (L, 3) float
        Vector area, pointing along the field's gradient side (module docstring).
    """
    levels = np.asarray(levels, dtype=np.float64)
    uf = np.asarray(u)[faces]                                         # (T, 3)
    lo = np.searchsorted(levels, uf.min(axis=1), side="right")
    hi = np.searchsorted(levels, uf.max(axis=1), side="right")
    count = hi - lo
    face = np.repeat(np.arange(len(faces)), count)
    start = np.repeat(np.cumsum(count) - count, count)
    lev = np.repeat(lo, count) + np.arange(face.size) - start
    t = levels[lev]
    fu = uf[face]
    ab = fu >= t[:, None]
    rising = ~ab & np.roll(ab, -1, axis=1)
    falling = ab & ~np.roll(ab, -1, axis=1)
    rows = np.arange(face.size)
    tri = vertices[faces[face]]                                       # (H, 3, 3)

    def crossing(side):
        k0, k1 = side, (side + 1) % 3
        u0, u1 = fu[rows, k0], fu[rows, k1]
        s = ((t - u0) / (u1 - u0))[:, None]
        return (1.0 - s) * tri[rows, k0] + s * tri[rows, k1]

    a = crossing(falling.argmax(axis=1))
    b = crossing(rising.argmax(axis=1))
    seg = np.linalg.norm(b - a, axis=1)
    n = len(levels)
    length = np.bincount(lev, seg, n)
    mid = 0.5 * (a + b) * seg[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        centroid = np.stack([np.bincount(lev, mid[:, d], n) for d in range(3)], axis=1) \
            / length[:, None]
    cr = 0.5 * np.cross(a, b)
    area = np.stack([np.bincount(lev, cr[:, d], n) for d in range(3)], axis=1)
    return length, centroid, area
