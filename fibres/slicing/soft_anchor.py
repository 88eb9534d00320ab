"""Correspondence points carried by a decomposition plan (`fibres.plan`,
`fibres.slicing.morph.anchored_maps`): on a deformed copy, the start and split points of each plane's
contour are found again near the rest pose's, softly (a Gaussian-weighted search along the arc,
so that they move continuously). Re-exported by `fibres.slicing.correspondence`, whose `soft_start`
places the rest pose's start the same way. Kohout et al. (GRAPP 2012) §3.3 choose these points
as contour vertices; here they are continuous (see `fibres.slicing.correspondence`).

The loop `_soft_anchor_loop` runs in Python (no compiled kernels: docs/decisions.md, issue 13).
"""
from __future__ import annotations

from math import erf, erfc, exp, pi, sqrt

import numpy as np

#: Smallest arc length between consecutive start/split points of an anchored contour, as a
#: fraction of its length, where `_order_arcs` has to restore their order.
ARC_GAP = 1e-3

#: Split point k of an anchored contour is searched within this fraction of the contour
#: length around its nominal position after the start (the rectangle corner's arc fraction).
ARC_WINDOW = 0.25


def _order_arcs(a, lo, hi):
    """Euclidean projection of ``a`` (3,) onto ``lo <= a0 <= a1 <= a2 <= hi``: pool adjacent
    violators (isotonic regression), then clip -- a continuous (1-Lipschitz) map that is
    the identity on ordered input (Barlow et al. 1972, "Statistical inference under order
    restrictions"; clipping the isotonic fit gives the bounded projection)."""
    val = np.empty(3)
    size = np.empty(3, dtype=np.int64)
    nb = 0
    for i in range(3):
        val[nb] = a[i]
        size[nb] = 1
        nb += 1
        while nb > 1 and val[nb - 2] > val[nb - 1]:
            tot = size[nb - 2] + size[nb - 1]
            val[nb - 2] = (val[nb - 2] * size[nb - 2] + val[nb - 1] * size[nb - 1]) / tot
            size[nb - 2] = tot
            nb -= 1
    out = np.empty(3)
    i = 0
    for b in range(nb):
        for _ in range(size[b]):
            out[i] = min(max(val[b], lo), hi)
            i += 1
    return out



#: Width of the soft closest point: the Gaussian weight of a contour point at distance d
#: from an anchor is ``exp(-(d^2 - d_min^2) / sigma^2)`` with
#: ``sigma^2 = (SOFT_SPREAD d_min)^2 + (SOFT_FLOOR L)^2``.
SOFT_SPREAD = 0.5
SOFT_FLOOR = 1e-7
#: Segments whose weight is below exp(-SOFT_CUTOFF) of the nearest one's are skipped (a
#: change of at most ~1e-17 relative, below rounding).
SOFT_CUTOFF = 40.0


def _erfcx(x):
    """exp(x^2) erfc(x), x >= 0 (asymptotic series beyond 20, relative error < 1e-11)."""
    if x < 20.0:
        return exp(x * x) * erfc(x)
    y = 1.0 / (x * x)
    return (1.0 - 0.5 * y * (1.0 - 1.5 * y * (1.0 - 2.5 * y * (1.0 - 3.5 * y)))) / (x * sqrt(pi))


def _gauss_segment(ax, px, dx, dim, sigma2):
    """Integral over t in [0, 1] of exp(-(|A - P - t D|^2 - d_c^2) / sigma^2) (d_c the
    distance to the segment's closest point, so the result is <= 1) and the mean t
    under that weight; exact (error functions), so splitting a segment in two changes
    nothing. Returns (integral, mean t, d_c^2)."""
    dd = 0.0
    rd = 0.0
    r2 = 0.0
    for c in range(dim):
        dd += dx[c] * dx[c]
        rd += (ax[c] - px[c]) * dx[c]
        r2 += (ax[c] - px[c]) * (ax[c] - px[c])
    if dd <= 1e-300:
        return 1.0, 0.5, r2
    ts = rd / dd                                   # unclamped projection
    tc = min(max(ts, 0.0), 1.0)
    dc2 = max(r2 - ts * ts * dd + (tc - ts) * (tc - ts) * dd, 0.0)
    beta = dd / sigma2
    sb = sqrt(beta)
    a = -sb * ts
    b = sb * (1.0 - ts)
    if a <= 0.0 <= b:
        f = 0.5 * sqrt(pi) * (erf(b) - erf(a))
        m2 = 0.0
    elif a > 0.0:
        f = 0.5 * sqrt(pi) * (_erfcx(a) - exp(a * a - b * b) * _erfcx(b))
        m2 = a * a
    else:
        f = 0.5 * sqrt(pi) * (_erfcx(-b) - exp(b * b - a * a) * _erfcx(-a))
        m2 = b * b
    i0 = f / sb
    if i0 <= 0.0:
        return 0.0, tc, dc2
    # first moment: t* I0 + (exp(-beta t*^2) - exp(-beta (1 - t*)^2)) / (2 beta), scaled
    i1 = ts * i0 + (exp(-(a * a - m2)) - exp(-(b * b - m2))) / (2.0 * beta)
    return i0, min(max(i1 / i0, 0.0), 1.0), dc2


