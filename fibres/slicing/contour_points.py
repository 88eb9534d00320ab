"""Points on a contour curve (a segment index and a fraction along it), for the continuous
correspondence of `fibres.slicing.correspondence` (Kohout et al., GRAPP 2012, §3.3, made
continuous: start and split points may lie between contour vertices).

Contours are given packed: ``pts`` (total, 2) of all contours, ``m`` (S,) their vertex counts and
``offs`` (S,) their offsets; a point on contour s is (segment k, fraction tau) on the segment from
vertex k to vertex k + 1 (cyclic). `closest_points` finds the exact closest point to targets,
`ratio_points` walks given arc fractions from a start, `insert_points` makes points vertices, and
`smooth_split_points` smooths split points along the slicing axis.
"""
from __future__ import annotations

import numpy as np

__all__ = ["closest_points", "ratio_points", "insert_points", "smooth_split_points", "SPLIT_SMOOTHING"]


def _contour_segments(pts, m, offs):
    """Plane, local index, next vertex and length of every segment of contours stored back
    to back: (K,) each."""
    sl = np.repeat(np.arange(m.size), m)
    j = np.arange(offs[-1]) - offs[sl]
    nxt = offs[sl] + (j + 1) % m[sl]
    d = pts[nxt] - pts
    return sl, j, nxt, np.hypot(d[:, 0], d[:, 1])


def closest_points(pts, m, offs, targets):
    """Exact closest point of every contour to each of its plane's targets.

    Parameters
    ----------
    pts : (K, 2) float
        Closed contours back to back (plane ``s`` is ``pts[offs[s]:offs[s + 1]]``).
    m : (S,) int
        Vertices per contour (``offs = [0, cumsum(m)]``).
    offs : (S + 1,) int
    targets : (S, A, 2) float

    Returns
    -------
    seg : (S, A) int64
        Local index ``j`` of the segment ``P_j -> P_{j+1}`` carrying the point (the first
        one on ties: the closest point is a continuous function of the target except where
        two parts of the contour are equally near).
    tau : (S, A) float
        Position along that segment, in [0, 1].
    point : (S, A, 2) float
    """
    m = np.asarray(m, dtype=np.int64)
    offs = np.asarray(offs, dtype=np.int64)
    targets = np.asarray(targets, dtype=float)
    n_s, n_a = targets.shape[:2]
    sl, _, nxt, _ = _contour_segments(pts, m, offs)
    d = pts[nxt] - pts                                                # (K, 2)
    dx, dy = d[:, 0:1], d[:, 1:2]
    dd = dx * dx + dy * dy
    rx = targets[sl, :, 0] - pts[:, 0:1]                              # (K, A)
    ry = targets[sl, :, 1] - pts[:, 1:2]
    tau = np.clip((rx * dx + ry * dy) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    gx, gy = rx - tau * dx, ry - tau * dy
    g2 = gx * gx + gy * gy
    best = g2 == np.minimum.reduceat(g2, offs[:-1], axis=0)[sl]
    seg = np.empty((n_s, n_a), dtype=np.int64)
    for a in range(n_a):                                  # targets per plane (1 or 4)
        hit = np.flatnonzero(best[:, a])
        seg[:, a] = hit[np.searchsorted(sl[hit], np.arange(n_s))]        # first minimum
    tk = np.take_along_axis(tau[seg], np.arange(n_a)[None, :, None], axis=2)[..., 0]
    point = pts[seg] + tk[..., None] * d[seg]
    return seg - offs[:-1, None], tk, point


def ratio_points(pts, m, offs, seg0, tau0, fractions):
    """Points at given fractions of each contour's length after a start point.

    Parameters
    ----------
    pts : (K, 2) float
    m : (S,) int
    offs : (S + 1,) int
    seg0 : (S,) int
    tau0 : (S,) float
        The start point of each contour: segment and position along it.
    fractions : (F,) or (S, F) float
        In [0, 1), e.g. `split_fractions` (the same for every plane) or per plane.

    Returns
    -------
    seg : (S, F) int64
    tau : (S, F) float
    point : (S, F, 2) float
        The points at arc length ``a0 + f * length`` (cyclic), ``a0`` the start's. A point
        at a vertex is reported at the start of the next segment of nonzero length.
    """
    m = np.asarray(m, dtype=np.int64)
    offs = np.asarray(offs, dtype=np.int64)
    _, _, nxt, seg_len = _contour_segments(pts, m, offs)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])                 # (K + 1,) global
    lo, hi = offs[:-1], offs[1:]
    base = cum[lo]
    length = cum[hi] - base
    g0 = lo + np.asarray(seg0, dtype=np.int64)
    a0 = cum[g0] - base + np.asarray(tau0, dtype=float) * seg_len[g0]
    f = np.asarray(fractions, dtype=float)
    a = a0[:, None] + (f if f.ndim == 2 else f[None, :]) * length[:, None]
    a = np.where(a >= length[:, None], a - length[:, None], a)        # once round at most
    target = base[:, None] + a
    g = np.clip(np.searchsorted(cum, target, side="right") - 1, lo[:, None], hi[:, None] - 1)
    span = seg_len[g]
    tk = np.where(span > 0, np.clip((target - cum[g]) / np.where(span > 0, span, 1.0), 0.0,
                                    1.0), 0.0)
    point = pts[g] + tk[..., None] * (pts[nxt[g]] - pts[g])
    return g - lo[:, None], tk, point


