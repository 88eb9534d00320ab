"""Compiled loops of `fibres.morph` (slicing and morphing, Kohout et al., GRAPP 2012, §3.3).

Each loop does the arithmetic of the array expressions it replaces in the same order, so
the results are the same bit for bit (see the callers in `fibres.morph`, which fall back to
numpy without numba):

- `_cross_loop`, `_clockwise_loop`: the chosen loops' orientation terms and their clockwise
  gather (`fibres.morph._clockwise_all`);
- `_insert_loop`, `_roll_loop`, `_subdivide_loop`: the correspondence points inserted as
  vertices, each contour rolled to its start and the rectangle subdivided like it
  (`fibres.morph._insert_and_subdivide`);
- `_maps_pass`: all of `fibres.morph.slice_maps` (without split smoothing) in one call over
  all planes -- the loops above, the soft start (`fibres.correspondence.soft_start`'s
  kernel), the insertion order of `fibres.correspondence.insert_points` and the material
  anchors -- with the outputs allocated once instead of per numpy step, and each old
  segment's length measured once (the soft start's ``hypot`` reused by the roll: the same
  function of the same difference);
- `_morph_pass`: all of `fibres.morph.morph_local` in one call: each point's plane pair and
  blending weight, the mean value map of every (point, plane) use (`fibres.mvc`'s
  vectorised kernel) and the two planes' contributions added in the array version's order.
"""
from __future__ import annotations

import numpy as np

__all__ = []


def _cross_loop(points, lo, m, offs):  # pragma: no cover - compiled by numba
    """Per-vertex terms ``x_j y_{j+1} - x_{j+1} y_j`` of the loops' signed areas."""
    out = np.empty(offs[-1])
    for s in range(m.size):
        for j in range(m[s]):
            a = lo[s] + j
            b = a + 1 if j + 1 < m[s] else lo[s]
            out[offs[s] + j] = points[a, 0] * points[b, 1] - points[b, 0] * points[a, 1]
    return out


def _clockwise_loop(points, edge, lo, m, offs, flip):  # pragma: no cover - numba
    """Indices, points and edges of the loops in clockwise order (reversed where ``flip``)."""
    n = offs[-1]
    idx = np.empty(n, np.int64)
    pts = np.empty((n, 2))
    ed = np.empty(n, np.int64)
    for s in range(m.size):
        for j in range(m[s]):
            i = lo[s] + m[s] - 1 - j if flip[s] else lo[s] + j
            q = offs[s] + j
            idx[q] = i
            pts[q, 0], pts[q, 1] = points[i, 0], points[i, 1]
            ed[q] = edge[i]
    return idx, pts, ed


def _insert_loop(pts, m, offs, seg, offs2):  # pragma: no cover - compiled by numba
    """The contours with A free slots per plane: vertex j moves up by the number of
    points inserted before it (segments < j)."""
    new = np.empty((offs2[-1], 2))
    for s in range(m.size):
        for j in range(m[s]):
            shift = 0
            for k in range(seg.shape[1]):
                if seg[s, k] < j:
                    shift += 1
            new[offs2[s] + j + shift, 0] = pts[offs[s] + j, 0]
            new[offs2[s] + j + shift, 1] = pts[offs[s] + j, 1]
    return new


def _segment_lengths(pts, m, offs):  # pragma: no cover - compiled by numba
    """Length of every segment ``P_j -> P_{j+1}`` of contours back to back (K,): ``hypot``
    of the difference, as `fibres.correspondence._contour_segments`."""
    seg = np.empty(pts.shape[0])
    for s in range(m.size):
        o = offs[s]
        for j in range(m[s]):
            nx = o + j + 1 if j + 1 < m[s] else o
            seg[o + j] = np.hypot(pts[nx, 0] - pts[o + j, 0], pts[nx, 1] - pts[o + j, 1])
    return seg


def _roll_loop(pts, m, offs, start):  # pragma: no cover - compiled by numba
    """Rolled contours P, segment lengths and arc lengths (cumulated over all contours
    back to back, then measured from each contour's start, as the array version)."""
    return _roll_lengths(pts, m, offs, start, _segment_lengths(pts, m, offs))


