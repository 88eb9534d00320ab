"""Slice-by-slice morphing of the fitted template into the muscle (Kohout et al. 2012, §3.3).

A plane perpendicular to the principal axis cuts the template box in a rectangle and the
muscle surface in a contour; after the rectangle <-> contour correspondence
(`fibres.correspondence`), a fibre point ``F`` on that plane has mean value coordinates
``lambda`` with respect to the subdivided rectangle ``Q`` (Hormann & Floater 2006) and is
moved to ``sum_i lambda_i P_i`` on the contour.

Slabs instead of one plane per point. The paper cuts "not only all fibre poly-line points
lying on the cutting plane but also those in its close proximity", so that the number of
slices is the resolution, not fibres x resolution. Here the surface is cut at S fixed
heights (fractions of the box height, `slice_fractions`); a point at height ``w`` between
planes ``s`` and ``s+1`` is mapped with both planes' correspondences and the two in-plane
results are blended linearly in ``w``, and the point keeps its own height ``w``. This makes
the result continuous in the point's height (a nearest-plane rule would jump between
planes), exact for points lying on a plane (the parallel template at the default slice
fractions puts every point on a plane, i.e. exactly the paper's sweep), and it costs one
MVC evaluation per point and neighbouring plane (`fibres.mvc.mvc_map`, compiled).
The two end planes are inset by `END_INSET` of the height (a plane through the extreme
vertex cuts a degenerate section); points beyond them use the end plane's mapping at their
own height, so fibres still reach the ends of the box. On a flat end (a cap) that is exact;
at a pointed end the end points can lie outside the surface by about the size of the end
plane's section, measured ~1e-4 of the muscle length (0.02 mm on a 200 mm spindle) -- the
attachment filter (§3.4, on by default) replaces those ends anyway.
"""
from __future__ import annotations

import numpy as np

from .contours import clockwise_contour
from .correspondence import correspond, rectangle, split_chain
from .mvc import mvc_map
from .slicing import MeshTopology, Sections

__all__ = ["END_INSET", "slice_fractions", "slice_maps", "morph_local"]

#: Inset of the first and last slicing planes, as a fraction of the box height.
END_INSET = 1e-4


def slice_fractions(resolution: int) -> np.ndarray:
    """Default slicing heights as fractions of the box height: ``resolution + 1`` planes.

    ``linspace(0, 1, resolution + 1)`` with the ends moved inside by `END_INSET`, i.e. one
    plane per point of a fibre of the parallel template (Kohout 2012: "the minimal number
    of slices used is equal to the specified resolution").

    Parameters
    ----------
    resolution : int
        Segments per fibre (R >= 1).

    Returns
    -------
    (S,) float, S = R + 1
    """
    if resolution < 1:
        raise ValueError(f"resolution must be >= 1, got {resolution}")
    f = np.linspace(0.0, 1.0, int(resolution) + 1)
    f[0], f[-1] = END_INSET, 1.0 - END_INSET
    return f


def _refine(points, edge):
    """Insert edge midpoints until the contour has at least 4 vertices (4 rectangle sides)."""
    while points.shape[0] < 4:
        mid = 0.5 * (points + np.roll(points, -1, axis=0))
        points = np.stack([points, mid], axis=1).reshape(-1, 2)
        edge = np.stack([edge, np.full_like(edge, -1)], axis=1).reshape(-1)
    return points, edge


def _locate(edge_ids, wanted, points, topology: MeshTopology, local_uv):
    """Contour position of the vertex on mesh edge ``wanted``, or the continuous fallback.

    When the deformed mesh no longer crosses the plane on that edge, a mesh vertex of it
    has passed the plane; the crossings near that vertex are on edges incident to it, so
    the crossing (on an edge sharing a vertex with ``wanted``) nearest to the shared vertex
    is used. At the moment of the change both lie on that vertex, so the choice stays
    continuous. Returns -1 if nothing qualifies.
    """
    hit = np.flatnonzero(edge_ids == wanted)
    if hit.size:
        return int(hit[0])
    a, b = topology.edges[wanted]
    valid = edge_ids >= 0
    ce = topology.edges[np.where(valid, edge_ids, 0)]
    share_a = valid & ((ce[:, 0] == a) | (ce[:, 1] == a))
    share_b = valid & ((ce[:, 0] == b) | (ce[:, 1] == b))
    cand = np.flatnonzero(share_a | share_b)
    if cand.size == 0:
        return -1
    shared = np.where(share_a[cand], a, b)
    dist = np.hypot(*(points[cand] - local_uv[shared]).T)
    return int(cand[np.argmin(dist)])


