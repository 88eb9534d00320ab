"""Support screen of the box search (`fibres.fitting`, Kohout et al., GRAPP 2012, §3.2).

The box of every rotation about the principal axis needs the minimum and maximum of the
projections ``cos(t) a + sin(t) b`` of the vertices' cross-section coordinates (a, b). Only
points that can attain such a minimum or maximum for some angle t matter: a superset of
the vertices of the points' convex hull. The screen drops the others, exactly: what it
drops lies deeper inside a convex polygon spanned by some of the points than a margin
``delta`` (1e-9 of the spread, ~1e7 times the rounding of a projection), so a polygon
vertex (kept) exceeds its projection in every direction and no minimum or maximum changes,
bit for bit.

- Polygon screen (Akl & Toussaint 1978, "A fast convex hull algorithm", Inf. Process.
  Lett. 7(5):219-222): the points extreme along n evenly spread directions span a convex
  polygon inside the hull; a point farther than delta inside every edge is dropped. Passes
  of `_SCREEN_DIRECTIONS` (8, 32, 128) directions; the first, coarse polygon is spanned by
  the extremes of every `_SCREEN_STRIDE`-th point only (any points of the set span a
  polygon inside the hull; this one is found 8x faster). numpy (`polygon_screen_numpy`),
  compiled (`_screen_loop`, the same candidates).
- Sector hull screen (compiled, `_hull_screen_loop`), after the first polygon pass: a finer
  polygon from the farthest point of each of `_HULL_BINS` angular sectors, each point tested
  against the edge(s) of its own sector only (one or two instead of every edge; the
  docstring states why that is exact). The compiled `fibres.fitting._support_candidates`
  is the 8-direction polygon then this; numpy's is the three polygons. The two keep
  different candidates, both every extreme point, so the boxes are the same.
"""
from __future__ import annotations

import numpy as np

__all__ = []

#: directions of the polygons that screen the support candidates (numpy: three passes; the
#: third cuts ~1200 candidates of a twisted 15K-vertex spindle to ~350)
_SCREEN_DIRECTIONS = (8, 32, 128)
#: the first screening pass takes its polygon from every 8th point
_SCREEN_STRIDE = 8
#: compiled: one polygon pass (8 directions), then the hull screen with this many bins
_HULL_BINS = 128


def _screen_tables(directions):
    """The compiled polygon screen's tables: pass sizes, cos and sin of all passes'
    directions back to back (the numpy version's angles ``2 pi k / n``)."""
    out = (np.array(directions, dtype=np.int64),
           np.concatenate([np.cos(2.0 * np.pi * np.arange(n) / n) for n in directions]),
           np.concatenate([np.sin(2.0 * np.pi * np.arange(n) / n) for n in directions]))
    for table in out:
        table.flags.writeable = False
    return out


_SCREEN = _screen_tables(_SCREEN_DIRECTIONS)
_FIRST_SCREEN = _screen_tables(_SCREEN_DIRECTIONS[:1])


def polygon_screen_numpy(a, b, spread):
    """The polygon screen (module docstring) with arrays: indices (V',) int64, increasing,
    of the points a, b (V,) kept; ``spread`` = max(ptp a, ptp b)."""
    idx = np.arange(a.size)
    for n_dir in _SCREEN_DIRECTIONS:
        if idx.size <= 4 * n_dir:
            break
        phi = 2.0 * np.pi * np.arange(n_dir) / n_dir
        pa, pb = a[idx], b[idx]
        step = _SCREEN_STRIDE if n_dir == _SCREEN_DIRECTIONS[0] else 1
        proj = np.cos(phi)[:, None] * pa[::step] + np.sin(phi)[:, None] * pb[::step]
        ext = np.argmax(proj, axis=1) * step        # counter-clockwise around the hull
        ext = ext[np.append(ext[1:] != ext[:-1], ext[-1] != ext[0])]     # distinct corners
        if np.unique(ext).size < 3:
            break
        qa, qb = pa[ext], pb[ext]
        ea, eb = np.roll(qa, -1) - qa, np.roll(qb, -1) - qb               # polygon edges
        margin = 1e-9 * spread * np.hypot(ea, eb)                          # distance * |edge|
        inside = np.ones(idx.size, dtype=bool)
        for k in range(ext.size):  # polygon edges (at most 128)
            inside &= ea[k] * (pb - qb[k]) - eb[k] * (pa - qa[k]) > margin[k]
        idx = idx[~inside]
    return idx