def _soft_anchor_loop(pts, X, NX, m, offs, AX, NAX, nominal, gap, window,
                      spread, floor):
    """The four correspondence points of every plane from a plan's anchors, as smooth
    functions of the contour (a soft closest point instead of an argmin).

    For anchor ``A`` the contour is weighted by ``exp(-(d^2 - d_min^2) / sigma^2)`` (d: the
    distance in the matching coordinates ``X`` (K, D) to ``AX`` (S, 4, D); sigma as in
    `SOFT_SPREAD`), times ``max(0, cos)`` of the angle between the contour normal
    (``NX[j] + NX[j+1]``) and the anchor's (``NAX``; zero normals: factor 1), integrated
    exactly along each segment against arc length in the plane (`_gauss_segment`), and
    the point is the weighted mean arc position. Near the contour this is its closest
    point (sigma -> floor); where two far parts of the contour are about as near (a plane
    that has moved through the material), it moves smoothly between them instead of
    jumping. The start is averaged within half a contour around its hard closest point;
    split point k within ``window`` of the length around its nominal place after the
    start, with a weight tapering to zero at the window's ends; the three split
    positions are then put in order (`_order_arcs`, the identity on ordered input).

    Returns segment (S, 4), parameter (S, 4), the points in the plane (S, 4, 2) and
    which planes were reordered (S,)."""
    n_s = m.size
    dim = X.shape[1]
    dn = NX.shape[1]
    seg = np.empty((n_s, 4), dtype=np.int64)
    tk = np.empty((n_s, 4))
    point = np.empty((n_s, 4, 2))
    moved = np.zeros(n_s, dtype=np.bool_)
    arc = np.empty(4)
    b = np.empty(3)
    px = np.empty(dim)
    dx = np.empty(dim)
    ax = np.empty(dim)
    for s in range(n_s):
        o = offs[s]
        ms = m[s]
        cum = np.empty(ms + 1)
        cum[0] = 0.0
        for j in range(ms):
            a = o + j
            nb = o + (j + 1) % ms
            cum[j + 1] = cum[j] + np.hypot(pts[nb, 0] - pts[a, 0], pts[nb, 1] - pts[a, 1])
        length = cum[ms]
        face = np.ones(ms)
        gi = np.empty(ms)
        gt = np.empty(ms)
        gd = np.empty(ms)
        for k in range(4):
            for c in range(dim):
                ax[c] = AX[s, k, c]
            na = 0.0
            for c in range(dn):
                na += NAX[s, k, c] * NAX[s, k, c]
            any_face = False
            if na == 0.0:                               # no normals: every segment
                face[:] = 1.0
                any_face = True
            for j in range(ms if na > 0.0 else 0):
                a = o + j
                nb = o + (j + 1) % ms
                dot = 0.0
                nn = 0.0
                for c in range(dn):
                    nc = NX[a, c] + NX[nb, c]
                    dot += nc * NAX[s, k, c]
                    nn += nc * nc
                face[j] = max(dot, 0.0) / sqrt(nn * na) if nn * na > 0 else 1.0
                if face[j] > 0:
                    any_face = True
            if not any_face:
                face[:] = 1.0
            # window factor of the split points, from the start's arc position
            wf = np.ones(ms)
            if k > 0 and length > 0:
                nom = nominal[k - 1] * length
                for j in range(ms):
                    mid = 0.5 * (cum[j] + cum[j + 1])
                    rel = (mid - arc[0]) % length
                    if rel - nom > 0.5 * length:
                        rel -= length
                    elif rel - nom < -0.5 * length:
                        rel += length
                    z = (rel - nom) / (window * length)
                    wf[j] = max(1.0 - z * z, 0.0)
            # hard closest point (first minimum) among the admissible segments -> d_min
            best = np.inf
            bj = 0
            bt = 0.0
            for j in range(ms):
                if face[j] * wf[j] <= 0 and k > 0:
                    continue
                if face[j] <= 0:
                    continue
                a = o + j
                nb = o + (j + 1) % ms
                dd = 0.0
                rd = 0.0
                for c in range(dim):
                    dc = X[nb, c] - X[a, c]
                    dd += dc * dc
                    rd += (ax[c] - X[a, c]) * dc
                tau = min(max(rd / (dd if dd > 0 else 1.0), 0.0), 1.0)
                g2 = 0.0
                for c in range(dim):
                    gc = ax[c] - X[a, c] - tau * (X[nb, c] - X[a, c])
                    g2 += gc * gc
                gd[j] = g2
                if g2 < best:
                    best = g2
                    bj = j
                    bt = tau
            if best == np.inf or length <= 0:          # nothing admissible: hard point
                arc[k] = cum[bj] + bt * (cum[bj + 1] - cum[bj])
                if k > 0 and length > 0:
                    arc[k] = (arc[k] - arc[0]) % length
                continue
            sigma2 = spread * spread * best + (floor * length) ** 2
            ref = cum[bj] + bt * (cum[bj + 1] - cum[bj]) if k == 0 else arc[0]
            wsum = 0.0
            msum = 0.0
            for j in range(ms):
                w0 = face[j] * wf[j]
                if w0 <= 0 or gd[j] - best > SOFT_CUTOFF * sigma2:
                    continue                    # weight below exp(-SOFT_CUTOFF) of the best
                a = o + j
                nb = o + (j + 1) % ms
                for c in range(dim):
                    px[c] = X[a, c]
                    dx[c] = X[nb, c] - X[a, c]
                i0, tm, dc2 = _gauss_segment(ax, px, dx, dim, sigma2)
                w = w0 * (cum[j + 1] - cum[j]) * exp(-(dc2 - best) / sigma2) * i0
                if w <= 0:
                    continue
                # arc position of the weighted mean point, relative to ref, unwrapped
                pos = cum[j] + tm * (cum[j + 1] - cum[j]) - ref
                centre = 0.0 if k == 0 else nominal[k - 1] * length
                pos = (pos - centre + 0.5 * length) % length - 0.5 * length + centre
                wsum += w
                msum += w * pos
            if wsum > 0:
                arc[k] = (ref + msum / wsum) % length if k == 0 else msum / wsum
            else:
                arc[k] = cum[bj] + bt * (cum[bj + 1] - cum[bj]) if k == 0 else \
                    (cum[bj] + bt * (cum[bj + 1] - cum[bj]) - arc[0]) % length
        # splits: relative arc positions, put in order with gaps (continuous)
        out = b
        if length > 0:
            g = gap * length
            for k in range(3):
                b[k] = arc[k + 1] - (k + 1) * g
            ordered = b[0] >= 0.0 and b[0] <= b[1] and b[1] <= b[2] and b[2] <= length - 4 * g
            out = b
            if not ordered:
                moved[s] = True
                out = _order_arcs(b, 0.0, length - 4 * g)
        for k in range(4):
            if length > 0:
                t = arc[0] if k == 0 else arc[0] + out[k - 1] + k * gap * length
                t = t % length
            else:
                t = 0.0
            j = np.searchsorted(cum, t, side="right") - 1
            j = min(max(j, 0), ms - 1)
            while j > 0 and cum[j + 1] - cum[j] <= 0:
                j -= 1
            span = cum[j + 1] - cum[j]
            seg[s, k] = j
            tk[s, k] = min(max((t - cum[j]) / span, 0.0), 1.0) if span > 0 else 0.0
            a = o + seg[s, k]
            nb = o + (seg[s, k] + 1) % ms
            point[s, k, 0] = pts[a, 0] + tk[s, k] * (pts[nb, 0] - pts[a, 0])
            point[s, k, 1] = pts[a, 1] + tk[s, k] * (pts[nb, 1] - pts[a, 1])
    return seg, tk, point, moved


_ANCHOR_KERNEL = []


def anchor_kernel():
    """`_soft_anchor_loop` (Python; no compiled kernels: docs/decisions.md, issue 13)."""
    return _soft_anchor_loop  # numpy (no compiled kernels: docs/decisions.md, issue 13)
