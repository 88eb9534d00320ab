"""Compiled loops of `fibres.fitting` (the box fit of Kohout et al., GRAPP 2012, §3.2).

Each is the array version's arithmetic in the same order (see the callers in
`fibres.fitting`, which compile them with numba and fall back to numpy without it).
"""
from __future__ import annotations

import numpy as np

__all__ = []


def _screen_loop(a, b, dirs, cos_all, sin_all, margin_scale,
                 stride):  # pragma: no cover - compiled by numba
    """`_support_candidates` in one call: the array version's polygons, margins and tests
    (hence its indices), directions ``cos_all``, ``sin_all`` of all passes back to back;
    each pass gathers its points contiguously and tests them edge by edge (vectorised)."""
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
        inside = np.ones(m, dtype=np.bool_)
        for k in range(nq):
            kn = k + 1 if k + 1 < nq else 0
            qa, qb = pa[q[k]], pb[q[k]]
            ea, eb = pa[q[kn]] - qa, pb[q[kn]] - qb
            margin = margin_scale * np.hypot(ea, eb)
            for i in range(m):
                inside[i] &= ea * (pb[i] - qb) - eb * (pa[i] - qa) > margin
        keep = np.empty(m, dtype=np.int64)
        n_keep = 0
        for i in range(m):
            keep[n_keep] = idx[i]
            n_keep += not inside[i]
        idx = keep[:n_keep]
    return idx


def _extents_loop(a, b, ct, st, out):  # pragma: no cover - compiled by numba
    """Per rotation j: min and max of ``px = ct a + st b`` and ``py = (-st) a + ct b`` into
    ``out`` (J, 4), with the array version's products and sums (the same bits)."""
    for j in range(ct.size):
        c, s = ct[j], st[j]
        ns = -s
        x_lo = x_hi = c * a[0] + s * b[0]
        y_lo = y_hi = ns * a[0] + c * b[0]
        for i in range(1, a.size):
            px = c * a[i] + s * b[i]
            py = ns * a[i] + c * b[i]
            x_lo = min(x_lo, px)
            x_hi = max(x_hi, px)
            y_lo = min(y_lo, py)
            y_hi = max(y_hi, py)
        out[j, 0] = x_lo
        out[j, 1] = x_hi
        out[j, 2] = y_lo
        out[j, 3] = y_hi


def _nearest_loop(area, landmarks, out):  # pragma: no cover - compiled by numba
    """``out[j, k]``: distance from area point (j, k) (J, Ka, 3) to its closest landmark
    (K, 3), with the operations of the array version (``(dx dx + dy dy) + dz dz``). One
    root per area point: the square root is correctly rounded and non-decreasing, so the
    root of the smallest square is the smallest root, bit for bit."""
    for j in range(area.shape[0]):
        for k in range(area.shape[1]):
            best = np.inf
            for m in range(landmarks.shape[0]):
                dx = area[j, k, 0] - landmarks[m, 0]
                dy = area[j, k, 1] - landmarks[m, 1]
                dz = area[j, k, 2] - landmarks[m, 2]
                best = min(best, dx * dx + dy * dy + dz * dz)
            out[j, k] = np.sqrt(best)


def _mapped_nearest_loop(area, axes, ext, corner, landmarks, out):  # pragma: no cover
    """`_nearest_loop` of the template area (Ka, 3) mapped into each box j without the
    (J, Ka, 3) temporaries: ``p_i = corner[j, i] + ((a0 s_i0 + a2 s_i2) + a1 s_i1)`` with
    ``s_il = axes[j, i, l] ext[j, l]``, the operations and order of `_scores`' array
    version, then the closest-landmark distance ``out[j, k]`` (J, Ka) as `_nearest_loop`."""
    for j in range(axes.shape[0]):
        s00 = axes[j, 0, 0] * ext[j, 0]
        s01 = axes[j, 0, 1] * ext[j, 1]
        s02 = axes[j, 0, 2] * ext[j, 2]
        s10 = axes[j, 1, 0] * ext[j, 0]
        s11 = axes[j, 1, 1] * ext[j, 1]
        s12 = axes[j, 1, 2] * ext[j, 2]
        s20 = axes[j, 2, 0] * ext[j, 0]
        s21 = axes[j, 2, 1] * ext[j, 1]
        s22 = axes[j, 2, 2] * ext[j, 2]
        for k in range(area.shape[0]):
            a0 = area[k, 0]
            a1 = area[k, 1]
            a2 = area[k, 2]
            px = corner[j, 0] + ((a0 * s00 + a2 * s02) + a1 * s01)
            py = corner[j, 1] + ((a0 * s10 + a2 * s12) + a1 * s11)
            pz = corner[j, 2] + ((a0 * s20 + a2 * s22) + a1 * s21)
            best = np.inf
            for m in range(landmarks.shape[0]):
                dx = px - landmarks[m, 0]
                dy = py - landmarks[m, 1]
                dz = pz - landmarks[m, 2]
                best = min(best, dx * dx + dy * dy + dz * dz)
            out[j, k] = np.sqrt(best)


def _centred_loop(v, c):  # pragma: no cover - compiled by numba
    """``v - c`` for (V, 3) vertices (numpy broadcasts a 3-element inner loop, ~5x slower)."""
    out = np.empty(v.shape)
    for i in range(v.shape[0]):
        out[i, 0] = v[i, 0] - c[0]
        out[i, 1] = v[i, 1] - c[1]
        out[i, 2] = v[i, 2] - c[2]
    return out


def _row_sum_loop(v):  # pragma: no cover - compiled by numba
    s0 = v[0, 0]
    s1 = v[0, 1]
    s2 = v[0, 2]
    for k in range(1, v.shape[0]):
        s0 += v[k, 0]
        s1 += v[k, 1]
        s2 += v[k, 2]
    out = np.empty(3)
    out[0] = s0
    out[1] = s1
    out[2] = s2
    return out
