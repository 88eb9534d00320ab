"""Compiled loops of `fibres.fitting` (the box fit of Kohout et al., GRAPP 2012, §3.2) and
of the cross-section reference in `fibres.decompose`.

Each is the array version's arithmetic in the same order (see the callers, which compile
them with numba, `fibres.fitting._fit_kernels`, and fall back to numpy without it), except
`_moment_loop`, an ordered sum whose sign is used only where rounding cannot change it. The
support screen's loops are in `fibres.support_screen`.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = []


class _Kernels(NamedTuple):
    """The compiled loops (`fibres.fit_kernels`, `fibres.support_screen`)."""

    screen: object            # polygon screen
    extents: object           # box extents
    nearest: object           # nearest landmark distances
    centred: object           # vertices - centroid
    row_sum: object           # row sums
    mapped_nearest: object    # template areas mapped into the boxes, nearest distances
    boxes: object             # the boxes
    projected_boxes: object   # the boxes of given (BLAS) projections
    candidates: object        # support candidates
    section: object           # cross-section reference: perpendicular spread
    combine: object           # cross-section reference: rows combined
    transposed_mean: object   # transposed vertices, centroid, bounds
    moment: object            # cross-section reference: the sign moment and its bound


def _extents_loop(a, b, ct, st, out):  # pragma: no cover - compiled by numba
    """Per rotation j: min and max of ``px = ct a + st b`` and ``py = (-st) a + ct b`` into
    ``out`` (J, 4), with the array version's products and sums (the same bits). The
    rotations are the inner loop (independent running minima and maxima, which the
    compiler vectorises; a reduction over the points is not, without fastmath), each
    rotation still visits the points in order: the same values, also for signed zeros."""
    n = ct.size
    lim = np.empty((4, n))                  # min px, max px, min py, max py per rotation
    nst = np.empty(n)
    for j in range(n):
        nst[j] = -st[j]
        lim[0, j] = lim[1, j] = ct[j] * a[0] + st[j] * b[0]
        lim[2, j] = lim[3, j] = nst[j] * a[0] + ct[j] * b[0]
    x_lo, x_hi, y_lo, y_hi = lim[0], lim[1], lim[2], lim[3]
    for i in range(1, a.size):
        ai = a[i]
        bi = b[i]
        for j in range(n):
            px = ct[j] * ai + st[j] * bi
            py = nst[j] * ai + ct[j] * bi
            x_lo[j] = min(x_lo[j], px)
            x_hi[j] = max(x_hi[j], px)
            y_lo[j] = min(y_lo[j], py)
            y_hi[j] = max(y_hi[j], py)
    for j in range(n):
        out[j, 0] = x_lo[j]
        out[j, 1] = x_hi[j]
        out[j, 2] = y_lo[j]
        out[j, 3] = y_hi[j]


def _boxes_loop(v, c, u, v0, w0, ct, st, dirs, cos_all, sin_all, stride, n_bins, axes,
                corner, ext):  # pragma: no cover - compiled by numba
    """`fibres.fitting._boxes` in one call, the array version's operations in its order:
    the projections ``a, b, z`` of the centred vertices ``d = v - c`` (V, 3) on v0, w0, u
    (``(d_x v_x + d_y v_y) + d_z v_z``; z only for its minimum and maximum), the support
    screen (`fibres.support_screen._candidates_loop`), the extents (`_extents_loop`) of
    the candidates and the boxes ``axes`` (J, 3, 3), ``corner`` (J, 3), ``ext`` (J, 3) of
    the rotations ``ct, st`` (J,): ``x = ct v0 + st w0``, ``y = u x x``
    (`fibres.fitting.cross3`), ``corner = c + (x lo_x + u lo_z) + y lo_y`` (numpy's einsum
    adds the three products in this order). The candidates may differ from the array
    version's screen (both keep every point that attains a minimum or maximum), the boxes
    are the same bit for bit."""
    n = v.shape[0]
    a = np.empty(n)
    b = np.empty(n)
    c0, c1, c2 = c[0], c[1], c[2]
    a0, a1, a2 = v0[0], v0[1], v0[2]
    b0, b1, b2 = w0[0], w0[1], w0[2]
    u0, u1, u2 = u[0], u[1], u[2]
    z_lo = z_hi = (v[0, 0] - c0) * u0 + (v[0, 1] - c1) * u1 + (v[0, 2] - c2) * u2
    for i in range(n):
        d0 = v[i, 0] - c0
        d1 = v[i, 1] - c1
        d2 = v[i, 2] - c2
        a[i] = d0 * a0 + d1 * a1 + d2 * a2
        b[i] = d0 * b0 + d1 * b1 + d2 * b2
        z = d0 * u0 + d1 * u1 + d2 * u2
        z_lo = z if z < z_lo else z_lo
        z_hi = z if z > z_hi else z_hi
    _projected_boxes_loop(a, b, z_lo, z_hi, c, u, v0, w0, ct, st, dirs, cos_all, sin_all,
                          stride, n_bins, axes, corner, ext)


def _projected_boxes_loop(a, b, z_lo, z_hi, c, u, v0, w0, ct, st, dirs, cos_all, sin_all,
                          stride, n_bins, axes, corner,
                          ext):  # pragma: no cover - compiled by numba
    """`_boxes_loop` after the projections: a, b (V,), the range ``z_lo, z_hi`` of z."""
    keep = _candidates_loop(a, b, dirs, cos_all, sin_all, stride, n_bins)
    m = keep.size
    pa = np.empty(m)
    pb = np.empty(m)
    for i in range(m):
        pa[i] = a[keep[i]]
        pb[i] = b[keep[i]]
    xy = np.empty((ct.size, 4))
    _extents_loop(pa, pb, ct, st, xy)
    for j in range(ct.size):
        x0 = ct[j] * v0[0] + st[j] * w0[0]
        x1 = ct[j] * v0[1] + st[j] * w0[1]
        x2 = ct[j] * v0[2] + st[j] * w0[2]
        y0 = u[1] * x2 - u[2] * x1
        y1 = u[2] * x0 - u[0] * x2
        y2 = u[0] * x1 - u[1] * x0
        lx, ly = xy[j, 0], xy[j, 2]
        axes[j, 0, 0], axes[j, 0, 1], axes[j, 0, 2] = x0, y0, u[0]
        axes[j, 1, 0], axes[j, 1, 1], axes[j, 1, 2] = x1, y1, u[1]
        axes[j, 2, 0], axes[j, 2, 1], axes[j, 2, 2] = x2, y2, u[2]
        corner[j, 0] = c[0] + ((x0 * lx + u[0] * z_lo) + y0 * ly)
        corner[j, 1] = c[1] + ((x1 * lx + u[1] * z_lo) + y1 * ly)
        corner[j, 2] = c[2] + ((x2 * lx + u[2] * z_lo) + y2 * ly)
        ext[j, 0] = xy[j, 1] - lx
        ext[j, 1] = xy[j, 3] - ly
        ext[j, 2] = z_hi - z_lo


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


def _section_loop(vt, c, u):  # pragma: no cover - compiled by numba
    """``dt = vt - c`` (3, V) with its component along u removed, ``dt_r - u_r ((u0 dt0 +
    u1 dt1) + u2 dt2)``: `fibres.decompose`'s cross-section reference, the array
    version's operations, in one pass."""
    n = vt.shape[1]
    dt = np.empty((3, n))
    c0, c1, c2 = c[0], c[1], c[2]
    u0, u1, u2 = u[0], u[1], u[2]
    for i in range(n):
        d0 = vt[0, i] - c0
        d1 = vt[1, i] - c1
        d2 = vt[2, i] - c2
        along = u0 * d0 + u1 * d1 + u2 * d2
        dt[0, i] = d0 - u0 * along
        dt[1, i] = d1 - u1 * along
        dt[2, i] = d2 - u2 * along
    return dt


