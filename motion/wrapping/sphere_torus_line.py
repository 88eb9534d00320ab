"""One straight segment over a WrapSphere or a WrapTorus, compiled (OpenSim 4.6's wrapLine).

Contract: `sphere_line` and `torus_line` return, for one segment p1 -> p2 in the object's frame,
OpenSim's WrapAction code, the tangent points r1, r2 and the arc length, values and
derivatives (complex-step numbers, `motion.wrapping.cylinder_line`). Numpy implementations of
the same steps are in ``tests/motion/wrap_oracle/``; ``tests/motion/test_compiled_wraps.py``
compares them. Read from OpenSim's public source for the facts; independent implementations.

WrapSphere::wrapLine (Peter Loan, from SIMM):

1. No wrap if an end point is inside the sphere (``insideRadius``), or if the straight segment
   does not pass through it (both intersection parameters in (0, 1)), or if the segment runs
   through the centre (OpenSim then reuses the previous frame's points; here: no wrap).
2. Tangent-point candidates: for each end point, the two points where the plane through the
   centre, p1 and p2 touches the tangent cone from it; the pair whose directions from the
   centre are most parallel is taken (the short great-circle arc).
3. With a quadrant: a segment with an end point on the active side is a ``mandatoryWrap`` if the
   line's closest point to the centre is within R and its parameter -- OpenSim compares a
   distance in metres with (0, 1) -- is in (0, 1); otherwise it wraps only if the end points
   are on opposite sides and that closest point is on the inactive side. Unless both end points
   are on the active side the tangent points face the active side, and a far-side wrap is
   detected, whose arc length OpenSim gives as ``-(2 pi - angle) R`` (negative; reproduced).

WrapTorus::wrapLine: no geodesic on the torus. The line point "closest" to the centre circle
solves OpenSim's calcCircleResids = 0 from u = 0, from p1 and from p2 (that residual carries a
factor 2 too many on its circle term, reproduced); with a quadrant only results on the active
side count, otherwise the one nearer the real circle wins. It is projected onto the circle, a
WrapCylinder of radius ``inner_radius`` and length 10000 is put there (axis tangent to the
circle, +x towards the centre, no quadrant in effect, tangents re-adjusted) and the segment is
wrapped over it. OpenSim solves the residual with MINPACK's lmdif to a relative 1e-4; this uses
Newton's method to machine precision (tangent points differ by about that tolerance).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .cylinder_line import (INSIDE_RADIUS, MANDATORY_WRAP, NO_WRAP, WRAPPED, aligned_pair, csqrt, vadd, vcross,
                            vdot, vnorm, vscale, vsub, vunit, wrap_line)

__all__ = ["sphere_line", "torus_line"]

_Z3 = (0j, 0j, 0j)
_TORUS_CYLINDER = 10000.0


@njit(cache=True, error_model="numpy")
def _casin(x):
    slope = 1.0 / math.sqrt(1.0 - x.real * x.real) if abs(x.real) < 1.0 else 0.0
    return complex(math.asin(x.real), slope * x.imag)


@njit(cache=True, error_model="numpy")
def _cacos(x):
    slope = -1.0 / math.sqrt(1.0 - x.real * x.real) if abs(x.real) < 1.0 else 0.0
    return complex(math.acos(x.real), slope * x.imag)


@njit(cache=True, error_model="numpy")
def _candidates(p, n, radius):
    """Two tangent-point candidates from end point p in the plane with normal n."""
    y, dist = vunit(vscale(p, -1.0))
    z = vcross(n, y)
    a = _casin(radius / dist)
    ca = complex(math.cos(a.real), -math.sin(a.real) * a.imag)
    sa = complex(math.sin(a.real), math.cos(a.real) * a.imag)
    scale = dist * ca
    ra = vadd(p, vscale(vsub(vscale(y, ca), vscale(z, sa)), scale))
    rb = vadd(p, vscale(vadd(vscale(y, ca), vscale(z, sa)), scale))
    return ra, rb


@njit(cache=True, error_model="numpy")
def _side(x, sign):
    return (1 if x.real >= 0.0 else -1) == sign


@njit(cache=True, error_model="numpy")
def sphere_line(p1, p2, radius, axis, sign):
    """WrapSphere::wrapLine in the sphere frame (centre at 0): (code, r1, r2, signed arc)."""
    if vnorm(p1).real < radius or vnorm(p2).real < radius:
        return INSIDE_RADIUS, _Z3, _Z3, 0j
    ri = vsub(p1, p2)
    a = vdot(ri, ri).real
    b = 2.0 * vdot(p2, ri).real
    c = vdot(p2, p2).real - radius * radius
    disc = b * b - 4.0 * a * c
    root = math.sqrt(max(disc, 0.0))
    l1 = (-b + root) / (2.0 * a)
    l2 = (-b - root) / (2.0 * a)
    if disc < 0.0 or not (0.0 < l1 < 1.0) or not (0.0 < l2 < 1.0) or l1 < l2:
        return NO_WRAP, _Z3, _Z3, 0j
    u12, _ = vunit(ri)
    np2, _ = vunit(p2)
    hp2 = vcross(u12, np2)
    if vnorm(hp2).real < 1e-5:
        return NO_WRAP, _Z3, _Z3, 0j
    code = WRAPPED
    n, _ = vunit(hp2)
    r1a, r1b = _candidates(p1, n, radius)
    r2a, r2b = _candidates(p2, n, radius)
    r1, r2 = aligned_pair(r1a, r1b, _Z3, r2a, r2b, _Z3)
    far = False
    if sign != 0:
        on1, on2 = _side(p1[axis], sign), _side(p2[axis], sign)
        tt = vdot(p1, u12)
        mm = vsub(p1, vscale(u12, tt))
        mand = vdot(mm, mm).real < radius * radius and 0.0 < tt.real < 1.0
        maybe = on1 != on2 and not _side(mm[axis], sign)
        if on1 or on2:
            if mand:
                code = MANDATORY_WRAP
            elif not maybe:
                return NO_WRAP, _Z3, _Z3, 0j
        if not on1 or not on2:
            sm, _ = vunit(vsub(vscale(p1, -1.0), p2))
            take1a = vdot(vunit(r1a)[0], sm).real > vdot(vunit(r1b)[0], sm).real
            take2a = vdot(vunit(r2a)[0], sm).real > vdot(vunit(r2b)[0], sm).real
            c1, o1 = (r1a, r1b) if take1a else (r1b, r1a)
            c2, o2 = (r2a, r2b) if take2a else (r2b, r2a)
            sm2, _ = vunit(vadd(vsub(c1, p1), vsub(c2, p2)))
            if sm2[axis].real * sign < 0.0:
                c1, c2 = o1, o2
            r1, r2 = c1, c2
            far = vdot(vadd(r1, r2), vadd(vsub(r1, p1), vsub(r2, p2))).real < 0.0
    r1n, _ = vunit(r1)
    r2n, _ = vunit(r2)
    cosang = vdot(r1n, r2n)
    if abs(cosang.real) > 1.0:
        cosang = complex(1.0 if cosang.real > 0.0 else -1.0)
    angle = _cacos(cosang)
    if far:
        angle = -(2.0 * np.pi - angle)
    return code, r1, r2, angle * radius


@njit(cache=True, error_model="numpy")
def _circle_point(p1, p2, radius):
    """Root of OpenSim's calcCircleResids along p1 -> p2 from u = 0 (Newton): the line point."""
    n, _ = vunit(vsub(p2, p1))
    c2 = vdot(p1, n) * 2.0
    c3 = p1[0] * n[0] + p1[1] * n[1]
    c4 = n[0] * n[0] + n[1] * n[1]
    c5 = p1[0] * p1[0] + p1[1] * p1[1]
    u = 0j
    for _ in range(100):
        c6 = csqrt(u * u * c4 + u * c3 * 2.0 + c5)
        g = c4 * u + c3
        res = c2 + u * 2.0 - g * (4.0 * radius) / c6
        dres = 2.0 - (c4 * c6 - g * g / c6) * (4.0 * radius) / (c6 * c6)
        step = res / dres
        if not abs(step.real) > 1e-15 * (1.0 + abs(u.real)):
            break
        u = u - step
    return vadd(p1, vscale(n, u))


