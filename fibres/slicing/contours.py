"""Choosing and orienting one contour per slicing plane.

A plane may cut a muscle surface into several loops (a bifid belly, a hole, a fold).
Kohout et al. (GRAPP 2012, section 3.3) morph one rectangle into one contour per plane;
here the loop containing the template rectangle's centre is used (the outermost one if
several nest around it), else the loop nearest to that centre, and the choice is written
into the result's notes. Contours are oriented **clockwise** in the plane frame (u, v),
as in the paper, where the rectangle is ``Q0=(0,0), Q1=(0,ey), Q2=(ex,ey), Q3=(ex,0)``.
"""
from __future__ import annotations

import numpy as np

from .planes import Sections

__all__ = ["loop_areas", "choose_loops", "anchored_loops", "bridge_loops",
           "clockwise_contour"]


def loop_areas(sections: Sections) -> np.ndarray:
    """Signed area of every loop (positive = counter-clockwise in (u, v)).

    Parameters
    ----------
    sections : Sections

    Returns
    -------
    (L,) float
    """
    p = sections.points
    q = _next_points(sections)
    cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
    return 0.5 * np.add.reduceat(cross, sections.loop_start[:-1]) if p.size else np.zeros(0)


def _next_points(sections: Sections) -> np.ndarray:
    """(K, 2) the following vertex of each loop vertex (cyclic within its loop)."""
    k = sections.points.shape[0]
    nxt = np.arange(1, k + 1)
    nxt[sections.loop_start[1:] - 1] = sections.loop_start[:-1]
    return sections.points[nxt]


