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
from numba import njit

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
    u = np.ascontiguousarray(u, dtype=np.float64)
    n = len(edges)
    work = np.empty((6, n + 1), dtype=np.int64)
    work[[2, 4]] = -1
    count, n_loops = _walk((u >= level).astype(np.int64),
                           np.ascontiguousarray(edges, dtype=np.int64),
                           np.ascontiguousarray(face_edges, dtype=np.int64),
                           np.ascontiguousarray(faces, dtype=np.int64), work,
                           np.zeros(n, dtype=np.bool_))
    nodes, seg_face, starts = work[3, :count], work[0, :count], work[5, :n_loops + 1]
    ea, eb = edges[nodes, 0], edges[nodes, 1]
    ua, ub = u[ea], u[eb]
    s = (level - ua) / (ub - ua)
    loops = [Loop(ea[i:j], eb[i:j], s[i:j], seg_face[i:j])
             for i, j in zip(starts[:-1].tolist(), starts[1:].tolist())]
    if vertices is not None and len(loops) > 1:
        loops.sort(key=lambda lp: -_length(lp.points(vertices)))
    return loops


@njit(cache=True, nogil=True, error_model="numpy")
def _walk(above, edges, face_edges, faces, work, seen):
    """The crossed edges of the isoline in loop order, ``above`` (V,) int64 1 where ``u >=
    level`` else 0, into ``work`` (6, E + 1) int64 (E edges; rows 2 and 4 all -1) and
    ``seen`` (E,) bool (all False): rows 3, 0, 5 hold the edge index of each loop point, the
    face of the segment from it to the next point, and the loop start offsets (n_loops + 1);
    returns (count of points, n_loops). A crossed edge is a node; each crossed face links
    its falling side's node to its rising side's (module docstring). Loops are listed by
    their smallest crossed edge index and each starts there."""
    node, edge_of, nxt, order, seg_face, starts = \
        work[0], work[1], work[2], work[3], work[4], work[5]
    count = 0
    for e in range(edges.shape[0]):
        if above[edges[e, 0]] != above[edges[e, 1]]:
            node[e] = count
            edge_of[count] = e
            count += 1
        else:
            node[e] = -1
    for f in range(faces.shape[0]):
        a0, a1, a2 = above[faces[f, 0]], above[faces[f, 1]], above[faces[f, 2]]
        if a0 == a1 and a1 == a2:
            continue
        # side k runs corner k -> k + 1; a crossed face has one falling side (k above,
        # k + 1 below) and one rising side
        src = face_edges[f, (a1 > a2) + 2 * (a2 > a0)]
        dst = face_edges[f, (a2 > a1) + 2 * (a0 > a2)]
        nxt[node[src]] = node[dst]
        seg_face[node[src]] = f
    n_out, n_loops = 0, 0
    faces_out = work[0]                # node is no longer needed
    for first in range(count):
        if seen[first]:
            continue
        starts[n_loops] = n_out
        n_loops += 1
        k = first
        while k >= 0 and not seen[k]:
            seen[k] = True
            order[n_out] = edge_of[k]
            faces_out[n_out] = seg_face[k]
            n_out += 1
            k = nxt[k]
    starts[n_loops] = n_out
    return n_out, n_loops


def _length(points) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0, append=points[:1]), axis=1).sum())


def isoline_moments(u, vertices, faces, levels, *, area: bool = True):
    """Length, centroid and vector area of the whole isoline at each of many levels at once
    (all loops of a level together; no loop ordering needed: a closed curve's vector area
    ``1/2 sum a x b`` over its oriented segments does not depend on where it starts).

    Returns
    -------
    length : (L,) float
    centroid : (L, 3) float
        Length-weighted mean of the segment midpoints (NaN where the level has no isoline).
    area : (L, 3) float
        Vector area, pointing along the field's gradient side (module docstring); None
        with ``area=False``.
    """
    levels = np.asarray(levels, dtype=np.float64)
    uf = np.asarray(u)[faces]                                         # (T, 3)
    u0, u1, u2 = uf.T
    lo = np.searchsorted(levels, np.minimum(np.minimum(u0, u1), u2), side="right")
    hi = np.searchsorted(levels, np.maximum(np.maximum(u0, u1), u2), side="right")
    count = hi - lo
    face = np.repeat(np.arange(len(faces)), count)
    start = np.repeat(np.cumsum(count) - count, count)
    lev = np.repeat(lo, count) + np.arange(face.size) - start
    t = levels[lev]
    fu = np.take(uf, face, axis=0)
    ab0, ab1, ab2 = (fu >= t[:, None]).T
    flat = 3 * face                                       # rows of the faces' corners, flat
    uflat, cflat = uf.reshape(-1), np.asarray(faces).reshape(-1)

    def crossing(side):
        k0, k1 = flat + side, flat + (side + 1) % 3
        u0, u1 = np.take(uflat, k0), np.take(uflat, k1)
        s = ((t - u0) / (u1 - u0))[:, None]
        return ((1.0 - s) * np.take(vertices, np.take(cflat, k0), axis=0)
                + s * np.take(vertices, np.take(cflat, k1), axis=0))

    # one falling (corner k at or above, k + 1 below) and one rising side per crossing face:
    # its index without an argmax
    a = crossing((ab1 & ~ab2) + 2 * (ab2 & ~ab0))
    b = crossing((~ab1 & ab2) + 2 * (~ab2 & ab0))
    seg = np.linalg.norm(b - a, axis=1)
    n = len(levels)
    length = np.bincount(lev, seg, n)
    mid = 0.5 * (a + b) * seg[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        centroid = np.stack([np.bincount(lev, mid[:, d], n) for d in range(3)], axis=1) \
            / length[:, None]
    if not area:
        return length, centroid, None
    cr = 0.5 * np.cross(a, b)
    return length, centroid, np.stack([np.bincount(lev, cr[:, d], n) for d in range(3)], axis=1)
