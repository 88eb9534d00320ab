"""One straight segment over one WrapEllipsoid, compiled: OpenSim 4.6's WrapEllipsoid::wrapLine.

Contract: `ellipsoid_line` returns, for one segment p1 -> p2 in the ellipsoid's frame (centred,
semi-axes along x, y, z), OpenSim's WrapAction code, the tangent points r1, r2 and the arc
length between them, values and derivatives (complex-step numbers, `motion.wrapping.
cylinder_line`). ``tests/motion/wrap_oracle/ellipsoid.py`` is a numpy implementation of the same
steps; ``tests/motion/test_compiled_wraps.py`` compares the two.

Method (Peter Loan's WrapEllipsoid, Frans van der Helm's technique, from SIMM; read from
OpenSim's public source for the facts, an independent implementation):

1. All coordinates are scaled by ``3 / (a + b + c)``. No wrap if an end point is inside the
   ellipsoid (``insideRadius``), if p1 and p2 are seen in the same direction from the centre,
   or if the straight *segment* does not pass through the ellipsoid; otherwise the wrap is a
   ``mandatoryWrap``.
2. The wrapping plane holds p1, p2 and a surface point c1 found from the chord r1 r2 (the
   segment's intersections with the ellipsoid): ``axial`` (c1 = closest surface point to where
   the chord crosses the plane normal to the axis most parallel to it), ``midpoint`` (closest
   point to the chord's midpoint) or ``hybrid`` (the default: the axial technique faded into the
   "fan" -- the mean direction from 298 chord samples to their closest surface points --
   between ``|cos| = 0.7073`` and ``0.9``). Closest points: Eberly's Newton iteration (Graphics
   Gems IV) with OpenSim's 2-D special case near the coordinate planes.
3. With a quadrant, c1 is mirrored to the active side (fan solutions pulled towards the
   bisecting plane; a pure axial solution is never pulled, OpenSim's quirk).
4. The tangent points start at c1 and move in the plane by OpenSim's damped Gauss-Newton
   iteration (calcTangentPoint, stopping at a squared residual of 1e-8).
5. The arc is the polyline of ``int(|r1 r2| / 1 mm)`` pieces (at most 499) got by turning in the
   plane about a point of it on the axis most normal to the plane and projecting onto the
   ellipsoid; a quadrant-constrained arc that starts the wrong way is redone the far way.

Every branch tests real parts; the derivative is the exact derivative of this iterative,
piecewise smooth function (the Gauss-Newton steps and the Newton steps are differentiated as
they run).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .cylinder_line import INSIDE_RADIUS, MANDATORY_WRAP, NO_WRAP, STEP, csqrt, vadd, vcross, vdot, vnorm, vscale, vsub, vunit

__all__ = ["ellipsoid_line", "closest_point", "new_fan_memo"]

_ROUNDOFF = 2e-13
_TINY = 1e-8
_MU_MIN = 0.7073
_MU_MAX = 0.9
_FAN = 300
_SV_BLEND = 0.3
_Z3 = (0j, 0j, 0j)
_NAN3 = (complex(np.nan, 0.0), complex(np.nan, 0.0), complex(np.nan, 0.0))


@njit(cache=True, error_model="numpy")
def _cabs(x):
    return x if x.real >= 0.0 else -x


@njit(cache=True, error_model="numpy")
def _cdiv(a, b):
    """a / b; a zero divisor gives what numpy gives (inf or nan, no derivative)."""
    if b.real == 0.0 and b.imag == 0.0:
        return complex(a.real / 0.0 if a.real != 0.0 else np.nan, 0.0)
    return a / b


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
    sq = (a2, b2, c2)
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


@njit(cache=True, error_model="numpy")
def _closest(ax, p):
    return closest_point(ax[0], ax[1], ax[2], p, -1, ax[0], ax[1], ax[2])


@njit(cache=True, error_model="numpy")
def _residuals(r1, d1, p1, ax, vs, vs4, ee):
    """calcTangentPoint's four residuals into ``ee``; their sum of squares (values)."""
    ee[0] = vdot(vs, r1) + vs4
    ee[1] = (r1[0] / ax[0]) ** 2 + (r1[1] / ax[1]) ** 2 + (r1[2] / ax[2]) ** 2 - 1.0
    e2 = d1
    e3 = d1
    for i in range(3):
        n = r1[i] * (2.0 / (ax[i] * ax[i]))
        e2 += n * r1[i]
        e3 += n * p1[i]
    ee[2] = e2
    ee[3] = e3
    return ee[0].real ** 2 + ee[1].real ** 2 + ee[2].real ** 2 + ee[3].real ** 2


