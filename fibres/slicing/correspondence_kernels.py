"""The loop of `fibres.slicing.correspondence.soft_start` (the start point of Kohout et al., GRAPP
2012, §3.3, made soft; see there), in Python: 0.17 s of a planar rest decomposition of a
15K-triangle muscle, not called per frame with a plan (no compiled kernels: docs/decisions.md,
issue 13).
"""
from __future__ import annotations

from math import exp, pi

import numpy as np

from .soft_anchor import SOFT_CUTOFF, _gauss_segment

__all__ = []


def _mod(x, length):
    """``x % length`` for ``length > 0`` (Python's float modulo: ``fmod``, then ``+ length``
    for a negative remainder, ``+0.0`` for a zero one) without the ``fmod`` call where
    ``|x| < length``: there ``fmod(x, length)`` is ``x`` itself, so the result is ``x``
    or ``x + length`` -- the same value bit for bit."""
    if 0.0 < x < length:
        return x
    if -length < x < 0.0:
        return x + length
    return x % length


def _soft_start_loop(pts, m, offs, q0, fractions, spread, floor,
                     seg_len):
    """`fibres.slicing.correspondence.soft_start` as one loop over the planes (see there), followed
    by the points at the arc ``fractions`` after the start (`ratio_points`). Returns seg (S, 1 + F), tau (S, 1 + F), point
    (S, 1 + F, 2), and fills ``seg_len`` (K,) with the segment lengths ``|P_{j+1} - P_j|``
    (``hypot``, as `fibres.slicing.correspondence._contour_segments`)."""
    n_s = m.size
    n_p = 1 + fractions.size
    seg = np.zeros((n_s, n_p), dtype=np.int64)
    tk = np.zeros((n_s, n_p))
    point = np.zeros((n_s, n_p, 2))
    px = np.empty(2)
    dx = np.empty(2)
    for s in range(n_s):
        o = offs[s]
        ms = m[s]
        cum = np.empty(ms + 1)
        cum[0] = 0.0
        gd = np.empty(ms)
        best = np.inf
        bj = 0
        bt = 0.0
        for j in range(ms):
            a = o + j
            b = a + 1 if j + 1 < ms else o
            ex = pts[b, 0] - pts[a, 0]
            ey = pts[b, 1] - pts[a, 1]
            seg_len[a] = np.hypot(ex, ey)
            cum[j + 1] = cum[j] + seg_len[a]
            dd = ex * ex + ey * ey
            rx = q0[0] - pts[a, 0]
            ry = q0[1] - pts[a, 1]
            tau = min(max((rx * ex + ry * ey) / (dd if dd > 0 else 1.0), 0.0), 1.0)
            g2 = (rx - tau * ex) ** 2 + (ry - tau * ey) ** 2
            gd[j] = g2
            if g2 < best:
                best = g2
                bj = j
                bt = tau
        length = cum[ms]
        pos = cum[bj] + bt * (cum[bj + 1] - cum[bj])
        if length > 0:
            sigma2 = spread * spread * best + (floor * length) ** 2
            w = np.zeros(ms)
            mid = np.zeros(ms)
            cs = 0.0
            sn = 0.0
            for j in range(ms):
                if gd[j] - best > SOFT_CUTOFF * sigma2:
                    continue                    # weight below exp(-SOFT_CUTOFF) of the best
                a = o + j
                b = a + 1 if j + 1 < ms else o
                px[0], px[1] = pts[a, 0], pts[a, 1]
                dx[0], dx[1] = pts[b, 0] - pts[a, 0], pts[b, 1] - pts[a, 1]
                i0, tm, dc2 = _gauss_segment(q0, px, dx, 2, sigma2)
                w[j] = (cum[j + 1] - cum[j]) * exp(-(dc2 - best) / sigma2) * i0
                mid[j] = cum[j] + tm * (cum[j + 1] - cum[j])
                cs += w[j] * np.cos(2.0 * pi * mid[j] / length)
                sn += w[j] * np.sin(2.0 * pi * mid[j] / length)
            if cs != 0.0 or sn != 0.0:
                # the exact weighted mean arc position, unwrapped around the circular mean
                # (continuous, unlike an unwrapping around the hard closest point)
                ref = (np.arctan2(sn, cs) / (2.0 * pi) * length) % length
                wsum = 0.0
                msum = 0.0
                for j in range(ms):
                    if w[j] > 0:
                        wsum += w[j]
                        msum += w[j] * (_mod(mid[j] - ref + 0.5 * length, length)
                                        - 0.5 * length)
                pos = (ref + msum / wsum) % length
        for k in range(n_p):
            if k == 0:
                j, t = bj, bt
                if length > 0:
                    j, t = _arc_segment(cum, ms, pos)
            else:
                # ratio_points: arc a0 + f L, once round at most; the segment found as
                # searchsorted(cum, ., "right") - 1 does
                target = pos + fractions[k - 1] * length
                if target >= length:
                    target -= length
                j = 0
                while j < ms - 1 and cum[j + 1] <= target:
                    j += 1
                span = cum[j + 1] - cum[j]
                t = min(max((target - cum[j]) / span, 0.0), 1.0) if span > 0 else 0.0
            seg[s, k] = j
            tk[s, k] = t
            a = o + j
            b = a + 1 if j + 1 < ms else o
            point[s, k, 0] = pts[a, 0] + t * (pts[b, 0] - pts[a, 0])
            point[s, k, 1] = pts[a, 1] + t * (pts[b, 1] - pts[a, 1])
    return seg, tk, point


def _arc_segment(cum, ms, pos):
    """(segment, tau) of arc position ``pos`` on a contour with cumulated lengths ``cum``:
    a zero-length segment is avoided by stepping back."""
    j = 0
    while j < ms - 1 and cum[j + 1] <= pos:
        j += 1
    while j > 0 and cum[j + 1] - cum[j] <= 0:
        j -= 1
    span = cum[j + 1] - cum[j]
    return j, min(max((pos - cum[j]) / span, 0.0), 1.0) if span > 0 else 0.0


_START_KERNEL = []


def _start_kernel():
    """`_soft_start_loop` (Python; no compiled kernels: docs/decisions.md, issue 13)."""
    return _soft_start_loop  # numpy (no compiled kernels: docs/decisions.md, issue 13)