def _screen_loop(a, b, dirs, cos_all, sin_all, margin_scale,
                 stride):  # pragma: no cover - compiled by numba
    """`polygon_screen_numpy` in one call: the array version's polygons, margins and tests
    (hence its indices), directions ``cos_all``, ``sin_all`` of all passes back to back;
    each pass gathers its points contiguously and tests them against 8 edges at a time
    (vectorised)."""
    idx = np.arange(a.size)
    off = 0
    for n_dir in dirs:
        c = cos_all[off:off + n_dir]
        s = sin_all[off:off + n_dir]
        step = stride if off == 0 else 1
        off += n_dir
        m = idx.size
        if m <= 4 * n_dir:
            break
        if off == n_dir:
            pa, pb = a, b                   # the first pass: every point, in order
        else:
            pa = np.empty(m)
            pb = np.empty(m)
            for i in range(m):
                pa[i] = a[idx[i]]
                pb[i] = b[idx[i]]
        best = np.full(n_dir, -np.inf)
        arg = np.zeros(n_dir, dtype=np.int64)
        for i in range(0, m, step):
            for k in range(n_dir):
                p = c[k] * pa[i] + s[k] * pb[i]
                if p > best[k]:         # first maximum, as argmax (values are finite)
                    best[k] = p
                    arg[k] = i
        q = np.empty(n_dir, dtype=np.int64)
        nq = 0
        for k in range(n_dir):
            if arg[k] != arg[k + 1 if k + 1 < n_dir else 0]:
                q[nq] = arg[k]
                nq += 1
        if nq == 0 or np.unique(q[:nq]).size < 3:
            break
        # the edges in groups of 8 (the last padded with copies of edge 0: the same test
        # again changes nothing), each group one pass over the points with its 8 tests
        # unrolled (vectorised over the points)
        n_e = (nq + 7) // 8 * 8
        qa = np.empty(n_e)
        qb = np.empty(n_e)
        ea = np.empty(n_e)
        eb = np.empty(n_e)
        margin = np.empty(n_e)
        for k in range(n_e):
            kk = k if k < nq else 0
            kn = kk + 1 if kk + 1 < nq else 0
            qa[k], qb[k] = pa[q[kk]], pb[q[kk]]
            ea[k], eb[k] = pa[q[kn]] - qa[k], pb[q[kn]] - qb[k]
            margin[k] = margin_scale * np.hypot(ea[k], eb[k])
        inside = np.ones(m, dtype=np.bool_)
        for g in range(0, n_e, 8):
            for i in range(m):
                x = pa[i]
                y = pb[i]
                ok = inside[i]
                for k in range(g, g + 8):
                    ok &= ea[k] * (y - qb[k]) - eb[k] * (x - qa[k]) > margin[k]
                inside[i] = ok
        keep = np.empty(m, dtype=np.int64)
        n_keep = 0
        for i in range(m):
            keep[n_keep] = idx[i]
            n_keep += not inside[i]
        idx = keep[:n_keep]
    return idx


def _pseudo_angle(x, y):  # pragma: no cover - compiled by numba (inlined)
    """Monotone stand-in for the polar angle of (x, y): ``t = y / (|x| + |y|)`` mapped to
    [0, 4) counter-clockwise from +x (quadrants [0, 1], (1, 2], (2, 3), (3, 4)); 0 at the
    origin."""
    s = abs(x) + abs(y)
    if s == 0.0:
        return 0.0
    t = y / s
    if x >= 0.0:
        return t if y >= 0.0 else 4.0 + t
    return 2.0 - t