def slice_maps(sections: Sections, chosen, extents, *, topology: MeshTopology,
               local_uv=None, planned=None):
    """Correspondence of every plane: the contour ``P`` and the subdivided rectangle ``Q``.

    All planes at once on the concatenated contours (orientation, start vertex closest to
    ``Q0``, rolling, arc lengths, side subdivision); only the split search
    (`fibres.correspondence.split_chain`) runs per plane, and only where no plan gives it.
    Same result as applying `fibres.correspondence.correspond` to each plane.

    Parameters
    ----------
    sections : Sections
    chosen : (S,) int
        Loop per plane (`fibres.contours.choose_loops`); -1 where nothing was cut.
    extents : (3,) float
        Box extents; the rectangle is ``[0, ex] x [0, ey]``.
    topology : MeshTopology
    local_uv : (V, 2) float, optional
        Vertex positions in the plane frame (needed with ``planned``).
    planned : (S, 4) int, optional
        Mesh edges of the start vertex and of the three split vertices from a plan
        (-1: decide afresh).

    Returns
    -------
    P, Q : tuple of (m_s, 2) float arrays
    choice : (S, 4) int64
        Mesh edges of the start and split vertices actually used (-1 where a refined
        midpoint was used), for `fibres.plan.DecompositionPlan`.
    notes : tuple of str
    """
    chosen = np.asarray(chosen, dtype=np.int64)
    n_s = chosen.size
    if (chosen < 0).any():
        s = int(np.flatnonzero(chosen < 0)[0])
        raise ValueError(f"slice {s} at height {sections.heights[s]:.6g} cuts no contour")
    rect = rectangle(float(extents[0]), float(extents[1]))
    sides = np.hypot(*(np.roll(rect, -1, axis=0) - rect).T)
    notes = []
    # clockwise contours, concatenated
    lo = sections.loop_start[chosen]
    m = sections.loop_start[chosen + 1] - lo
    offs = np.concatenate([[0], np.cumsum(m)])
    sl = np.repeat(np.arange(n_s), m)
    j = np.arange(offs[-1]) - offs[sl]
    raw = sections.points[lo[sl] + j]
    nx = raw[offs[sl] + (j + 1) % m[sl]]
    flip = np.add.reduceat(raw[:, 0] * nx[:, 1] - nx[:, 0] * raw[:, 1], offs[:-1]) > 0
    idx = np.where(flip[sl], lo[sl] + m[sl] - 1 - j, lo[sl] + j)
    pts = sections.points[idx]
    edge = sections.edge[idx]
    if (m < 4).any():
        pl, el = np.split(pts, offs[1:-1]), np.split(edge, offs[1:-1])
        for s in np.flatnonzero(m < 4):
            notes.append(f"slice {s}: contour of {m[s]} vertices refined with midpoints")
            pl[s], el[s] = _refine(pl[s], el[s])
        pts, edge = np.concatenate(pl), np.concatenate(el)
        m = np.array([len(p) for p in pl])
        offs = np.concatenate([[0], np.cumsum(m)])
        sl = np.repeat(np.arange(n_s), m)
        j = np.arange(offs[-1]) - offs[sl]
    # start vertex: closest to Q0 (first one on ties), unless planned
    dx, dy = pts[:, 0] - rect[0, 0], pts[:, 1] - rect[0, 1]
    d2 = dx * dx + dy * dy
    closest = np.flatnonzero(d2 == np.minimum.reduceat(d2, offs[:-1])[sl])
    start = j[closest[np.searchsorted(sl[closest], np.arange(n_s))]]
    split = np.full((n_s, 3), -1, dtype=np.int64)
    if planned is not None:
        pos = _locate_all(edge, sl, offs, planned, topology.edges.shape[0])
        for s in np.flatnonzero((pos < 0).any(axis=1) & (planned >= 0).all(axis=1)):
            seg = slice(offs[s], offs[s + 1])
            pos[s] = [_locate(edge[seg], e, pts[seg], topology, local_uv) for e in planned[s]]
        has_start = pos[:, 0] >= 0
        for s in np.flatnonzero(~has_start & (planned[:, 0] >= 0)):
            notes.append(f"slice {s}: planned start vertex not found; chose afresh")
        start = np.where(has_start, pos[:, 0], start)
        rel = (pos[:, 1:] - start[:, None]) % m[:, None]
        ok = has_start & (pos[:, 1:] >= 0).all(axis=1) & (0 < rel[:, 0]) \
            & (rel[:, 0] < rel[:, 1]) & (rel[:, 1] < rel[:, 2])
        for s in np.flatnonzero(has_start & ~ok):
            notes.append(f"slice {s}: planned side split not found; split afresh")
        split[ok] = rel[ok]
    # roll every contour to its start; arc lengths within each contour
    roll = offs[sl] + (start[sl] + j) % m[sl]
    P = pts[roll]
    P_edge = edge[roll]
    nxt = offs[sl] + (j + 1) % m[sl]
    seg = np.hypot(*(P[nxt] - P).T)
    cum = np.cumsum(seg)
    base = np.concatenate([[0.0], cum])[offs[:-1]]
    c_incl = cum - base[sl]                         # arc length from P0 to P_{j+1}
    c_excl = c_incl - seg                           # ... to P_j
    for s in np.flatnonzero(split[:, 0] < 0):
        split[s] = split_chain(seg[offs[s]:offs[s + 1]], sides)
    # subdivide each rectangle side like its part
    bounds = np.concatenate([np.zeros((n_s, 1), np.int64), split, m[:, None]], axis=1)
    arc = np.concatenate([np.zeros((n_s, 1)), np.zeros((n_s, 3)), c_incl[offs[1:] - 1, None]],
                         axis=1)
    arc[:, 1:4] = c_excl[offs[:-1, None] + split]
    part = (j[:, None] >= split[sl]).sum(axis=1)
    b0, b1 = bounds[sl, part], bounds[sl, part + 1]
    a0, a1 = arc[sl, part], arc[sl, part + 1]
    span = a1 - a0
    frac = np.where(span > 0, (c_excl - a0) / np.where(span > 0, span, 1.0),
                    (j - b0) / (b1 - b0))
    Q = rect[part] + frac[:, None] * (rect[(part + 1) % 4] - rect[part])
    pick = offs[:-1, None] + np.concatenate([np.zeros((n_s, 1), np.int64), split], axis=1)
    choice = P_edge[pick]
    cut = offs[1:-1]
    return tuple(np.split(P, cut)), tuple(np.split(Q, cut)), choice, tuple(notes)


