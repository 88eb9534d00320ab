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

__all__ = ["Loop", "isoline_loops", "isoline_loops_at"]


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
    return isoline_loops_at(u, faces, [level], edges, face_edges, vertices)[0]


def isoline_loops_at(u, faces, levels, edges, face_edges, vertices=None) -> list:
    """`isoline_loops` of each of many levels, in one pass of the compiled walk.

    Returns
    -------
    list (one per level) of lists of Loop
    """
    u = np.ascontiguousarray(u, dtype=np.float64)
    levels = np.ascontiguousarray(np.atleast_1d(levels), dtype=np.float64)
    nodes, seg_face, starts, per_level = _walk(
        u, levels, np.ascontiguousarray(edges, dtype=np.int64),
        np.ascontiguousarray(face_edges, dtype=np.int64),
        np.ascontiguousarray(faces, dtype=np.int64))
    ea, eb = edges[nodes, 0], edges[nodes, 1]
    ua, ub = u[ea], u[eb]
    level = np.repeat(levels, np.diff(starts[per_level]))
    s = (level - ua) / (ub - ua)
    bounds = starts.tolist()
    loops = [Loop(ea[i:j], eb[i:j], s[i:j], seg_face[i:j])
             for i, j in zip(bounds[:-1], bounds[1:])]
    out = []
    for i, j in zip(per_level[:-1].tolist(), per_level[1:].tolist()):
        found = loops[i:j]
        if vertices is not None and len(found) > 1:
            found.sort(key=lambda lp: -_length(lp.points(vertices)))
        out.append(found)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _walk(u, levels, edges, face_edges, faces):
    """The crossed edges of the isolines ``u = levels[l]`` in loop order: (edge index of each
    loop point, face of the segment from it to the next point (-1 where a loop is open),
    loop start offsets (n_loops + 1), each level's first loop (L + 1)). Per level, a vertex
    is above where ``u >= level``; a crossed edge is a node, and each crossed face links its
    falling side's node to its rising side's (module docstring). A level's loops are listed
    by their smallest crossed edge index and each starts there."""
    n_e, n_l = edges.shape[0], levels.size
    # edge of each point, face of its segment, loop starts: grown when a level needs it
    out_edge = np.empty(n_e + 1, np.int64)
    out_face = np.empty(n_e + 1, np.int64)
    starts = np.empty(n_e + 1, np.int64)
    per_level = np.empty(n_l + 1, np.int64)
    above = np.empty(u.size, np.int64)
    node = np.empty(n_e, np.int64)
    edge_of = np.empty(n_e, np.int64)
    nxt = np.empty(n_e, np.int64)
    seg_face = np.empty(n_e, np.int64)
    seen = np.empty(n_e, np.bool_)
    n_out, n_loops = 0, 0
    for l in range(n_l):
        per_level[l] = n_loops
        t = levels[l]
        for v in range(u.size):
            above[v] = 1 if u[v] >= t else 0
        count = 0
        for e in range(n_e):
            if above[edges[e, 0]] != above[edges[e, 1]]:
                node[e] = count
                edge_of[count] = e
                count += 1
            else:
                node[e] = -1
        if n_out + count >= out_edge.size:
            cap = 2 * (n_out + count) + 1
            out_edge = np.concatenate((out_edge, np.empty(cap - out_edge.size, np.int64)))
            out_face = np.concatenate((out_face, np.empty(cap - out_face.size, np.int64)))
            starts = np.concatenate((starts, np.empty(cap - starts.size, np.int64)))
        nxt[:count] = -1
        seg_face[:count] = -1
        seen[:count] = False
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
        for first in range(count):
            if seen[first]:
                continue
            starts[n_loops] = n_out
            n_loops += 1
            k = first
            while k >= 0 and not seen[k]:
                seen[k] = True
                out_edge[n_out] = edge_of[k]
                out_face[n_out] = seg_face[k]
                n_out += 1
                k = nxt[k]
    per_level[n_l] = n_loops
    starts[n_loops] = n_out
    return out_edge[:n_out], out_face[:n_out], starts[:n_loops + 1], per_level


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
    levels = np.ascontiguousarray(levels, dtype=np.float64)
    sums = _moments(np.ascontiguousarray(u, dtype=np.float64),
                    np.ascontiguousarray(vertices, dtype=np.float64),
                    np.ascontiguousarray(faces, dtype=np.int64), levels, bool(area))
    length = sums[:, 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        centroid = sums[:, 1:4] / length[:, None]
    return length, centroid, (sums[:, 4:] if area else None)


@njit(cache=True, nogil=True, error_model="numpy")
def _moments(u, vertices, faces, levels, area):
    """(L, 7) sums over each level's isoline segments, face by face: length, midpoint times
    length (3), half the cross product of the segment's ends (3; zero unless ``area``). Level
    l crosses face f where ``min u < levels[l] <= max u`` over its corners (levels
    increasing); the segment runs from the falling side's crossing to the rising side's
    (module docstring)."""
    out = np.zeros((levels.size, 7))
    p = np.empty((2, 3))
    uc = np.empty(3)
    x = np.empty((3, 3))                             # the face's corners
    for f in range(faces.shape[0]):
        for k in range(3):
            uc[k] = u[faces[f, k]]
        low, high = min(min(uc[0], uc[1]), uc[2]), max(max(uc[0], uc[1]), uc[2])
        lv, hi = 0, levels.size                      # lv: the first level above the lowest u
        while lv < hi:
            mid = (lv + hi) // 2
            if levels[mid] <= low:
                lv = mid + 1
            else:
                hi = mid
        if lv < levels.size and levels[lv] <= high:
            for k in range(3):
                for d in range(3):
                    x[k, d] = vertices[faces[f, k], d]
        while lv < levels.size and levels[lv] <= high:
            t = levels[lv]
            ab0, ab1, ab2 = uc[0] >= t, uc[1] >= t, uc[2] >= t
            for r in range(2):
                # the falling side (corner k at or above, k + 1 below), then the rising side
                if r == 0:
                    k0 = (ab1 and not ab2) + 2 * (ab2 and not ab0)
                else:
                    k0 = (ab2 and not ab1) + 2 * (ab0 and not ab2)
                k1 = k0 + 1 if k0 < 2 else 0
                s = (t - uc[k0]) / (uc[k1] - uc[k0])
                for d in range(3):
                    p[r, d] = (1.0 - s) * x[k0, d] + s * x[k1, d]
            d0, d1, d2 = p[1, 0] - p[0, 0], p[1, 1] - p[0, 1], p[1, 2] - p[0, 2]
            seg = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            out[lv, 0] += seg
            for d in range(3):
                out[lv, 1 + d] += 0.5 * (p[0, d] + p[1, d]) * seg
            if area:
                out[lv, 4] += 0.5 * (p[0, 1] * p[1, 2] - p[0, 2] * p[1, 1])
                out[lv, 5] += 0.5 * (p[0, 2] * p[1, 0] - p[0, 0] * p[1, 2])
                out[lv, 6] += 0.5 * (p[0, 0] * p[1, 1] - p[0, 1] * p[1, 0])
            lv += 1
    return out