def _hull_screen_loop(pa, pb, delta, n_bins):  # pragma: no cover - compiled by numba
    """Indices (increasing) of the 2D points (pa, pb) (m,) that can be extreme in some
    direction, after a convex polygon Q with vertices among the points; all indices if Q
    is unusable. Coordinates below are relative to the points' mean o (inside their hull).

    Q: the farthest point from o in each of ``n_bins`` angular sectors (pseudo-angle bins,
    `_pseudo_angle`), in angular order, reduced to a convex polygon by Graham's scan from
    the farthest of them (a hull vertex). Used only if every turn is strictly left and o
    lies inside every edge by more than 4 ``delta`` (then o is inside Q and the rays from
    it through Q's vertices cut the plane into wedges, one per edge).

    Dropped: a point p in the wedge of edge k with ``cross_k(p) > 2 delta cross_k(o) /
    h_min`` (``cross_k(x) = e_k x (x - q_k)``, |e_k| times the distance inside edge k's
    line; h_min the smallest distance from o to an edge line). Exact: p - o is then
    ``l1 (q_k - o) + l2 (q_k+1 - o)``, l1, l2 >= 0, with ``l0 = 1 - l1 - l2 = cross_k(p) /
    cross_k(o) > 2 delta / h_min``, so for every direction t, ``(p - o).t <= (1 - l0) S(t)``
    with ``S(t) = max_q (q - o).t >= h_min`` (Q contains o) and ``S(t) - (p - o).t >= l0
    h_min > 2 delta``: Q's vertices (kept: ``cross_k(q_k) = 0``) exceed p's projection by
    far more than rounding (delta is 1e-9 of the spread; rounding ~1e-16), so no minimum
    or maximum changes. Each point is tested against every edge whose wedge meets its bin
    (widened by 1e-9 in pseudo-angle, far above its rounding), its own wedge's edge among
    them.
    """
    m = pa.size
    every = np.arange(m)
    if m == 0:
        return every
    oa = 0.0
    ob = 0.0
    for i in range(m):
        oa += pa[i]
        ob += pb[i]
    oa /= m
    ob /= m
    per = n_bins / 4.0
    bins = np.empty(m, dtype=np.int64)
    r2s = np.empty(m)
    top = n_bins - 1
    for i in range(m):                  # bins (vectorised: no branches)
        x = pa[i] - oa
        y = pb[i] - ob
        s = abs(x) + abs(y)
        t = y / (s if s > 0.0 else 1.0)
        psi = (t if y >= 0.0 else 4.0 + t) if x >= 0.0 else 2.0 - t
        bi = int(psi * per)
        bins[i] = bi if bi < top else top
        r2s[i] = x * x + y * y
    best = np.full(n_bins, -1.0)
    arg = np.full(n_bins, -1, dtype=np.int64)
    for i in range(m):                  # the farthest point of each bin
        bi = bins[i]
        if r2s[i] > best[bi]:
            best[bi] = r2s[i]
            arg[bi] = i
    cand = np.empty(n_bins, dtype=np.int64)
    n_c = 0
    start = 0
    for bi in range(n_bins):
        if arg[bi] >= 0:
            if n_c == 0 or best[bi] > best[bins[cand[start]]]:
                start = n_c
            cand[n_c] = arg[bi]
            n_c += 1
    if n_c < 3:
        return every
    hull = np.empty(n_c + 1, dtype=np.int64)
    n_h = 0
    for j in range(start, start + n_c + 1):     # Graham's scan, back to the start
        i = cand[j - n_c if j >= n_c else j]
        while n_h >= 2:
            h1 = hull[n_h - 1]
            h2 = hull[n_h - 2]
            if (pa[h1] - pa[h2]) * (pb[i] - pb[h1]) - (pb[h1] - pb[h2]) * (pa[i] - pa[h1]) > 0:
                break
            n_h -= 1
        hull[n_h] = i
        n_h += 1
    n_h -= 1                                    # the start again
    if n_h < 3:
        return every
    # vertices from the smallest pseudo-angle on, tables doubled for the cyclic edge runs
    low = 0
    psi = np.empty(n_h)
    for k in range(n_h):
        psi[k] = _pseudo_angle(pa[hull[k]] - oa, pb[hull[k]] - ob)
        if psi[k] < psi[low]:
            low = k
    qa = np.empty(2 * n_h + 1)
    qb = np.empty(2 * n_h + 1)
    ps = np.empty(n_h)
    for k in range(2 * n_h + 1):
        h = low + k
        while h >= n_h:
            h -= n_h
        qa[k] = pa[hull[h]]
        qb[k] = pb[hull[h]]
        if k < n_h:
            ps[k] = psi[h]
    ea = np.empty(2 * n_h)
    eb = np.empty(2 * n_h)
    thr = np.empty(2 * n_h)
    h_min = np.inf
    for k in range(2 * n_h):
        ea[k] = qa[k + 1] - qa[k]
        eb[k] = qb[k + 1] - qb[k]
        thr[k] = ea[k] * (ob - qb[k]) - eb[k] * (oa - qa[k])       # cross_k(o)
    for k in range(n_h):
        if ea[k] * eb[k + 1] - eb[k] * ea[k + 1] <= 0.0:
            return every
        h_min = min(h_min, thr[k] / np.hypot(ea[k], eb[k]))
    if not h_min > 4.0 * delta:
        return every
    for k in range(2 * n_h):
        thr[k] = 2.0 * delta * thr[k] / h_min
    # per bin: the run of edges whose wedges meet it (edge k spans ps[k] .. ps[k + 1]; the
    # last one wraps through 4 = 0)
    first = np.empty(n_bins, dtype=np.int64)
    count = np.empty(n_bins, dtype=np.int64)
    for bi in range(n_bins):
        lo = bi / per - 1e-9
        hi = (bi + 1) / per + 1e-9
        lo = lo + 4.0 if lo < 0.0 else lo
        hi = hi - 4.0 if hi >= 4.0 else hi
        k_lo = np.searchsorted(ps, lo, side="right") - 1
        k_hi = np.searchsorted(ps, hi, side="right") - 1
        k_lo = n_h - 1 if k_lo < 0 else k_lo     # before the first vertex: the wrapping edge
        k_hi = n_h - 1 if k_hi < 0 else k_hi
        first[bi] = k_lo
        count[bi] = k_hi - k_lo + 1 if k_hi >= k_lo else k_hi + n_h - k_lo + 1
    keep = np.empty(m, dtype=np.int64)
    n_k = 0
    for i in range(m):
        bi = bins[i]
        x = pa[i]
        y = pb[i]
        k = first[bi]
        out = not ea[k] * (y - qb[k]) - eb[k] * (x - qa[k]) > thr[k]
        if not out:
            for k in range(first[bi] + 1, first[bi] + count[bi]):
                if not ea[k] * (y - qb[k]) - eb[k] * (x - qa[k]) > thr[k]:
                    out = True
                    break
        keep[n_k] = i
        n_k += out
    return keep[:n_k]