def _locate_all(edge, sl, offs, planned, n_edges):
    """Contour positions (S, 4) of the planned mesh edges in their planes (-1: absent)."""
    key = np.where(edge >= 0, sl * n_edges + edge, -1)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    want = np.arange(planned.shape[0])[:, None] * n_edges + planned
    hit = np.clip(np.searchsorted(ks, want), 0, ks.size - 1)
    found = (ks[hit] == want) & (planned >= 0)
    return np.where(found, order[hit] - offs[:-1, None], -1)


def _slice_maps_loop(sections: Sections, chosen, extents, *, topology: MeshTopology,
               local_uv=None, planned=None):
    """`slice_maps` one plane at a time (reference implementation for the tests).

    Parameters
    ----------
    sections : Sections
    chosen : (S,) int
        Loop per plane (`fibres.contours.choose_loops`); -1 where nothing was cut.
    extents : (3,) float
        Box extents; the rectangle is ``[0, ex] x [0, ey]``.
    topology : MeshTopology
    local_uv : (V, 2) float, optional
        Vertex positions in the plane frame (needed with ``planned``).
    planned : (S, 4) int, optional
        Mesh edges of the start vertex and of the three split vertices from a plan
        (-1: decide afresh).

    Returns
    -------
    P, Q : tuple of (m_s, 2) float arrays
    choice : (S, 4) int64
        Mesh edges of the start and split vertices actually used (-1 where a refined
        midpoint was used), for `fibres.plan.DecompositionPlan`.
    notes : tuple of str
    """
    rect = rectangle(float(extents[0]), float(extents[1]))
    sides = np.hypot(*(np.roll(rect, -1, axis=0) - rect).T)
    n_s = len(chosen)
    P_all, Q_all, notes = [], [], []
    choice = np.full((n_s, 4), -1, dtype=np.int64)
    for s in range(n_s):
        if chosen[s] < 0:
            raise ValueError(f"slice {s} at height {sections.heights[s]:.6g} cuts no contour")
        pts, edge = clockwise_contour(sections, int(chosen[s]))
        if pts.shape[0] < 4:
            notes.append(f"slice {s}: contour of {pts.shape[0]} vertices refined with midpoints")
            pts, edge = _refine(pts, edge)
        start = splits = None
        if planned is not None and planned[s, 0] >= 0:
            pos = [_locate(edge, planned[s, j], pts, topology, local_uv) if planned[s, j] >= 0
                   else -1 for j in range(4)]
            if pos[0] >= 0:
                start = pos[0]
                rel = [(p - start) % pts.shape[0] for p in pos[1:]]
                if min(pos[1:]) >= 0 and 0 < rel[0] < rel[1] < rel[2]:
                    splits = np.array(rel)
                else:
                    notes.append(f"slice {s}: planned side split not found; split afresh")
            else:
                notes.append(f"slice {s}: planned start vertex not found; chose afresh")
        P, Q, start, splits = correspond(pts, rect, start=start, splits=splits)
        m = pts.shape[0]
        choice[s] = edge[[start, (start + splits[0]) % m, (start + splits[1]) % m,
                          (start + splits[2]) % m]]
        P_all.append(P)
        Q_all.append(Q)
    return tuple(P_all), tuple(Q_all), choice, tuple(notes)