@njit(cache=True, error_model="numpy")
def _solve4(m, rhs, out):
    """Gaussian elimination with partial pivoting (by real parts) of a 4 x 4 complex system."""
    a = m.copy()
    b = rhs.copy()
    for k in range(4):
        piv = k
        for i in range(k + 1, 4):
            if abs(a[i, k].real) > abs(a[piv, k].real):
                piv = i
        if piv != k:
            for j in range(4):
                a[k, j], a[piv, j] = a[piv, j], a[k, j]
            b[k], b[piv] = b[piv], b[k]
        for i in range(k + 1, 4):
            f = a[i, k] / a[k, k]
            for j in range(k, 4):
                a[i, j] -= f * a[k, j]
            b[i] -= f * b[k]
    for i in range(3, -1, -1):
        s = b[i]
        for j in range(i + 1, 4):
            s -= a[i, j] * out[j]
        out[i] = s / a[i, i]


@njit(cache=True, error_model="numpy")
def _tangent_point(pe, r1, p1, ax, vs, vs4):
    """OpenSim WrapEllipsoid::calcTangentPoint (damped Gauss-Newton) from r1; the tangent point."""
    if abs(pe.real) < 1e-4:
        return p1
    d1 = 0j
    for i in range(3):
        d1 -= r1[i] * (2.0 / (ax[i] * ax[i])) * r1[i]
    ee = np.empty(4, dtype=np.complex128)
    ssq = _residuals(r1, d1, p1, ax, vs, vs4, ee)
    ssqo = ssq
    alpha = 0.01
    p1n, _ = vunit(p1)
    dedth = np.zeros((4, 4), dtype=np.complex128)
    dedth2 = np.empty((4, 4), dtype=np.complex128)
    damp = np.empty((4, 4), dtype=np.complex128)
    v = np.empty(4, dtype=np.complex128)
    vt = np.zeros(4, dtype=np.complex128)
    step = np.empty(4, dtype=np.complex128)
    scratch = np.empty(4, dtype=np.complex128)
    nit = 0
    while ssq > _TINY and nit < 50:
        nit += 1
        for i in range(3):
            s = 2.0 / (ax[i] * ax[i])
            dedth[i, 0] = vs[i]
            dedth[i, 1] = r1[i] * s
            dedth[i, 2] = r1[i] * (2.0 * s)
            dedth[i, 3] = p1[i] * s
        dedth[3, 0], dedth[3, 1], dedth[3, 2], dedth[3, 3] = 0j, 0j, 1.0 + 0j, 1.0 + 0j
        p1r1, _ = vunit(vsub(p1, r1))
        pcos = vdot(p1r1, p1n)
        if pcos.real > 0.1:
            dd = complex(1.0 - pcos.real ** 100, -100.0 * pcos.real ** 99 * pcos.imag)
        else:
            dd = 1.0 + 0j
        for i in range(4):
            s = 0j
            for j in range(4):
                s += dedth[i, j] * ee[j]
            v[i] = -s
            for k in range(4):
                s = 0j
                for j in range(4):
                    s += dedth[i, j] * dedth[k, j]
                dedth2[i, k] = s
        nit2 = 0
        while True:
            for i in range(4):
                for k in range(4):
                    damp[i, k] = dedth2[i, k] * (1.0 + alpha) if i == k else dedth2[i, k]
            _solve4(damp, v, step)
            for i in range(4):
                vt[i] = step[i] * (dd / 16.0)
            r1 = (r1[0] + vt[0], r1[1] + vt[1], r1[2] + vt[2])
            d1 = d1 + vt[3]
            ssqo = ssq
            ssq = _residuals(r1, d1, p1, ax, vs, vs4, ee)
            alpha *= 4.0
            nit2 += 1
            if not (ssq >= ssqo and nit2 < 1000):
                break
        alpha /= 8.0
        fakt = 0.5
        nit2 = 0
        while ssq <= ssqo and nit2 < 1000:
            fakt *= 2.0
            r1 = (r1[0] + vt[0] * fakt, r1[1] + vt[1] * fakt, r1[2] + vt[2] * fakt)
            d1 = d1 + vt[3] * fakt
            ssqo = ssq
            ssq = _residuals(r1, d1, p1, ax, vs, vs4, scratch)
            nit2 += 1
        r1 = (r1[0] - vt[0] * fakt, r1[1] - vt[1] * fakt, r1[2] - vt[2] * fakt)
        d1 = d1 - vt[3] * fakt
        ssq = _residuals(r1, d1, p1, ax, vs, vs4, ee)
        ssqo = ssq
    return r1


@njit(cache=True, error_model="numpy")
def _ccos(x):
    return complex(math.cos(x.real), -math.sin(x.real) * x.imag)


@njit(cache=True, error_model="numpy")
def _csin(x):
    return complex(math.sin(x.real), math.cos(x.real) * x.imag)