def _roll_lengths(pts, m, offs, start, seg_len):  # pragma: no cover - compiled by numba
    """`_roll_loop` with the unrolled contours' segment lengths given (``seg_len``,
    `_segment_lengths`): a rolled segment is an unrolled one, the same ``hypot`` of the
    same difference. Indices stepped without integer division."""
    n = pts.shape[0]
    roll = np.empty(n, dtype=np.int64)
    P = np.empty((n, 2))
    seg = np.empty(n)
    c_incl = np.empty(n)
    c_excl = np.empty(n)
    for s in range(m.size):
        o = offs[s]
        i = start[s] % m[s]
        for j in range(m[s]):
            roll[o + j] = o + i
            P[o + j, 0] = pts[o + i, 0]
            P[o + j, 1] = pts[o + i, 1]
            seg[o + j] = seg_len[o + i]
            i = i + 1 if i + 1 < m[s] else 0
    cum = 0.0
    for s in range(m.size):
        o = offs[s]
        base = cum
        for j in range(m[s]):
            cum += seg[o + j]
            c_incl[o + j] = cum - base
            c_excl[o + j] = c_incl[o + j] - seg[o + j]
    return roll, P, seg, c_incl, c_excl


def _subdivide_loop(m, offs, split, c_incl, c_excl, rect):  # pragma: no cover - numba
    """The subdivided rectangles Q (each side like its part of the contour)."""
    Q = np.empty((c_incl.size, 2))
    bounds = np.empty(5, dtype=np.int64)
    arc = np.empty(5)
    for s in range(m.size):
        o = offs[s]
        bounds[0] = 0
        arc[0] = 0.0
        for k in range(3):
            bounds[k + 1] = split[s, k]
            arc[k + 1] = c_excl[o + split[s, k]]
        bounds[4] = m[s]
        arc[4] = c_incl[o + m[s] - 1]
        for j in range(m[s]):
            part = 0
            for k in range(3):
                if j >= split[s, k]:
                    part += 1
            a0 = arc[part]
            span = arc[part + 1] - a0
            if span > 0:
                frac = (c_excl[o + j] - a0) / span
            else:
                frac = (j - bounds[part]) / (bounds[part + 1] - bounds[part])
            p1 = (part + 1) % 4
            Q[o + j, 0] = rect[part, 0] + frac * (rect[p1, 0] - rect[part, 0])
            Q[o + j, 1] = rect[part, 1] + frac * (rect[p1, 1] - rect[part, 1])
    return Q