def _candidates_loop(a, b, dirs, cos_all, sin_all, stride,
                     n_bins):  # pragma: no cover - compiled by numba
    """The compiled support screen (`fibres.fitting._support_candidates`): the margin
    ``delta`` = 1e-9 of the spread (``max(ptp a, ptp b)``), the polygon pass(es) of
    `_screen_loop` (``dirs``), then `_hull_screen_loop` on their survivors. Returns the
    indices (increasing)."""
    a_lo = a_hi = a[0]
    b_lo = b_hi = b[0]
    for i in range(1, a.size):
        x = a[i]
        y = b[i]
        a_lo = x if x < a_lo else a_lo
        a_hi = x if x > a_hi else a_hi
        b_lo = y if y < b_lo else b_lo
        b_hi = y if y > b_hi else b_hi
    delta = 1e-9 * max(a_hi - a_lo, b_hi - b_lo)
    keep = _screen_loop(a, b, dirs, cos_all, sin_all, delta, stride)
    pa = np.empty(keep.size)
    pb = np.empty(keep.size)
    for i in range(keep.size):
        pa[i] = a[keep[i]]
        pb[i] = b[keep[i]]
    sub = _hull_screen_loop(pa, pb, delta, n_bins)
    out = np.empty(sub.size, dtype=np.int64)
    for i in range(sub.size):
        out[i] = keep[sub[i]]
    return out


def compile_screens(jit):
    """(polygon screen, support candidates) compiled with numba's ``jit`` (`_screen_loop`,
    `_candidates_loop` with the compiled loops it calls: numba resolves the globals of a
    compiled function when it compiles it)."""
    import types

    import numba

    def with_globals(fn, **called):
        return jit(types.FunctionType(fn.__code__, dict(fn.__globals__, **called), fn.__name__))

    screen = jit(_screen_loop)
    hull = with_globals(_hull_screen_loop,
                        _pseudo_angle=numba.njit(inline="always")(_pseudo_angle))
    return screen, with_globals(_candidates_loop, _screen_loop=screen,
                                _hull_screen_loop=hull)