@njit(cache=True, error_model="numpy")
def _ring_distance(p, radius):
    rho = math.sqrt(p[0].real ** 2 + p[1].real ** 2)
    return math.sqrt(p[0].real ** 2 + p[1].real ** 2 + p[2].real ** 2 + radius * radius - 2.0 * radius * rho)


@njit(cache=True, error_model="numpy")
def torus_line(p1, p2, inner_radius, outer_radius, axis, sign):
    """WrapTorus::wrapLine in the torus frame (axis z, centre at 0): (code, r1, r2, arc)."""
    a1 = _circle_point(p1, p2, outer_radius)
    a2 = _circle_point(p2, p1, outer_radius)
    near1 = _ring_distance(a1, outer_radius) < _ring_distance(a2, outer_radius)
    ok = True
    if sign != 0:
        on1, on2 = _side(a1[axis], sign), _side(a2[axis], sign)
        use2 = (not near1) if (on1 and on2) else ((not on1) and on2)
        ok = on1 or on2
    else:
        use2 = not near1
    a = a2 if use2 else a1
    rho = csqrt(a[0] * a[0] + a[1] * a[1])
    closest = (a[0] * outer_radius / rho, a[1] * outer_radius / rho, 0j)
    cx, _ = vunit(vscale(closest, -1.0))
    cy = (0j, 0j, -1.0 + 0j)
    cz = vcross(cx, cy)
    neg = vscale(closest, -1.0)
    shift = (vdot(cx, neg), vdot(cy, neg), vdot(cz, neg))
    q1 = (vdot(cx, p1) + shift[0], vdot(cy, p1) + shift[1], vdot(cz, p1) + shift[2])
    q2 = (vdot(cx, p2) + shift[0], vdot(cy, p2) + shift[1], vdot(cz, p2) + shift[2])
    code, r1, r2, arc = wrap_line(q1, q2, inner_radius, _TORUS_CYLINDER, 0, 0, True)
    if not (ok and code >= WRAPPED):
        return NO_WRAP, _Z3, _Z3, 0j
    s1, s2 = vsub(r1, shift), vsub(r2, shift)
    g1 = vadd(vadd(vscale(cx, s1[0]), vscale(cy, s1[1])), vscale(cz, s1[2]))
    g2 = vadd(vadd(vscale(cx, s2[0]), vscale(cy, s2[1])), vscale(cz, s2[2]))
    return WRAPPED, g1, g2, arc