def _pairwise_sum(a, lo, n):  # pragma: no cover - compiled by numba (and called by it)
    """numpy's pairwise summation of ``a[lo:lo + n]`` (its float64 add loop: sequential
    below 8 terms, eight running sums up to 128, halves rounded down to a multiple of 8
    above), so the same rounding as ``np.add.reduce``'s inner loop."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    if n <= 128:
        r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
        r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
        i = 8
        while i < n - n % 8:
            r0 += a[lo + i]
            r1 += a[lo + i + 1]
            r2 += a[lo + i + 2]
            r3 += a[lo + i + 3]
            r4 += a[lo + i + 4]
            r5 += a[lo + i + 5]
            r6 += a[lo + i + 6]
            r7 += a[lo + i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[lo + i]
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise_sum(a, lo, n2) + _pairwise_sum(a, lo + n2, n - n2)


def _reduceat_sum(a, lo, n):  # pragma: no cover - compiled by numba (and called by it)
    """``np.add.reduceat``'s sum of a segment ``a[lo:lo + n]`` (n >= 1): its first term
    plus the pairwise sum of the others."""
    return a[lo] + _pairwise_sum(a, lo + 1, n - 1) if n > 1 else a[lo]


def _maps_pass(points, edge, t, loop_start, chosen, edges, ex, ey, spread,
               floor):  # pragma: no cover - compiled by numba
    """`fibres.morph.slice_maps` without split smoothing, all planes in one pass.

    Parameters
    ----------
    points, edge, t, loop_start : `fibres.slicing.Sections` arrays
    chosen : (S,) int64
        Loop per plane, >= 0.
    edges : (E, 2) int64
        Mesh edges (`fibres.slicing.MeshTopology.edges`).
    ex, ey : float
        The rectangle ``[0, ex] x [0, ey]``.
    spread, floor : float
        `fibres.plan.SOFT_SPREAD`, `fibres.plan.SOFT_FLOOR`.

    Returns
    -------
    P, Q : (K + 4 S, 2) float
        Rolled contours with the four points inserted and the subdivided rectangles, back
        to back (``offs2``).
    offs2 : (S + 1,) int64
    ok : (S,) bool
        As `fibres.morph._insert_and_subdivide`.
    choice : (S, 4) int64
    av, aw : (S, 4, 4) int64, (S, 4, 4) float
        The four points' material anchors.
    pts : (K, 2) float
        The clockwise contours (``offs`` (S + 1,)), for a degenerate plane's fallback.
    offs : (S + 1,) int64
    """
    n_s = chosen.size
    # _clockwise_all: the chosen loops, reversed where their signed area is positive
    lo = np.empty(n_s, np.int64)
    m = np.empty(n_s, np.int64)
    offs = np.zeros(n_s + 1, np.int64)
    for s in range(n_s):
        lo[s] = loop_start[chosen[s]]
        m[s] = loop_start[chosen[s] + 1] - lo[s]
        offs[s + 1] = offs[s] + m[s]
    cross = _cross_loop(points, lo, m, offs)
    flip = np.empty(n_s, np.bool_)
    for s in range(n_s):
        flip[s] = _reduceat_sum(cross, offs[s], m[s]) > 0
    idx, pts, ed = _clockwise_loop(points, edge, lo, m, offs, flip)
    # split_fractions of the rectangle (sides ey, ex, ey, ex; numpy's cumsum and sum order)
    sy, sx = abs(ey), abs(ex)
    total = ((sy + sx) + sy) + sx
    fractions = np.empty(3)
    fractions[0] = sy / total
    fractions[1] = (sy + sx) / total
    fractions[2] = ((sy + sx) + sy) / total
    q0 = np.zeros(2)
    seg_len = np.empty(offs[-1])
    seg, tk, point = _soft_start(pts, m, offs, q0, fractions, spread, floor, seg_len)
    # insert_points: index of each point in its new contour (order (seg, tau, a))
    n_a = 4
    index = np.empty((n_s, n_a), np.int64)
    for s in range(n_s):
        for a in range(n_a):
            before = 0
            for b in range(n_a):
                if seg[s, b] < seg[s, a] or (seg[s, b] == seg[s, a] and (
                        tk[s, b] < tk[s, a] or (tk[s, b] == tk[s, a] and b < a))):
                    before += 1
            index[s, a] = seg[s, a] + 1 + before
    m2 = m + n_a
    offs2 = np.zeros(n_s + 1, np.int64)
    for s in range(n_s):
        offs2[s + 1] = offs2[s] + m2[s]
    new = _insert_loop(pts, m, offs, seg, offs2)
    for s in range(n_s):
        for a in range(n_a):
            new[offs2[s] + index[s, a], 0] = point[s, a, 0]
            new[offs2[s] + index[s, a], 1] = point[s, a, 1]
    # the new contours' segment lengths: an old segment's where both ends are its old
    # vertices (the same hypot of the same difference), else measured
    old = np.empty(offs2[-1], np.int64)         # old local index at each new position
    for s in range(n_s):
        j = 0
        for i in range(m2[s]):
            if (i == index[s, 0] or i == index[s, 1] or i == index[s, 2]
                    or i == index[s, 3]):
                old[offs2[s] + i] = -1
            else:
                old[offs2[s] + i] = j
                j += 1
    new_len = np.empty(offs2[-1])
    for s in range(n_s):
        o = offs2[s]
        for i in range(m2[s]):
            nx = o + i + 1 if i + 1 < m2[s] else o
            j = old[o + i]
            if j >= 0 and old[nx] >= 0 and (old[nx] == j + 1 or (old[nx] == 0
                                                                and j == m[s] - 1)):
                new_len[o + i] = seg_len[offs[s] + j]
            else:
                new_len[o + i] = np.hypot(new[nx, 0] - new[o + i, 0],
                                          new[nx, 1] - new[o + i, 1])
    # _insert_and_subdivide: roll to the start, subdivide like the split
    start = np.empty(n_s, np.int64)
    split = np.empty((n_s, 3), np.int64)
    ok = np.empty(n_s, np.bool_)
    for s in range(n_s):
        start[s] = index[s, 0]
        for k in range(3):
            split[s, k] = (index[s, k + 1] - start[s]) % m2[s]
        ok[s] = 0 < split[s, 0] and split[s, 0] < split[s, 1] and split[s, 1] < split[s, 2]
        if not ok[s]:
            split[s, 0], split[s, 1], split[s, 2] = 1, 1, 1
    _, P, _, c_incl, c_excl = _roll_lengths(new, m2, offs2, start, new_len)
    rect = np.zeros((4, 2))
    rect[1, 1] = ey
    rect[2, 0], rect[2, 1] = ex, ey
    rect[3, 0] = ex
    Q = _subdivide_loop(m2, offs2, split, c_incl, c_excl, rect)
    # material anchors and choice: the two contour vertices around each point
    choice = np.empty((n_s, n_a), np.int64)
    av = np.empty((n_s, n_a, 4), np.int64)
    aw = np.empty((n_s, n_a, 4))
    for s in range(n_s):
        for a in range(n_a):
            i0 = idx[offs[s] + seg[s, a]]
            i1 = idx[offs[s] + (seg[s, a] + 1) % m[s]]
            tau = tk[s, a]
            choice[s, a] = edge[i0] if tau < 0.5 else edge[i1]
            av[s, a, 0], av[s, a, 1] = edges[edge[i0], 0], edges[edge[i0], 1]
            av[s, a, 2], av[s, a, 3] = edges[edge[i1], 0], edges[edge[i1], 1]
            aw[s, a, 0] = (1.0 - tau) * (1.0 - t[i0])
            aw[s, a, 1] = (1.0 - tau) * t[i0]
            aw[s, a, 2] = tau * (1.0 - t[i1])
            aw[s, a, 3] = tau * t[i1]
    return P, Q, offs2, ok, choice, av, aw, pts, offs


def _morph_pass(xy, w, h, src_x, src_y, src, dst, offsets, eps):  # pragma: no cover
    """`fibres.morph.morph_local` in one call (compiled by numba): for each point the
    planes ``s0 = clip(searchsorted(h, w, "right") - 1, 0, S - 2)`` and ``s0 + 1`` with
    the weights ``1 - a``, ``a`` (``a`` the clipped fraction of the slab), a row per use
    with nonzero weight (first the lower planes' rows, then the upper ones', each in point
    order), mapped by `fibres.mvc`'s vectorised kernel, and ``out = (0 + lower) + upper``.
    Returns (M, 2) float."""
    n = xy.shape[0]
    n_s = h.size
    s0 = np.empty(n, np.int64)
    frac = np.empty(n)
    n_lo = 0
    n_hi = 0
    for p in range(n):
        lo_, hi_ = 0, n_s                      # searchsorted(h, w[p], side="right")
        while lo_ < hi_:
            mid = (lo_ + hi_) // 2
            if w[p] < h[mid]:
                hi_ = mid
            else:
                lo_ = mid + 1
        s = min(max(lo_ - 1, 0), n_s - 2)
        s0[p] = s
        a = (w[p] - h[s]) / (h[s + 1] - h[s])
        a = min(max(a, 0.0), 1.0)
        frac[p] = a
        if a < 1.0:
            n_lo += 1
        if a > 0.0:
            n_hi += 1
    rows = np.empty((n_lo + n_hi, 2))
    groups = np.empty(n_lo + n_hi, np.int64)
    wts = np.empty(n_lo + n_hi)
    q_lo = 0
    q_hi = n_lo
    for p in range(n):
        if frac[p] < 1.0:
            rows[q_lo, 0], rows[q_lo, 1] = xy[p, 0], xy[p, 1]
            groups[q_lo] = s0[p]
            wts[q_lo] = 1.0 - frac[p]
            q_lo += 1
        if frac[p] > 0.0:
            rows[q_hi, 0], rows[q_hi, 1] = xy[p, 0], xy[p, 1]
            groups[q_hi] = s0[p] + 1
            wts[q_hi] = frac[p]
            q_hi += 1
    mapped = np.empty((n_lo + n_hi, 2))
    _mvc_vec(rows, groups, wts, src_x, src_y, src, dst, offsets, eps, mapped)
    out = np.zeros((n, 2))
    q_lo = 0
    q_hi = n_lo
    for p in range(n):
        if frac[p] < 1.0:
            out[p, 0] += mapped[q_lo, 0]
            out[p, 1] += mapped[q_lo, 1]
            q_lo += 1
    for p in range(n):
        if frac[p] > 0.0:
            out[p, 0] += mapped[q_hi, 0]
            out[p, 1] += mapped[q_hi, 1]
            q_hi += 1
    return out


#: compiled callees of `_maps_pass` and `_morph_pass` (set by `kernels`)
_soft_start = None
_mvc_vec = None

_KERNELS = []


def kernels():
    """(roll, subdivide, anchor search, insertion, orientation terms, clockwise gather,
    slice_maps pass, morph_local pass) compiled with numba, or None."""
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)
