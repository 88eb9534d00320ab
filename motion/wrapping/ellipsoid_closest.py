"""Closest points on an ellipsoid, compiled: OpenSim 4.6's WrapEllipsoid::findClosestPoint and the
hybrid method's "fan", for `motion.wrapping.ellipsoid_line`.

Contract: `closest_point` returns the point of the ellipsoid (a, b, c) (centred, semi-axes along
x, y, z) closest to p, as complex-step numbers (value + i STEP derivative, `motion.wrapping.
cylinder_line`). `_fan_sum` returns the fan's sum of unit vectors from 298 chord samples to
their closest points, with its derivative along the chord ends' directions.

Method: Eberly's Newton iteration on the sixth-degree polynomial of the closest point's
Lagrange parameter (D. Eberly, "Distance from a point to an ellipse, an ellipsoid, or a
hyperellipsoid", Geometric Tools, after Graphics Gems IV), with OpenSim's 2-D special case near
the coordinate planes; read from OpenSim's public source for the facts, an independent
implementation. Derivatives: the Newton steps differentiated as they run (forward mode in real
arithmetic, the same numbers complex arithmetic would give). The fan's samples are solved
side by side in real arithmetic, the derivative recurrence of each solve carried for the three
components of the sample at once (`_fan_sum`); its result is kept in a small memo keyed by its
real inputs (`new_fan_memo`) so that several derivative directions of one row compute it once.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .cylinder_line import STEP, csqrt

__all__ = ["closest_point", "new_fan_memo"]

_ROUNDOFF = 2e-13
_FAN = 300


@njit(cache=True, error_model="numpy")
def _cabs(x):
    return x if x.real >= 0.0 else -x


@njit(cache=True, error_model="numpy")
def _ellipse(a, b, u, v):
    """Eberly's closest point on the ellipse (x/a)^2 + (y/b)^2 = 1 to (u, v); OpenSim's cases."""
    a2, b2 = a * a, b * b
    near_x = abs(u.real) <= _ROUNDOFF
    near_y = abs(v.real) <= _ROUNDOFF
    if near_x and near_y:
        if a < b:
            return complex(-a if u.real < 0.0 else a), v
        return u, complex(-b if v.real < 0.0 else b)
    if near_x:
        if a >= b or abs(v.real) >= b - a2 / b:
            return u, complex(b if v.real >= 0.0 else -b)
        y = v * b2 / (b2 - a2)
        return csqrt(_cabs(1.0 - (y / b) * (y / b))) * a, y
    if near_y:
        if b >= a or abs(u.real) >= a - b2 / a:
            return complex(a if u.real >= 0.0 else -a), v
        x = u * a2 / (a2 - b2)
        return x, csqrt(_cabs(1.0 - (x / a) * (x / a))) * b
    a2u2, b2v2 = u * u * a2, v * v * b2
    inside = (u.real / a) ** 2 + (v.real / b) ** 2 < 1.0
    t = 0j if inside else csqrt(u * u + v * v) * max(a, b)
    p, q = t + a2, t + b2
    for _ in range(64):
        p, q = t + a2, t + b2
        f = p * p * q * q - a2u2 * q * q - b2v2 * p * p
        if abs(f.real) < 1e-9:
            break
        fp = (p * q * (p + q) - a2u2 * q - b2v2 * p) * 2.0
        t = t - f / fp
    return u * a2 / p, v * b2 / q


@njit(cache=True, error_model="numpy")
def closest_point(a, b, c, p, special, ta, tb, tc):
    """OpenSim WrapEllipsoid::findClosestPoint: the point of the ellipsoid (a, b, c) closest to p.

    ``special`` 0, 1, 2 forces the 2-D reduction about that axis (the axial technique); -1
    detects points on coordinate planes as OpenSim does, ties broken with dimensions
    ``(ta, tb, tc)`` (OpenSim uses the unscaled dimensions for the fan samples).
    """
    u, v, w = p
    if special < 0:
        best = np.inf
        s_sum = ta + tb + tc
        if abs(u.real) <= _ROUNDOFF and best > s_sum - ta:
            special, best = 0, s_sum - ta
        if abs(v.real) <= _ROUNDOFF and best > s_sum - tb:
            special, best = 1, s_sum - tb
        if abs(w.real) <= _ROUNDOFF and best > s_sum - tc:
            special, best = 2, s_sum - tc
    if special == 0:
        y, z = _ellipse(b, c, v, w)
        return (u, y, z)
    if special == 1:
        z, x = _ellipse(c, a, w, u)
        return (x, v, z)
    if special == 2:
        x, y = _ellipse(a, b, u, v)
        return (x, y, w)
    # Newton on Eberly's polynomial in real arithmetic, its derivative carried alongside (forward
    # mode, the same numbers as complex arithmetic would give, at about half the cost)
    a2, b2, c2 = a * a, b * b, c * c
    ur, vr, wr = u.real, v.real, w.real
    ca, cb, cc = a2 * ur * ur, b2 * vr * vr, c2 * wr * wr
    da, db, dc = 2.0 * a2 * ur * u.imag, 2.0 * b2 * vr * v.imag, 2.0 * c2 * wr * w.imag
    if (ur / a) ** 2 + (vr / b) ** 2 + (wr / c) ** 2 < 1.0:
        t, dt = 0.0, 0.0
    else:
        n = math.sqrt(ur * ur + vr * vr + wr * wr)
        m = max(a, max(b, c))
        t, dt = n * m, m * (ur * u.imag + vr * v.imag + wr * w.imag) / n
    for _ in range(64):
        p_, q_, r_ = t + a2, t + b2, t + c2
        p2, q2, r2 = p_ * p_, q_ * q_, r_ * r_
        f = p2 * q2 * r2 - ca * q2 * r2 - cb * p2 * r2 - cc * p2 * q2
        if abs(f) < 1e-9:
            break
        dp2, dq2, dr2 = 2.0 * p_ * dt, 2.0 * q_ * dt, 2.0 * r_ * dt
        df = (dp2 * q2 * r2 + p2 * dq2 * r2 + p2 * q2 * dr2 - da * q2 * r2 - ca * (dq2 * r2 + q2 * dr2)
              - db * p2 * r2 - cb * (dp2 * r2 + p2 * dr2) - dc * p2 * q2 - cc * (dp2 * q2 + p2 * dq2))
        pq, pr, qr = p_ * q_, p_ * r_, q_ * r_
        s1, s2 = pq * r_, qr + pr + pq
        ga, gb, gc = qr * (q_ + r_), pr * (p_ + r_), pq * (p_ + q_)
        fp = (s1 * s2 - ca * ga - cb * gb - cc * gc) * 2.0
        dfp = (dt * (s2 * s2 + s1 * 2.0 * (p_ + q_ + r_)) - da * ga - ca * dt * (q2 + 4.0 * qr + r2)
               - db * gb - cb * dt * (p2 + 4.0 * pr + r2) - dc * gc - cc * dt * (p2 + 4.0 * pq + q2)) * 2.0
        t, dt = t - f / fp, dt - (df * fp - f * dfp) / (fp * fp)
    tc = complex(t, dt)
    return (u * a2 / (tc + a2), v * b2 / (tc + b2), w * c2 / (tc + c2))


@njit(cache=True, error_model="numpy")
def _fan_sum(i1, r1r2, ax, dims, memo, memo_n):
    """The fan's sum of unit "blades" from the chord samples ``i1 + r1r2 k / 300`` (k = 1..298) to
    their closest ellipsoid points, with its derivative along the direction ``i1``, ``r1r2`` carry.

    Values: the real steps of `closest_point` (the same Newton iterates). Derivative: the sample
    is affine in (i1, r1r2), so the sum's derivative is ``A di1 + B dr1r2`` with the 3 x 3 sums
    ``A = sum_k M_k``, ``B = sum_k (k / 300) M_k`` of the blade Jacobians
    ``M_k = (I - b b^T) / |x - s| (dx/ds - I)``; dx/ds is the derivative of the Newton iteration
    carried for the three components of s at once (its linear recurrence, as `closest_point`'s
    forward mode). Samples on a coordinate plane take `closest_point`'s 2-D case, three
    complex-step calls for their Jacobian.

    ``memo`` (K, 30), ``memo_n`` (1,): a ring of past results, keyed by the real parts of i1,
    r1r2 and the dimensions (the sum and A, B depend on nothing else), so that the derivative
    directions of one row (each a run of the same values) compute the fan once (`new_fan_memo`).
    """
    i1r = (i1[0].real, i1[1].real, i1[2].real)
    dr = (r1r2[0].real, r1r2[1].real, r1r2[2].real)
    di = (i1[0].imag, i1[1].imag, i1[2].imag)
    dd = (r1r2[0].imag, r1r2[1].imag, r1r2[2].imag)
    key = (i1r[0], i1r[1], i1r[2], dr[0], dr[1], dr[2], dims[0], dims[1], dims[2])
    for e in range(min(memo_n[0], memo.shape[0])):
        hit = True
        for i in range(9):
            if memo[e, i] != key[i]:
                hit = False
                break
        if hit:
            return _fan_out(memo[e], di, dd)
    a, b, c = ax
    a2, b2, c2 = a * a, b * b, c * c
    m = max(a, max(b, c))
    n_s = _FAN - 2
    # the samples' Newton solves in lockstep (a converged sample is frozen, as closest_point's
    # loop stops there): the same iterates, in branch-free loops over samples
    su, sv, sw = np.empty(n_s), np.empty(n_s), np.empty(n_s)
    t, g0, g1, g2 = np.zeros(n_s), np.zeros(n_s), np.zeros(n_s), np.zeros(n_s)
    done = np.zeros(n_s, dtype=np.bool_)
    for k in range(n_s):
        tk = (k + 1) / _FAN
        ur, vr, wr = i1r[0] + dr[0] * tk, i1r[1] + dr[1] * tk, i1r[2] + dr[2] * tk
        su[k], sv[k], sw[k] = ur, vr, wr
        if abs(ur) <= _ROUNDOFF or abs(vr) <= _ROUNDOFF or abs(wr) <= _ROUNDOFF:
            done[k] = True                # 2-D special case, below
        elif not (ur / a) ** 2 + (vr / b) ** 2 + (wr / c) ** 2 < 1.0:
            n = math.sqrt(ur * ur + vr * vr + wr * wr)
            t[k] = n * m
            g0[k], g1[k], g2[k] = m * ur / n, m * vr / n, m * wr / n
    special = done.copy()
    for _ in range(64):
        left = 0
        for k in range(n_s):
            ur, vr, wr, tt = su[k], sv[k], sw[k], t[k]
            ca, cb, cc = a2 * ur * ur, b2 * vr * vr, c2 * wr * wr
            p_, q_, r_ = tt + a2, tt + b2, tt + c2
            p2, q2, r2 = p_ * p_, q_ * q_, r_ * r_
            f = p2 * q2 * r2 - ca * q2 * r2 - cb * p2 * r2 - cc * p2 * q2
            stop = done[k] | (abs(f) < 1e-9)
            pq, pr, qr = p_ * q_, p_ * r_, q_ * r_
            s1, s2 = pq * r_, qr + pr + pq
            ga, gb, gc = qr * (q_ + r_), pr * (p_ + r_), pq * (p_ + q_)
            fp = (s1 * s2 - ca * ga - cb * gb - cc * gc) * 2.0
            fpp = ((s2 * s2 + s1 * 2.0 * (p_ + q_ + r_)) - ca * (q2 + 4.0 * qr + r2)
                   - cb * (p2 + 4.0 * pr + r2) - cc * (p2 + 4.0 * pq + q2)) * 2.0
            # d t_new = d t (f fpp / fp^2) - sum_i dc_i (f_ci fp - f fp_ci) / fp^2, where
            # c_i = a_i^2 s_i^2, f_ci = -(product of the other two squares), fp_ci = -2 g_i
            inv = 1.0 / (fp * fp)
            keep = f * fpp * inv
            h0 = (-q2 * r2 * fp + f * 2.0 * ga) * inv * (2.0 * a2 * ur)
            h1 = (-p2 * r2 * fp + f * 2.0 * gb) * inv * (2.0 * b2 * vr)
            h2 = (-p2 * q2 * fp + f * 2.0 * gc) * inv * (2.0 * c2 * wr)
            g0[k] = g0[k] if stop else g0[k] * keep - h0
            g1[k] = g1[k] if stop else g1[k] * keep - h1
            g2[k] = g2[k] if stop else g2[k] * keep - h2
            t[k] = tt if stop else tt - f / fp
            done[k] = stop
            left += 0 if stop else 1
        if left == 0:
            break
    bs = np.zeros(3)
    mat_a = np.zeros((3, 3))
    mat_b = np.zeros((3, 3))
    jac = np.empty((3, 3))
    x = np.empty(3)
    for k in range(n_s):
        tk = (k + 1) / _FAN
        sk = (su[k], sv[k], sw[k])
        if special[k]:                   # Jacobian column by column (complex steps)
            for j in range(3):
                e = (complex(sk[0], STEP if j == 0 else 0.0), complex(sk[1], STEP if j == 1 else 0.0),
                     complex(sk[2], STEP if j == 2 else 0.0))
                close = closest_point(a, b, c, e, -1, dims[0], dims[1], dims[2])
                for i in range(3):
                    x[i] = close[i].real
                    jac[i, j] = close[i].imag / STEP
            v0, v1, v2 = x[0] - sk[0], x[1] - sk[1], x[2] - sk[2]
            nv = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
            if not nv > 0.0:
                continue                 # a zero blade (vunit's zero vector), no derivative
            bl = (v0 / nv, v1 / nv, v2 / nv)
            for i in range(3):           # M = (I - b b^T) (J - I) / |v|
                bs[i] += bl[i]
                for j in range(3):
                    mij = 0.0
                    for l in range(3):
                        mij += ((1.0 if i == l else 0.0) - bl[i] * bl[l]) * (jac[l, j] - (1.0 if l == j else 0.0))
                    mat_a[i, j] += mij / nv
                    mat_b[i, j] += tk * (mij / nv)
            continue
        # general case: J = diag(a_i^2 / d_i) - y g^T (d_i = t + a_i^2, y_i = x_i / d_i), so
        # M = (I - b b^T)(J - I) / |v| = (diag(e) - b (b * e)^T) / |v| + z g^T with
        # e_i = a_i^2 / d_i - 1, z = (b (b . y) - y) / |v|
        d0, d1, d2 = t[k] + a2, t[k] + b2, t[k] + c2
        x0, x1, x2 = sk[0] * a2 / d0, sk[1] * b2 / d1, sk[2] * c2 / d2
        v0, v1, v2 = x0 - sk[0], x1 - sk[1], x2 - sk[2]
        nv = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if not nv > 0.0:
            continue
        b0, b1, b2_ = v0 / nv, v1 / nv, v2 / nv
        bs[0] += b0
        bs[1] += b1
        bs[2] += b2_
        y0, y1, y2 = x0 / d0, x1 / d1, x2 / d2
        e0, e1, e2 = (a2 / d0 - 1.0) / nv, (b2 / d1 - 1.0) / nv, (c2 / d2 - 1.0) / nv
        by = b0 * y0 + b1 * y1 + b2_ * y2
        z0, z1, z2 = (b0 * by - y0) / nv, (b1 * by - y1) / nv, (b2_ * by - y2) / nv
        be0, be1, be2 = b0 * e0, b1 * e1, b2_ * e2
        h0, h1, h2 = g0[k], g1[k], g2[k]
        m00, m01, m02 = e0 - b0 * be0 + z0 * h0, -b0 * be1 + z0 * h1, -b0 * be2 + z0 * h2
        m10, m11, m12 = -b1 * be0 + z1 * h0, e1 - b1 * be1 + z1 * h1, -b1 * be2 + z1 * h2
        m20, m21, m22 = -b2_ * be0 + z2 * h0, -b2_ * be1 + z2 * h1, e2 - b2_ * be2 + z2 * h2
        mat_a[0, 0] += m00
        mat_a[0, 1] += m01
        mat_a[0, 2] += m02
        mat_a[1, 0] += m10
        mat_a[1, 1] += m11
        mat_a[1, 2] += m12
        mat_a[2, 0] += m20
        mat_a[2, 1] += m21
        mat_a[2, 2] += m22
        mat_b[0, 0] += tk * m00
        mat_b[0, 1] += tk * m01
        mat_b[0, 2] += tk * m02
        mat_b[1, 0] += tk * m10
        mat_b[1, 1] += tk * m11
        mat_b[1, 2] += tk * m12
        mat_b[2, 0] += tk * m20
        mat_b[2, 1] += tk * m21
        mat_b[2, 2] += tk * m22
    e = memo_n[0] % memo.shape[0]
    memo_n[0] += 1
    for i in range(9):
        memo[e, i] = key[i]
    for i in range(3):
        memo[e, 9 + i] = bs[i]
        for j in range(3):
            memo[e, 12 + 3 * i + j] = mat_a[i, j]
            memo[e, 21 + 3 * i + j] = mat_b[i, j]
    return _fan_out(memo[e], di, dd)


@njit(cache=True, error_model="numpy")
def _fan_out(entry, di, dd):
    """The fan sum of a memo entry (key, sum, A, B) as complex-step numbers: the sum, and
    ``A di + B dd`` as derivative."""
    out = [0j, 0j, 0j]
    for i in range(3):
        im = 0.0
        for j in range(3):
            im += entry[12 + 3 * i + j] * di[j] + entry[21 + 3 * i + j] * dd[j]
        out[i] = complex(entry[9 + i], im)
    return (out[0], out[1], out[2])


def new_fan_memo(size: int = 8) -> tuple:
    """An empty fan memo for `ellipsoid_line`: ((size, 30) float, (1,) int)."""
    return np.full((size, 30), np.nan), np.zeros(1, dtype=np.int64)