def insert_points(pts, m, offs, seg, tau, point, *, shift_kernel=None):
    """Insert points lying on the contours' segments as new vertices.

    Parameters
    ----------
    pts : (K, 2) float
    m : (S,) int
    offs : (S + 1,) int
    seg, tau : (S, A) int, float
        Where the points lie (`closest_points`, `ratio_points`).
    point : (S, A, 2) float
    shift_kernel : callable, optional
        Compiled ``(pts, m, offs, seg, offs2) -> new`` moving the old vertices
        (`fibres.slicing.morph`'s ``_insert_loop``); default: the array expression.

    Returns
    -------
    new : (K + S A, 2) float
        The contours with the points inserted after vertex ``seg`` in the order
        ``(seg, tau, a)``; back to back with ``m + A`` vertices each.
    index : (S, A) int64
        Local index of each inserted point in its new contour.
    """
    m = np.asarray(m, dtype=np.int64)
    offs = np.asarray(offs, dtype=np.int64)
    seg = np.asarray(seg, dtype=np.int64)
    tau = np.asarray(tau, dtype=float)
    n_s, n_a = seg.shape
    aa = np.arange(n_a)
    same = seg[:, None, :] == seg[:, :, None]
    before = ((seg[:, None, :] < seg[:, :, None])
              | (same & (tau[:, None, :] < tau[:, :, None]))
              | (same & (tau[:, None, :] == tau[:, :, None])
                 & (aa[None, None, :] < aa[None, :, None])))
    index = seg + 1 + before.sum(axis=2)                               # (S, A)
    offs2 = np.concatenate([[0], np.cumsum(m + n_a)])
    if shift_kernel is not None:
        new = shift_kernel(pts, m, offs, seg, offs2)
    else:
        sl = np.repeat(np.arange(n_s), m)
        j = np.arange(offs[-1]) - offs[sl]
        shift = (seg[sl] < j[:, None]).sum(axis=1)                     # points before j
        new = np.empty((offs2[-1], 2))
        new[offs2[sl] + j + shift] = pts
    new[(offs2[:-1, None] + index).ravel()] = np.asarray(point, dtype=float).reshape(-1, 2)
    return new, index


#: Split-point smoothing along the axis (`smooth_split_points`): Jacobi iterations (0: off,
#: the default, see there), weight per neighbouring plane, perimeter ratio, size condition.
SPLIT_SMOOTHING = {"iterations": 0, "weight": 1.0, "cut": 0.5, "size": 0.5}


def _arc_of(cum, offs, seg, tau):
    """Arc position (from each contour's first vertex) of points (segment, tau): (S, A)."""
    g = offs[:-1, None] + seg
    return cum[g] - cum[offs[:-1], None] + tau * (cum[g + 1] - cum[g])