def morph_local(xy, w, heights, P, Q) -> np.ndarray:
    """Map template points to the muscle, plane by plane (Kohout 2012 §3.3).

    Parameters
    ----------
    xy : (M, 2) float
        In-plane template coordinates in the box frame (``x * ex, y * ey``).
    w : (M,) float
        Heights in the box frame (``z * ez``).
    heights : (S,) float
        Plane heights, S >= 2, increasing.
    P, Q : sequences of S (m_s, 2) float arrays
        Contours and subdivided rectangles of the planes (`slice_maps`).

    Returns
    -------
    (M, 2) float
        Mapped in-plane coordinates: ``sum_i lambda_i(xy; Q_s) P_s,i`` blended linearly in
        ``w`` between the two planes around ``w`` (the end planes beyond them).
    """
    xy = np.asarray(xy, dtype=float)
    w = np.asarray(w, dtype=float)
    h = np.asarray(heights, dtype=float)
    n_s = h.size
    s0 = np.clip(np.searchsorted(h, w, side="right") - 1, 0, n_s - 2)
    a = np.clip((w - h[s0]) / (h[s0 + 1] - h[s0]), 0.0, 1.0)
    # every (point, plane) use with its weight; one compiled pass over all of them
    use_lo = a < 1.0
    use_hi = a > 0.0
    idx = np.concatenate([np.flatnonzero(use_lo), np.flatnonzero(use_hi)])
    pl = np.concatenate([s0[use_lo], s0[use_hi] + 1])
    wt = np.concatenate([1.0 - a[use_lo], a[use_hi]])
    mapped = mvc_map(xy[idx], pl, Q, P, weights=wt)
    out = np.zeros_like(xy)
    np.add.at(out, idx, mapped)
    return out