def _moment_loop(dt, r):  # pragma: no cover - compiled by numba
    """``S = sum_i (i + 1) x_i`` added in order and ``A = sum_i |(i + 1) x_i|`` of the
    rows combined as `_combine_loop`, ``x = (r0 dt0 + r1 dt1) + r2 dt2`` (not stored)."""
    r0, r1, r2 = r[0], r[1], r[2]
    s = 0.0
    a = 0.0
    for i in range(dt.shape[1]):
        t = (i + 1.0) * (r0 * dt[0, i] + r1 * dt[1, i] + r2 * dt[2, i])
        s += t
        a += abs(t)
    return s, a


def _combine_loop(dt, r):  # pragma: no cover - compiled by numba
    """``(r0 dt0 + r1 dt1) + r2 dt2`` (V,) of (3, V) rows, as numpy adds them."""
    n = dt.shape[1]
    out = np.empty(n)
    r0, r1, r2 = r[0], r[1], r[2]
    for i in range(n):
        out[i] = r0 * dt[0, i] + r1 * dt[1, i] + r2 * dt[2, i]
    return out



def _blas_boxes_loop(a, b, z, c, u, v0, w0, ct, st, dirs, cos_all, sin_all, stride, n_bins,
                     axes, corner, ext):  # pragma: no cover - compiled by numba
    """`_projected_boxes_loop` of given projections a, b, z (V,) (numpy's ``d @ v0`` ...)."""
    z_lo = z_hi = z[0]
    for i in range(1, z.size):
        z_lo = min(z_lo, z[i])
        z_hi = max(z_hi, z[i])
    _projected_boxes_loop(a, b, z_lo, z_hi, c, u, v0, w0, ct, st, dirs, cos_all, sin_all,
                          stride, n_bins, axes, corner, ext)


def _transposed_mean_loop(v):  # pragma: no cover - compiled by numba
    """The transposed copy (3, V) of C-contiguous (V, 3) vertices, V >= 1, their centroid
    (3,) (`_row_sum_loop` / V: the same sums) and coordinate-wise minimum and maximum
    (3,) each, in one pass."""
    n = v.shape[0]
    vt = np.empty((3, n))
    s0 = lo0 = hi0 = v[0, 0]
    s1 = lo1 = hi1 = v[0, 1]
    s2 = lo2 = hi2 = v[0, 2]
    vt[0, 0] = s0
    vt[1, 0] = s1
    vt[2, 0] = s2
    for i in range(1, n):
        x = v[i, 0]
        y = v[i, 1]
        z = v[i, 2]
        s0 += x
        s1 += y
        s2 += z
        vt[0, i] = x
        vt[1, i] = y
        vt[2, i] = z
        lo0 = x if x < lo0 else lo0
        lo1 = y if y < lo1 else lo1
        lo2 = z if z < lo2 else lo2
        hi0 = x if x > hi0 else hi0
        hi1 = y if y > hi1 else hi1
        hi2 = z if z > hi2 else hi2
    c = np.empty(3)
    c[0] = s0 / n
    c[1] = s1 / n
    c[2] = s2 / n
    return vt, c, np.array([lo0, lo1, lo2]), np.array([hi0, hi1, hi2])