@njit(cache=True, error_model="numpy")
def _arc(r1, r2, ax, vs, vs4, factor, far):
    """OpenSim CalcDistanceOnEllipsoid: polyline length, its 2nd and second-to-last points, and
    whether it has interior points."""
    chord = vnorm(vsub(r1, r2)) / factor
    if chord.real < 0.001:
        return chord * factor, r2, r1, False
    seg = chord.real / 0.001
    nseg = min(max(int(seg), 1), 499)
    imax = 0
    for i in (1, 2):
        if abs(vs[i].real) > abs(vs[imax].real):
            imax = i
    mu = -vs4 / vs[imax]
    a0 = (mu if imax == 0 else 0j, mu if imax == 1 else 0j, mu if imax == 2 else 0j)
    ar1, _ = vunit(vsub(r1, a0))
    ar2, _ = vunit(vsub(r2, a0))
    c = vdot(ar1, ar2)
    if abs(c.real) > 1.0:
        c = complex(1.0 if c.real > 0.0 else -1.0)
    slope = -1.0 / math.sqrt(1.0 - c.real * c.real) if abs(c.real) < 1.0 else 0.0
    phi0 = complex(math.acos(c.real), slope * c.imag)
    dphi = (-(2.0 * np.pi - phi0) if far else phi0) / nseg
    vsz, _ = vunit(vcross(ar1, ar2))
    vsy = vcross(vsz, ar1)
    f2 = (a0[0] / ax[0], a0[1] / ax[1], a0[2] / ax[2])
    cc = vdot(f2, f2) - 1.0
    prev = r1
    total = 0j
    w1 = r2
    w2 = r1
    for k in range(1, nseg):
        phi = dphi * k
        cph, sph = _ccos(phi), _csin(phi)
        r = vadd(vscale(ar1, cph), vscale(vsy, sph))
        f1 = (r[0] / ax[0], r[1] / ax[1], r[2] / ax[2])
        aa = vdot(f1, f1)
        bb = vdot(f1, f2) * 2.0
        mu3 = (-bb + csqrt(bb * bb - aa * cc * 4.0)) / (aa * 2.0)
        s = vadd(a0, vscale(r, mu3))
        total += vnorm(vsub(s, prev))
        prev = s
        if k == 1:
            w1 = s
        w2 = s
    total += vnorm(vsub(r2, prev))
    return total, w1, w2, nseg >= 2


@njit(cache=True, error_model="numpy")
def _plane_point(q1, q2, d12, i1, i2, ax, dims, method, memo, memo_n):
    """Step 2: the surface point c1 of the wrapping plane; (c1, tr1, tr2 start, has_fan, fan weight)."""
    r1r2 = vsub(i2, i1)
    mu_vec, _ = vunit(d12)
    best = 0
    for i in (1, 2):
        if abs(mu_vec[i].real) > abs(mu_vec[best].real):
            best = i
    mu_b = _cabs(mu_vec[best])
    t_b = _cdiv(-i1[best], r1r2[best])
    sv_f = vadd(i1, vscale(r1r2, t_b))
    c1_f = closest_point(ax[0], ax[1], ax[2], sv_f, best, ax[0], ax[1], ax[2])
    has_fan = False
    fan_weight = 0j
    if method == 1:                                       # midpoint
        sv = vadd(i1, vscale(r1r2, 0.5))
        c1 = _closest(ax, sv)
        return c1, c1, c1, has_fan, fan_weight
    if method == 0:                                       # hybrid: blend near the chord's ends
        tb = t_b.real
        s = 1.0 + 0j
        if tb > 1.0 - _SV_BLEND:
            s = (1.0 - t_b) / _SV_BLEND
        if tb < _SV_BLEND:
            s = t_b / _SV_BLEND
        if tb < 0.0 or tb > 1.0:
            s = 0j
        if mu_b.real > _MU_MIN and s.real < 1.0:
            mu_b = (mu_b - _MU_MIN) * s + _MU_MIN
    use_frans = method == 2 or mu_b.real > _MU_MIN
    c1 = c1_f if use_frans else _NAN3
    if method == 0 and mu_b.real < _MU_MAX:              # the fan
        mid = vadd(i1, vscale(r1r2, 0.5))
        vsum, _ = vunit(_fan_sum(i1, r1r2, ax, dims, memo, memo_n))
        c_fan = _closest(ax, vadd(mid, vsum))
        w = (mu_b - _MU_MIN) / (_MU_MAX - _MU_MIN)
        has_fan = True
        if mu_b.real <= _MU_MIN:
            c1 = c_fan
            fan_weight = 1.0 + 0j
        else:
            c1 = _closest(ax, vadd(vscale(c1, w), vscale(c_fan, 1.0 - w)))
            fan_weight = 1.0 - w
    if method == 2 and not (t_b.real > 0.0 and t_b.real < 1.0):
        return c1, i1, i2, has_fan, fan_weight
    return c1, c1, c1, has_fan, fan_weight


