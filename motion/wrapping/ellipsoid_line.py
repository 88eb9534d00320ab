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
they run). Closest points and the fan: `motion.wrapping.ellipsoid_closest` (the fan in real
arithmetic, its derivative along any direction from two 3 x 3 sums, memoised per row).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .cylinder_line import INSIDE_RADIUS, MANDATORY_WRAP, NO_WRAP, csqrt, vadd, vcross, vdot, vnorm, vscale, vsub, vunit
from .ellipsoid_closest import _cabs, _fan_sum, closest_point, new_fan_memo

__all__ = ["ellipsoid_line", "closest_point", "new_fan_memo"]

_TINY = 1e-8
_MU_MIN = 0.7073
_MU_MAX = 0.9
_SV_BLEND = 0.3
_Z3 = (0j, 0j, 0j)
_NAN3 = (complex(np.nan, 0.0), complex(np.nan, 0.0), complex(np.nan, 0.0))


@njit(cache=True, error_model="numpy")
def _cdiv(a, b):
    """a / b; a zero divisor gives what numpy gives (inf or nan, no derivative)."""
    if b.real == 0.0 and b.imag == 0.0:
        return complex(a.real / 0.0 if a.real != 0.0 else np.nan, 0.0)
    return a / b


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