def smooth_split_points(pts, m, offs, seg, tau, point, *, iterations=None, weight=None,
                        cut=None, size=None):
    """The split points of every plane moved towards its neighbours' split points.

    Departure from Kohout 2012 §3.3, whose perimeter-ratio rule (`ratio_points`) gives the
    starting positions: it fixes each split point's *fraction of the perimeter*, so where a
    section grows a lobe between two planes every split point after the lobe moves along
    the contour by its share of the lobe and the fibres step sideways (LHDL gluteus medius,
    planes 6-7 of 20: perimeter 226 -> 276 mm, a zig-zag mid-belly). Here each split point,
    as an arc position on its contour, is averaged with the points of that contour nearest
    (`closest_points`) to the two neighbouring planes' split points (weight 1 for its own,
    ``weight`` per neighbour; Jacobi ``iterations``): the split points are smoothed along
    the axis *in space*, and a lobe changes the fractions instead of moving the points. The
    start ``P0`` is kept. A neighbour takes part only if its perimeter is within a factor
    ``1 / cut`` of the plane's, fully from ``size`` times the largest perimeter and fading
    as the square below it, times ``sin^2(pi s / (S - 1))`` (0 at the end planes: the small
    end sections, whose fibres the attachment filter rebuilds, keep the paper's rule). A
    plane whose averaged points leave the order ``start < P_i1 < P_i2 < P_i3`` keeps those
    of the previous iteration. A plan freezes the points (rest pose) as material anchors.
    Off by default (``SPLIT_SMOOTHING["iterations"] = 0``; 3 turns it on). Measured with 3
    (``bench/render_lhdl.py`` inputs, 20 planes, default chain; 95th percentile of the
    turning angle between consecutive fibre segments, degrees): glut_max 22.0 -> 15.2,
    glut_med 15.1 -> 9.8 (the zig-zag gone), iliacus 15.7 -> 13.4, psoas 31.9 -> 31.3. But
    the plan's carried anchors (`fibres.plan`) then sit elsewhere, and the LHDL bend sweeps
    (tests/fibres/test_decompose_lhdl.py) lose: iliacus morph-only h/2h agreement 0.994 ->
    0.937 (target 0.95), glut_med/iliacus whole-section step ratios over their bounds (1
    or 2 iterations: other sweeps fail) -- they react to where the anchors sit.

    Parameters
    ----------
    pts, m, offs : the packed contours (module docstring)
    seg, tau : (S, 4) int, float
        Start and split points (`soft_start` with `split_fractions`).
    point : (S, 4, 2) float
    iterations, weight, cut, size : optional
        Default `SPLIT_SMOOTHING`.

    Returns
    -------
    seg, tau, point : (S, 4) int64, (S, 4) float, (S, 4, 2) float
        Column 0 (the start) unchanged; the split points in arc order after it.
    """
    opt = dict(SPLIT_SMOOTHING)
    given = dict(iterations=iterations, weight=weight, cut=cut, size=size)
    opt.update({k: v for k, v in given.items() if v is not None})
    m, offs = np.asarray(m, dtype=np.int64), np.asarray(offs, dtype=np.int64)
    seg, tau, point = np.array(seg, np.int64), np.array(tau, float), np.array(point, float)
    n_s = m.size
    if n_s < 3 or opt["iterations"] <= 0 or opt["weight"] <= 0:
        return seg, tau, point                                        # off: unchanged
    _, _, _, seg_len = _contour_segments(pts, m, offs)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    L = cum[offs[1:]] - cum[offs[:-1]]                                # (S,) perimeters
    a0 = _arc_of(cum, offs, seg[:, :1], tau[:, :1])                   # (S, 1) start
    Ls = np.where(L > 0, L, 1.0)[:, None]
    cur = (_arc_of(cum, offs, seg[:, 1:], tau[:, 1:]) - a0) % Ls      # (S, 3) after start
    taper = np.sin(np.pi * np.arange(n_s) / (n_s - 1)) ** 2
    w = np.zeros((n_s, 2))                                            # (S, [s - 1, s + 1])
    for j, d in enumerate((-1, 1)):
        s = np.arange(max(0, -d), n_s - max(0, d))
        lo, hi = np.minimum(L[s], L[s + d]), np.maximum(L[s], L[s + d])
        like = (lo >= opt["cut"] * hi) & (lo > 0)
        big = np.clip(lo / (opt["size"] * L.max()), 0.0, 1.0) ** 2 if L.max() > 0 else 0.0
        w[s, j] = np.where(like, opt["weight"] * taper[s] * big, 0.0)
    active = w.sum(axis=1) > 0
    cur_pt, s_idx = point[:, 1:], np.arange(n_s)
    for _ in range(int(opt["iterations"])):
        # the neighbours' split points (S, 6, 2); rows without a neighbour weigh 0
        tgt = np.concatenate([cur_pt[np.maximum(s_idx - 1, 0)],
                              cur_pt[np.minimum(s_idx + 1, n_s - 1)]], axis=1)
        cs, ct, _ = closest_points(pts, m, offs, tgt)
        r = (_arc_of(cum, offs, cs, ct) - a0) % Ls                    # (S, 6)
        acc, wsum = cur.copy(), np.ones((n_s, 1))
        for j in range(2):
            dr = (r[:, 3 * j:3 * j + 3] - cur + 0.5 * Ls) % Ls - 0.5 * Ls
            acc += w[:, j:j + 1] * (cur + dr)
            wsum += w[:, j:j + 1]
        new = acc / wsum
        ok = (active & (new[:, 0] > 0) & (np.diff(new, axis=1) > 0).all(axis=1)
              & (new[:, 2] < L))
        cur = np.where(ok[:, None], new, cur)
        s1, t1, cur_pt = ratio_points(pts, m, offs, seg[:, 0], tau[:, 0], cur / Ls)
    act = np.flatnonzero(active)
    seg[act, 1:], tau[act, 1:], point[act, 1:] = s1[act], t1[act], cur_pt[act]
    return seg, tau, point