@njit(cache=True, error_model="numpy")
def ellipsoid_line(p1, p2, da, db, dc, axis, sign, method, memo, memo_n):
    """WrapEllipsoid::wrapLine in the ellipsoid frame: (code, r1, r2, arc).

    ``p1``, ``p2``: triples of complex (value + i STEP derivative); ``da, db, dc`` the semi-axes;
    ``axis``, ``sign`` the quadrant (`motion.wrapping.cylinder_line.quadrant_axis_sign`); ``method``
    0 hybrid, 1 midpoint, 2 axial; ``memo``, ``memo_n`` the fan's memo (`new_fan_memo`). r1, r2,
    arc are meaningful where code is MANDATORY_WRAP.
    """
    dims = (da, db, dc)
    factor = 3.0 / (da + db + dc)
    ax = (da * factor, db * factor, dc * factor)
    q1 = vscale(p1, factor)
    q2 = vscale(p2, factor)
    p1e = (q1[0] / ax[0]) ** 2 + (q1[1] / ax[1]) ** 2 + (q1[2] / ax[2]) ** 2 - 1.0
    p2e = (q2[0] / ax[0]) ** 2 + (q2[1] / ax[1]) ** 2 + (q2[2] / ax[2]) ** 2 - 1.0
    if p1e.real < -0.0001 or p2e.real < -0.0001:
        return INSIDE_RADIUS, _Z3, _Z3, 0j
    d12 = vsub(q1, q2)
    n1, _ = vunit(q1)
    n2, _ = vunit(q2)
    if abs(vdot(n1, n2).real - 1.0) < 0.0001:
        return NO_WRAP, _Z3, _Z3, 0j
    f1 = (d12[0] / ax[0], d12[1] / ax[1], d12[2] / ax[2])
    f2 = (q2[0] / ax[0], q2[1] / ax[1], q2[2] / ax[2])
    aa = vdot(f1, f1)
    bb = vdot(f1, f2) * 2.0
    cc = vdot(f2, f2) - 1.0
    disc = bb * bb - aa * cc * 4.0
    if disc.real < 0.0:
        return NO_WRAP, _Z3, _Z3, 0j
    root = csqrt(disc)
    l1 = (-bb + root) / (aa * 2.0)
    l2 = (-bb - root) / (aa * 2.0)
    if not (0.0 < l1.real < 1.0 and 0.0 < l2.real < 1.0):
        return NO_WRAP, _Z3, _Z3, 0j
    i1 = vadd(q2, vscale(d12, l1))
    i2 = vadd(q2, vscale(d12, l2))
    c1, tr1, tr2, has_fan, fan_weight = _plane_point(q1, q2, d12, i1, i2, ax, dims, method, memo, memo_n)
    if sign != 0 and (1 if c1[axis].real >= 0.0 else -1) != sign:
        c1m = (-c1[0] if axis == 0 else c1[0], -c1[1] if axis == 1 else c1[1], -c1[2] if axis == 2 else c1[2])
        tr1 = c1m
        tr2 = c1m
        fw = 1.0 + 0j if fan_weight.real > 1.0 else fan_weight
        if has_fan and fw.real > 0.0:
            comp = c1m[axis] * fw
            moved = (c1m[0] - comp if axis == 0 else c1m[0], c1m[1] - comp if axis == 1 else c1m[1],
                     c1m[2] - comp if axis == 2 else c1m[2])
            c1 = _closest(ax, moved)
        else:
            c1 = c1m
    vs, _ = vunit(vcross(d12, vsub(q1, c1)))
    vs4 = -vdot(vs, c1)
    tr1 = _tangent_point(p1e, tr1, q1, ax, vs, vs4)
    tr2 = _tangent_point(p2e, tr2, q2, ax, vs, vs4)
    length, w1, w2, has_mid = _arc(tr1, tr2, ax, vs, vs4, factor, False)
    if sign != 0 and has_mid:
        e1, _ = vunit(vsub(q1, tr1))
        g1, _ = vunit(vsub(w1, tr1))
        e2, _ = vunit(vsub(q2, tr2))
        g2, _ = vunit(vsub(w2, tr2))
        if vdot(e1, g1).real > 0.0 or vdot(e2, g2).real > 0.0:
            length = _arc(tr1, tr2, ax, vs, vs4, factor, True)[0]
    return MANDATORY_WRAP, vscale(tr1, 1.0 / factor), vscale(tr2, 1.0 / factor), length / factor