def choose_loops(sections: Sections, centres, *, n_slices: int):
    """Pick one loop per plane: containing the centre (outermost), else nearest to it.

    Parameters
    ----------
    sections : Sections
    centres : (S, 2) float
        The rectangle centre of each plane in (u, v).
    n_slices : int
        S, the number of planes.

    Returns
    -------
    chosen : (S,) int64
        Loop index per plane, -1 where the plane cut nothing.
    notes : tuple of str
        One note per plane that was cut into several loops (or none).
    """
    centres = np.asarray(centres, dtype=float)
    n_loops = sections.loop_slice.size
    chosen = np.full(n_slices, -1, dtype=np.int64)
    if n_loops == 0:
        return chosen, tuple(f"slice {s} cut no loop" for s in range(n_slices))
    if n_loops == n_slices and np.array_equal(sections.loop_slice, np.arange(n_slices)):
        return np.arange(n_slices, dtype=np.int64), ()     # one loop per plane: no choice
    p = sections.points
    q = _next_points(sections)
    counts = np.diff(sections.loop_start)
    vert_slice = np.repeat(sections.loop_slice, counts)
    c = centres[vert_slice]
    # crossing number of the ray from the centre towards +u (half-open rule on v).
    straddle = (p[:, 1] > c[:, 1]) != (q[:, 1] > c[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        u_cross = p[:, 0] + (c[:, 1] - p[:, 1]) * (q[:, 0] - p[:, 0]) / (q[:, 1] - p[:, 1])
    hits = straddle & (u_cross > c[:, 0])
    inside = (np.add.reduceat(hits.astype(np.int64), sections.loop_start[:-1]) % 2) == 1
    # distance from the centre to every segment, minimum per loop.
    seg = q - p
    L2 = np.einsum("ij,ij->i", seg, seg)
    tt = np.clip(np.einsum("ij,ij->i", c - p, seg) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    dist = np.hypot(*(p + tt[:, None] * seg - c).T)
    loop_dist = np.minimum.reduceat(dist, sections.loop_start[:-1])
    area = np.abs(loop_areas(sections))
    # rank: containing loops first (largest area first), then by distance.
    key_primary = np.where(inside, 0, 1)
    key_secondary = np.where(inside, -area, loop_dist)
    order = np.lexsort((key_secondary, key_primary, sections.loop_slice))
    first = np.ones(n_loops, dtype=bool)
    first[1:] = sections.loop_slice[order][1:] != sections.loop_slice[order][:-1]
    best = order[first]
    chosen[sections.loop_slice[best]] = best
    notes = []
    per_slice = np.bincount(sections.loop_slice, minlength=n_slices)
    for s in np.flatnonzero(per_slice != 1):
        if per_slice[s] == 0:
            notes.append(f"slice {s} cut no loop")
        else:
            how = ("the outermost one containing the box centre" if inside[chosen[s]]
                   else "the one nearest to the box centre")
            notes.append(f"slice {s} cut {per_slice[s]} loops; used {how}")
    return chosen, tuple(notes)


def clockwise_contour(sections: Sections, loop: int):
    """One loop as a clockwise polygon with the mesh edge of each vertex.

    Parameters
    ----------
    sections : Sections
    loop : int

    Returns
    -------
    points : (m, 2) float
        Clockwise in (u, v); not repeated at the end.
    edge : (m,) int64
        Mesh edge index of each vertex.
    """
    lo, hi = sections.loop_start[loop], sections.loop_start[loop + 1]
    pts = sections.points[lo:hi]
    edge = sections.edge[lo:hi]
    area = 0.5 * np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
    if area > 0:
        pts, edge = pts[::-1], edge[::-1]
    return np.ascontiguousarray(pts), np.ascontiguousarray(edge)


def anchored_loops(sections: Sections, chosen, anchors_uv, *, points=None, carriers=False):
    """The loop of each plane that carries a plan's anchors (used with a `DecompositionPlan`).

    Where a plane cuts several loops, the choice of `choose_loops` (box centre inside /
    nearest) can switch between two frames of a motion. With a plan the loop is identified
    through the plan instead: its four material anchor points (start and split points of
    the rest contour, carried along with the surface and projected onto the plane) lie on
    the loop the rest pose used, so the loop with the smallest sum of squared distances to
    them is taken. The choice only changes where two loops are equally close to the anchors,
    i.e. where loops merge or split.

    Parameters
    ----------
    sections : Sections
    chosen : (S,) int
        `choose_loops`'s loops (kept for planes with a single loop).
    anchors_uv : (S, 4, D) float
        The anchors, in the plane (D = 2) or in the coordinates of ``points``.
    points : (K, D) float, optional
        Coordinates of the section points to measure in (default the plane coordinates);
        e.g. their rest-pose positions, to match the anchors materially.

    Returns
    -------
    chosen : (S,) int64
    changed : (S,) bool
        Planes where the anchored loop differs from ``chosen``.
    carrier : (S, 4) int64
        Only with ``carriers=True``: the loop nearest to each anchor (``chosen`` on planes
        with one loop).
    """
    chosen = np.array(chosen, dtype=np.int64)
    n_s = chosen.size
    per_slice = np.bincount(sections.loop_slice, minlength=n_s)
    multi = per_slice > 1
    changed = np.zeros(n_s, dtype=bool)
    carrier = np.repeat(chosen[:, None], 4, axis=1)
    if not multi.any():
        return (chosen, changed, carrier) if carriers else (chosen, changed)
    loops = np.flatnonzero(multi[sections.loop_slice])                # (L',)
    lo, hi = sections.loop_start[loops], sections.loop_start[loops + 1]
    cnt = hi - lo
    lid = np.repeat(np.arange(loops.size), cnt)
    k = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    idx = lo[lid] + k
    pts = sections.points if points is None else np.asarray(points, dtype=float)
    p = pts[idx]
    q = pts[lo[lid] + (k + 1) % cnt[lid]]
    a = np.asarray(anchors_uv, dtype=float)[sections.loop_slice[loops][lid]]   # (K', 4, D)
    d = (q - p)[:, None, :]
    r = a - p[:, None, :]
    dd = np.einsum("kij,kij->ki", d, d)
    tau = np.clip(np.einsum("kij,kij->ki", r, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    g = r - tau[..., None] * d
    g2 = np.einsum("kij,kij->ki", g, g)                                # (K', 4)
    offs = np.concatenate([[0], np.cumsum(cnt)])
    per_anchor = np.minimum.reduceat(g2, offs[:-1], axis=0)            # (L', 4)
    cost = per_anchor.sum(axis=1)                                      # (L',)
    sl = sections.loop_slice[loops]
    order = np.lexsort((cost, sl))
    first = np.ones(order.size, dtype=bool)
    first[1:] = sl[order][1:] != sl[order][:-1]
    best = loops[order[first]]
    new = chosen.copy()
    new[sections.loop_slice[best]] = best
    changed = new != chosen
    if not carriers:
        return new, changed
    carrier = np.repeat(new[:, None], 4, axis=1)
    for k in range(4):
        order = np.lexsort((per_anchor[:, k], sl))
        first = np.ones(order.size, dtype=bool)
        first[1:] = sl[order][1:] != sl[order][:-1]
        carrier[sl[order[first]], k] = loops[order[first]]
    return new, changed, carrier


def bridge_loops(a_pts, a_mat, b_pts, b_mat):
    """One closed contour through two disjoint clockwise loops, joined at their closest
    points by a bridge travelled both ways.

    Where a loop pinches and splits in two (or two merge), the two loops touch at the
    pinch; joined at their closest pair of points the contour is, at that moment, the
    pinched contour itself, and the bridge grows continuously from zero length as they
    move apart. A new island (a loop of no area, possibly far away) must not appear (or
    vanish) with a bridge of finite length: each loop is scaled towards the other loop's
    bridge end by `_fade` (1 at a pinch, 0 for a loop of no area, ~1 for the larger). So the
    section keeps one contour that depends continuously on the vertices through splits,
    merges and islands. The bridge ends are soft closest points (`_soft_bridge_end`).

    Parameters
    ----------
    a_pts, b_pts : (m_a, 2), (m_b, 2) float
        The loops, clockwise, not repeated at the end.
    a_mat, b_mat : ((m, 4) int64, (m, 4) float)
        Material anchors of the loop vertices (vertex indices and weights); the bridge
        points get theirs by interpolation (`_rolled_at`).

    Returns
    -------
    pts : (m_a + m_b + 4, 2) float
        ``a*, A_{i+1} .. A_i, a*, b*, B_{j+1} .. B_j, b*`` (the closing segment is the bridge
        back from ``b*`` to ``a*``).
    mat : ((m_a + m_b + 4, 4) int64, (m_a + m_b + 4, 4) float)
    gap : float
        Bridge length.
    """
    ia, ta, ib, tb, gap = _closest_pair(a_pts, b_pts)
    ia, ta = _soft_bridge_end(a_pts, b_pts, ia, ta, gap)
    ib, tb = _soft_bridge_end(b_pts, a_pts, ib, tb, gap)
    pa, ma = _rolled_at(a_pts, a_mat, ia, ta)
    pb, mb = _rolled_at(b_pts, b_mat, ib, tb)
    # a loop far from the other and small (an island the plane has just started or is
    # about to stop cutting) is shrunk towards the other loop's bridge end: lambda =
    # area / (area + gap^2) is 1 where the loops touch (a pinch) and 0 for a loop of no
    # area, so splits, merges and islands appearing or vanishing are all continuous
    a_star, b_star = pa[0].copy(), pb[0].copy()
    area_a, area_b = _area(a_pts), _area(b_pts)
    pa = b_star + _fade(area_a, area_b, gap) * (pa - b_star)
    pb = a_star + _fade(area_b, area_a, gap) * (pb - a_star)
    mat = tuple(np.concatenate([x, y]) for x, y in zip(ma, mb))
    return np.concatenate([pa, pb]), mat, gap


def _closest_pair(a, b):
    """Closest points of two closed polylines: (segment of a, tau, segment of b, tau,
    distance), over every vertex of one against every segment of the other."""
    best = None
    for first, second, swap in ((a, b, False), (b, a, True)):
        d = np.roll(second, -1, axis=0) - second                     # (n, 2) segments
        r = first[:, None, :] - second[None, :, :]                   # (m, n, 2)
        dd = np.einsum("ij,ij->i", d, d)
        tau = np.clip(np.einsum("mnj,nj->mn", r, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        g = r - tau[..., None] * d[None]
        g2 = np.einsum("mnj,mnj->mn", g, g)
        i, j = np.unravel_index(np.argmin(g2), g2.shape)
        if best is None or g2[i, j] < best[0]:
            # vertex i of `first` (segment i, tau 0) against segment j of `second`
            best = (g2[i, j], (j, tau[i, j], i, 0.0) if swap else (i, 0.0, j, tau[i, j]))
    ia, ta, ib, tb = best[1]
    return int(ia), float(ta), int(ib), float(tb), float(np.sqrt(best[0]))


def _area(loop):
    """Unsigned area of a closed polygon."""
    return 0.5 * abs(np.sum(loop[:, 0] * np.roll(loop[:, 1], -1)
                            - np.roll(loop[:, 0], -1) * loop[:, 1]))


def _fade(area, other, gap):
    """Scale of a loop of ``area`` bridged to one of area ``other`` across ``gap``.

    With ``r = area / (area + other)`` and ``g2 = gap^2 / (area + other)``: 1 for the larger
    loop (``r >= 1/2``), else ``2r / (2r + g2 (1 - 2r))`` -- 1 at a pinch (gap 0) and at equal
    areas, 0 for a loop of no area; continuous in all three."""
    total = area + other
    if total <= 0:
        return 1.0
    r2 = 2.0 * area / total
    if r2 >= 1.0:
        return 1.0
    den = r2 + gap * gap / total * (1.0 - r2)
    return r2 / den if den > 0 else 1.0


#: Width of the soft bridge ends, relative to the gap between the loops (see
#: `_soft_bridge_end`), and its floor relative to the loop's length.
BRIDGE_SPREAD = 0.5
BRIDGE_FLOOR = 1e-7


def _soft_bridge_end(a, b, i0, t0, gap):
    """Where the bridge leaves loop ``a``: the mean arc position on ``a`` weighted by
    ``exp(-(d^2 - gap^2) / sigma^2)``, d the distance to loop ``b``, ``sigma = BRIDGE_SPREAD
    * gap`` (floored): the closest point while the loops touch, moving smoothly (not
    jumping) where two places of ``a`` are about as near to ``b``. Trapezoidal weights at
    the vertices of ``a``; positions measured around the hard closest point ``(i0, t0)``.

    Returns (segment, tau) on ``a``."""
    m = a.shape[0]
    seg = np.hypot(*(np.roll(a, -1, axis=0) - a).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    length = cum[-1]
    if length <= 0:
        return i0, t0
    d = np.roll(b, -1, axis=0) - b
    r = a[:, None, :] - b[None, :, :]
    dd = np.einsum("ij,ij->i", d, d)
    tau = np.clip(np.einsum("mnj,nj->mn", r, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    g = r - tau[..., None] * d[None]
    d2 = np.einsum("mnj,mnj->mn", g, g).min(axis=1)                   # (m,) to loop b
    sigma2 = (BRIDGE_SPREAD * gap) ** 2 + (BRIDGE_FLOOR * length) ** 2
    w = np.exp(-(d2 - gap * gap) / sigma2) * 0.5 * (seg + np.roll(seg, 1))
    ref = cum[i0] + t0 * seg[i0]
    rel = (cum[:-1] - ref + 0.5 * length) % length - 0.5 * length
    if w.sum() <= 0:
        return i0, t0
    pos = (ref + (w * rel).sum() / w.sum()) % length
    j = int(min(max(np.searchsorted(cum, pos, side="right") - 1, 0), m - 1))
    while j > 0 and seg[j] <= 0:
        j -= 1
    return j, float(np.clip((pos - cum[j]) / seg[j], 0.0, 1.0)) if seg[j] > 0 else 0.0


def _rolled_at(pts, mat, i, tau):
    """The loop from the point at ``tau`` on segment ``i`` once round and back to it:
    (m + 2, 2) points, and the material anchors ``mat = (av (m, 4) int, aw (m, 4) float)``
    of the new point: the two edge points' vertices and weights combined (exact for
    contour points on mesh edges), else the nearer vertex's."""
    m = pts.shape[0]
    j = (i + 1) % m
    order = (j + np.arange(m)) % m                                   # A_{i+1} .. A_i
    p = (1.0 - tau) * pts[i] + tau * pts[j]
    av, aw = mat
    if (aw[i, 2:] == 0).all() and (aw[j, 2:] == 0).all():
        v_new = np.concatenate([av[i, :2], av[j, :2]])
        w_new = np.concatenate([(1.0 - tau) * aw[i, :2], tau * aw[j, :2]])
    else:
        k = i if tau < 0.5 else j
        v_new, w_new = av[k], aw[k]
    out = np.concatenate([p[None], pts[order], p[None]])
    return out, (np.concatenate([v_new[None], av[order], v_new[None]]),
                 np.concatenate([w_new[None], aw[order], w_new[None]]))
