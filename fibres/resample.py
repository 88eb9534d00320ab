"""Compiled loops of the attachment filter's resampling record (`fibres.filtering`).

`fibres.filtering._record_resampling` finds, for every point of the uniform arc-length
resampling of each cut fibre's poly-line [new end, cut, kept points, cut, new end] (Kohout
et al., GRAPP 2012, §3.4), the piece it falls on and its parameter there. `resampling_loop`
does the same element-wise arithmetic in the same order as the array version, one fibre at a
time (no (M, P, Q) comparison table), so the two agree bit for bit (tests/fibres/test_filtering.py).
`evaluate_loop` is `fibres.filtering._evaluate`'s point placement from those records.
"""
from __future__ import annotations

import numpy as np

__all__ = ["resampling_kernel", "evaluate_kernel"]

_KERNEL = []


def _compiled():
    """(resampling_loop, evaluate_loop) compiled with numba, or None."""
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)


def resampling_kernel():
    """`resampling_loop` compiled with numba, or None (then the array version)."""
    kernels = _compiled()
    return None if kernels is None else kernels[0]


def evaluate_kernel():
    """`evaluate_loop` compiled with numba, or None (then the array version)."""
    kernels = _compiled()
    return None if kernels is None else kernels[1]


def resampling_loop(fib, tau_o, tau_i, c_o, c_i, end_o, end_i, lin):  # pragma: no cover
    """Piece (M, P) int8 and parameter (M, P) of the resampled points of M fibres (M, P, 3)
    whose kept part runs between fractional indices tau_o and tau_i (cut points c_o, c_i,
    new ends end_o, end_i; lin = linspace(0, 1, P)): `fibres.filtering._record_resampling`."""
    m, p = fib.shape[0], fib.shape[1]
    q = p + 4
    piece = np.empty((m, p), np.int8)
    param = np.empty((m, p))
    poly = np.empty((q, 3))
    tau = np.empty(q)
    cum = np.empty(q)
    for r in range(m):
        to, ti = tau_o[r], tau_i[r]
        for c in range(3):
            poly[0, c], poly[1, c] = end_o[r, c], c_o[r, c]
            poly[q - 2, c], poly[q - 1, c] = c_i[r, c], end_i[r, c]
        tau[0], tau[1], tau[q - 2], tau[q - 1] = to, to, ti, ti
        for j in range(p):  # the kept points, clamped to the cuts (np.clip: min(max))
            bt = min(max(float(j), to), ti)
            tau[2 + j] = bt
            if bt == j:
                for c in range(3):
                    poly[2 + j, c] = fib[r, j, c]
            else:  # `_at_index`: linear along the poly-line
                i0 = min(max(int(np.floor(bt)), 0), p - 2)
                f = bt - i0
                for c in range(3):
                    a = fib[r, i0, c]
                    poly[2 + j, c] = a + f * (fib[r, i0 + 1, c] - a)
        cum[0] = 0.0
        for k in range(q - 1):
            dx = poly[k + 1, 0] - poly[k, 0]
            dy = poly[k + 1, 1] - poly[k, 1]
            dz = poly[k + 1, 2] - poly[k, 2]
            cum[k + 1] = cum[k] + np.sqrt(dx * dx + dy * dy + dz * dz)
        total = cum[q - 1]
        for j in range(p):
            t = total * lin[j]
            n_le = 0
            for k in range(1, q):
                if cum[k] <= t:
                    n_le += 1
            k = min(max(n_le, 0), q - 2)
            c0, c1 = cum[k], cum[k + 1]
            frac = (t - c0) / (c1 - c0) if c1 > c0 else 0.0
            pc = 0 if k == 0 else (2 if k == q - 2 else 1)
            if pc == 1:
                tk = tau[k] + frac * (tau[k + 1] - tau[k])
                param[r, j] = (tk - to) / (ti - to)
            else:
                param[r, j] = frac
            piece[r, j] = pc
        piece[r, 0], param[r, 0] = 0, 0.0
        piece[r, p - 1], param[r, p - 1] = 2, 1.0
    return piece, param


def evaluate_loop(fib, tau_o, tau_i, c_o, c_i, end_o, end_i, piece, param):  # pragma: no cover
    """Output points (M, P, 3) from recorded pieces and parameters (M, P):
    `fibres.filtering._evaluate` after its `_geometry`, point by point."""
    m, p = fib.shape[0], fib.shape[1]
    out = np.empty((m, p, 3))
    for r in range(m):
        for j in range(p):
            lam = param[r, j]
            pc = piece[r, j]
            if pc == 0:
                for c in range(3):
                    out[r, j, c] = end_o[r, c] + lam * (c_o[r, c] - end_o[r, c])
            elif pc == 2:
                for c in range(3):
                    out[r, j, c] = c_i[r, c] + lam * (end_i[r, c] - c_i[r, c])
            else:  # `_at_index` at tau_o + lam (tau_i - tau_o)
                tau = tau_o[r] + lam * (tau_i[r] - tau_o[r])
                i0 = min(max(int(np.floor(tau)), 0), p - 2)
                f = tau - i0
                for c in range(3):
                    a = fib[r, i0, c]
                    out[r, j, c] = a + f * (fib[r, i0 + 1, c] - a)
    return out
