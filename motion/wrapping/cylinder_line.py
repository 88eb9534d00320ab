"""One straight segment over one WrapCylinder, compiled: OpenSim 4.6's WrapCylinder::wrapLine.

Contract: `wrap_line` returns, for one segment p1 -> p2 in the cylinder's frame (axis z, centred),
OpenSim's WrapAction code, the tangent points r1, r2 and the helix length, values and
derivatives; `motion.wrapping.wrapped_rows` calls it for every candidate segment (and
`motion.wrapping.sphere_torus_line` for a torus). Steps (Peter Loan's WrapCylinder::wrapLine and
_make_spiral_path of OpenSim 4.6, read from its public source for the facts):

1. No wrap if either end point lies inside the infinite cylinder (``insideRadius``).
2. ``quadrant = all``: wrap only if the straight segment passes within ``radius`` of the
   cylinder's axis segment (closest points of the two lines, WrapMath::IntersectLines): a
   ``mandatoryWrap``. With a quadrant the segment may also wrap without touching (``wrapped``)
   when its end points lie on opposite sides and its closest point is on the inactive side.
3. Preliminary tangent points in the planes normal to the axis through each end point; the
   pair is chosen by the most-parallel rule (all) or by the active side (quadrant).
4. They are slid along the axis to the plane through p1, p2 and an "apex" on the cylinder; no
   wrap if both end up beyond the half length.
5. The surface path is a helix of length ``sqrt((R theta)^2 + axial^2)``, theta signed about the
   axis (``atan2``; ``2 pi - theta`` for a long wrap). Except for paths with a single wrap
   object (OpenSim's ``WrapResult::singleWrap``), the tangent points are then re-adjusted along
   the axis until the straight lines meet the helix within 0.1 degree (up to 100 restarts),
   r2 tested against a spiral point taken after r1 moved in the same pass (OpenSim 4.6).

A numpy implementation of the same steps is in ``tests/motion/wrap_oracle/cylinder.py``. The module
also holds what every compiled wrap line shares: the complex-step vector helpers, OpenSim's
WrapAction codes and quadrant names (`quadrant_axis_sign`).

Method: numbers are ``complex128`` carrying a derivative along one direction in the
imaginary part, scaled by ``STEP`` (``x + i STEP dx/ds``): sums, products and quotients of
such numbers are forward-mode dual numbers up to terms of order ``STEP**2`` (1e-200 relative,
below double precision), i.e. the complex-step derivative (Squire & Trapp, SIAM Review 40,
1998; Martins, Sturdza & Alonso, ACM TOMS 29, 2003), exact to rounding with no step-size
error. Square roots, trigonometric functions and ``atan2`` are applied as value plus
derivative (a zero square root gets derivative 0: a zero vector's norm). Every
branch tests real parts only. Vectors are triples of such numbers.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit


__all__ = ["wrap_line", "STEP", "NO_WRAP", "INSIDE_RADIUS", "WRAPPED", "MANDATORY_WRAP", "quadrant_axis_sign",
           "ELLIPSOID_METHODS"]

# OpenSim WrapObject::WrapAction
NO_WRAP, INSIDE_RADIUS, WRAPPED, MANDATORY_WRAP = 0, 1, 2, 3

# WrapEllipsoid methods, numbered as `motion.wrapping.ellipsoid_line.ellipsoid_line` takes them
ELLIPSOID_METHODS = ("hybrid", "midpoint", "axial")


def quadrant_axis_sign(quadrant: str) -> tuple:
    """(axis, sign) of an OpenSim quadrant name; sign 0 means all quadrants."""
    q = str(quadrant).strip()
    table = {"x": (0, 1), "+x": (0, 1), "X": (0, 1), "+X": (0, 1), "-x": (0, -1), "-X": (0, -1),
             "y": (1, 1), "+y": (1, 1), "Y": (1, 1), "+Y": (1, 1), "-y": (1, -1), "-Y": (1, -1),
             "z": (2, 1), "+z": (2, 1), "Z": (2, 1), "+Z": (2, 1), "-z": (2, -1), "-Z": (2, -1),
             "all": (0, 0), "ALL": (0, 0), "All": (0, 0), "Unassigned": (0, 0)}
    if q not in table:
        raise ValueError(f"quadrant must be one of x, -x, y, -y, z, -z, all; got {quadrant!r}")
    return table[q]

STEP = 1e-100                        # scale of the derivative in the imaginary part
_TANGENCY = 0.1 * np.pi / 180.0      # WrapCylinder's tangency threshold (rad)
_MAX_ADJUST = 100
_LINE_EPS = 1e-5
_NO, _INSIDE, _WRAPPED, _MANDATORY = NO_WRAP, INSIDE_RADIUS, WRAPPED, MANDATORY_WRAP
_Z3 = (0j, 0j, 0j)


@njit(cache=True, error_model="numpy")
def csqrt(a):
    """Square root of the value, derivative 1 / (2 sqrt) (0 at 0)."""
    s = math.sqrt(a.real) if a.real >= 0.0 else np.nan
    return complex(s, 0.5 / s * a.imag if s > 0.0 else 0.0)


@njit(cache=True, error_model="numpy")
def vsub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True, error_model="numpy")
def vadd(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(cache=True, error_model="numpy")
def vscale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@njit(cache=True, error_model="numpy")
def vdot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, error_model="numpy")
def vcross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True, error_model="numpy")
def vnorm(a):
    return csqrt(vdot(a, a))


@njit(cache=True, error_model="numpy")
def vunit(a):
    """WrapMath's normalize: (unit vector, or the zero vector where |a| = 0; |a|)."""
    n = vnorm(a)
    if n.real > 0.0:
        return (a[0] / n, a[1] / n, a[2] / n), n
    return _Z3, n


@njit(cache=True, error_model="numpy")
def _dist2(a, b):
    x, y, z = a[0].real - b[0].real, a[1].real - b[1].real, a[2].real - b[2].real
    return x * x + y * y + z * z


@njit(cache=True, error_model="numpy")
def _angle(a, b):
    """Angle between two vectors (values), arccos of the clipped cosine."""
    c = vdot(a, b).real / (vnorm(a).real * vnorm(b).real)
    return math.acos(-1.0 if c < -1.0 else (1.0 if c > 1.0 else c))


@njit(cache=True, error_model="numpy")
def aligned_pair(r1a, r1b, c1, r2a, r2b, c2):
    """Of the candidate tangent points ``r1a``/``r1b`` (about centre ``c1``) and ``r2a``/``r2b``
    (about ``c2``), the pair whose directions from their centres agree best (largest cosine;
    OpenSim's if/else chain: the first maximum, strict '>')."""
    n1a, _ = vunit(vsub(r1a, c1))
    n1b, _ = vunit(vsub(r1b, c1))
    n2a, _ = vunit(vsub(r2a, c2))
    n2b, _ = vunit(vsub(r2b, c2))
    e0, e1 = vdot(n1a, n2a).real, vdot(n1a, n2b).real
    e2, e3 = vdot(n1b, n2a).real, vdot(n1b, n2b).real
    pick = 3
    if e2 > e3:
        pick = 2
    if e1 > e2 and e1 > e3:
        pick = 1
    if e0 > e1 and e0 > e2 and e0 > e3:
        pick = 0
    return (r1a if pick <= 1 else r1b), (r2a if (pick == 0 or pick == 2) else r2b)


@njit(cache=True, error_model="numpy")
def _prelim(p, radius):
    """Two candidate tangent points in the plane normal to the axis through p; p11, |p - p11|."""
    p11 = (0j, 0j, p[2])
    vv, dist_axis = vunit(vsub(p, p11))
    rr = radius * radius
    dist = rr / dist_axis
    pp = vadd(p11, vscale(vv, dist))
    h = csqrt(rr - dist * dist)
    uu = (0.0 * vv[2] - vv[1], vv[0] - 0.0 * vv[2], 0j)
    return vadd(pp, vscale(uu, h)), vsub(pp, vscale(uu, h)), p11, dist_axis


@njit(cache=True, error_model="numpy")
def _slide_to_plane(r, pn, dpl, p_own, p_other):
    """A preliminary tangent point slid along the axis onto the plane (pn, dpl), as OpenSim."""
    ra = (r[0], r[1], r[2] - 10.0)
    dotprod = pn[2] * 20.0
    ok = abs(dotprod.real) >= _LINE_EPS
    t = (-dpl - vdot(pn, ra)) / (dotprod if ok else 1.0 + 0j)
    ok = ok and t.real >= -_LINE_EPS and t.real <= 1.0 + _LINE_EPS
    rp = (ra[0] + t * 0.0, ra[1] + t * 0.0, ra[2] + t * 20.0)
    n, _ = vunit(p_other)       # OpenSim passes the other point as the line direction here
    closest = vadd(p_own, vscale(n, vdot(vsub(rp, p_own), n)))
    if ok and _dist2(closest, p_other) < _dist2(p_own, p_other):
        return rp
    return r


@njit(cache=True, error_model="numpy")
def _slide(pt, x, y, z, w):
    """WrapCylinder::_adjust_tangent_point for r = (x, y, z) towards spiral point w: (z, adjusted)."""
    prx, pry, prz = x.real - pt[0].real, y.real - pt[1].real, z.real - pt[2].real
    rwx, rwy, rwz = w[0].real - x.real, w[1].real - y.real, w[2].real - z.real
    cos_a = prz / math.sqrt(prx * prx + pry * pry + prz * prz)
    cos_o = rwz / math.sqrt(rwx * rwx + rwy * rwy + rwz * rwz)
    cos_a = 0.0 if cos_a != cos_a else max(-1.0, min(1.0, cos_a))
    cos_o = 0.0 if cos_o != cos_o else max(-1.0, min(1.0, cos_o))
    adjust = abs(math.acos(cos_a) - math.acos(cos_o)) > _TANGENCY
    d = vsub(w, pt)
    w0x, w0y, w0z = pt[0] - x, pt[1] - y, pt[2]
    a = vdot(d, d)
    b = d[2]
    dd = d[0] * w0x + d[1] * w0y + d[2] * w0z
    denom = a - b * b
    ok = abs(denom.real) > 1e-300
    zint = (a * w0z - b * dd) / (denom if ok else 1.0 + 0j)
    return z + (zint - z) * 1.5, adjust and ok


@njit(cache=True, error_model="numpy")
def _spiral_point(x1, y1, z1, dz, angle, t):
    c = complex(math.cos(angle.real), -math.sin(angle.real) * angle.imag)
    s = complex(math.sin(angle.real), math.cos(angle.real) * angle.imag)
    return (x1 * c - y1 * s, x1 * s + y1 * c, z1 + dz * t)


@njit(cache=True, error_model="numpy")
def wrap_line(p1, p2, radius, length, axis, sign, adjust):
    """WrapCylinder::wrapLine in the cylinder frame (axis z, centred): (code, r1, r2, arc).

    ``p1``, ``p2``: triples of complex (value + i STEP derivative); ``axis``, ``sign`` from
    `motion.wrapping.cylinder_line.quadrant_axis_sign`; ``adjust``: the tangency re-adjustment.
    r1, r2 and arc are meaningful where code is WRAPPED or MANDATORY_WRAP.
    """
    r2sq = radius * radius
    if (p1[0].real ** 2 + p1[1].real ** 2 < r2sq) or (p2[0].real ** 2 + p2[1].real ** 2 < r2sq):
        return _INSIDE, _Z3, _Z3, 0j
    code = _WRAPPED
    # closest points of the segment's line and the axis segment (WrapMath::IntersectLines)
    cyl_s = (0j, 0j, complex(-0.5 * length))
    vec1, mag1 = vunit(vsub(p2, p1))
    vec2, _ = vunit((0j, 0j, complex(length)))
    cp = vcross(vec1, vec2)
    denom = vdot(cp, cp)
    if not abs(denom.real) > 2e-13:
        denom = 1.0 + 0j
    row0 = vsub(cyl_s, p1)
    near00 = vadd(cyl_s, vscale(vec2, vdot(row0, vcross(vec1, cp)) / denom))
    ss = vdot(row0, vcross(vec2, cp)) / denom
    near12 = vadd(p1, vscale(vec1, ss))
    t12 = ss.real / mag1.real
    hits = _dist2(near12, near00) < r2sq and t12 > 0.0 and t12 < 1.0
    if sign == 0:
        if not hits:
            return _NO, _Z3, _Z3, 0j
        code = _MANDATORY
    r1a, r1b, p11, d1 = _prelim(p1, radius)
    r2a, r2b, p22, d2 = _prelim(p2, radius)
    far_side = False
    long_wrap = False
    if sign != 0:
        s1 = 1 if p1[axis].real >= 0.0 else -1
        s2 = 1 if p2[axis].real >= 0.0 else -1
        if s1 == sign or s2 == sign:
            if hits:
                code = _MANDATORY
            elif s1 != s2 and (1 if near12[axis].real >= 0.0 else -1) != sign:
                code = _WRAPPED
            else:
                return _NO, _Z3, _Z3, 0j
        a_gt_b = _angle(vsub(r1a, p11), vsub(r2b, p22)) > _angle(vsub(r1b, p11), vsub(r2a, p22))
        a1 = (1 if r1a[axis].real >= 0.0 else -1) == sign
        b1 = (1 if r1b[axis].real >= 0.0 else -1) == sign
        a2 = (1 if r2a[axis].real >= 0.0 else -1) == sign
        b2 = (1 if r2b[axis].real >= 0.0 else -1) == sign
        case_none = not a1 and not b1
        choose_b = ((a1 and b1 and a2) or (not a1 and b1) or (case_none and a2)
                    or (case_none and not a2 and not b2 and not a_gt_b))
        far_side = (not a_gt_b) if choose_b else a_gt_b
        if case_none and not a2 and not b2:
            far_side = True
        r1 = r1b if choose_b else r1a
        r2 = r2a if choose_b else r2b
        long_wrap = vdot(vadd(vsub(r1, p11), vsub(r2, p22)), vadd(vsub(r1, p1), vsub(r2, p2))).real < 0.0
    else:
        r1, r2 = aligned_pair(r1a, r1b, p11, r2a, r2b, p22)
    # apex on the cylinder between the points, in the plane through p1, p2 and the axis
    mpt = vadd(p1, vscale(vsub(p2, p1), d1 / (d1 + d2)))
    axispt = (0.0 * mpt[0], 0.0 * mpt[0], mpt[2])
    l1, _ = vunit(vsub(p1, axispt))
    l2, _ = vunit(vsub(p2, axispt))
    pn, _ = vunit(vcross(l1, l2))
    dn = (0j, 0j, 1.0 + 0j)
    vert1, _ = vunit(vcross(dn, pn))
    vert2, _ = vunit(vcross(pn, dn))
    apex1 = vadd(axispt, vscale(vert1, complex(radius)))
    apex2 = vadd(axispt, vscale(vert2, complex(radius)))
    first_closer = _dist2(mpt, apex1) < _dist2(mpt, apex2)
    apex = apex1 if ((not first_closer) if far_side else first_closer) else apex2
    uu, _ = vunit(vsub(p1, apex))
    vv, _ = vunit(vsub(p2, apex))
    pn, _ = vunit(vcross(uu, vv))
    dpl = -vdot(p1, pn)
    r1 = _slide_to_plane(r1, pn, dpl, p11, p22)
    r2 = _slide_to_plane(r2, pn, dpl, p22, p11)
    half = 0.5 * length
    if (r1[2].real < -half or r1[2].real > half) and (r2[2].real < -half or r2[2].real > half):
        return _NO, _Z3, _Z3, 0j
    # the helix between the tangent points (WrapCylinder::_make_spiral_path, OpenSim 4.6)
    x1, y1, z1 = r1
    x2, y2, z2 = r2
    cz = x1 * y2 - y1 * x2
    cc = x1 * x2 + y1 * y2
    r2c = cc.real * cc.real + cz.real * cz.real
    theta = complex(math.atan2(cz.real, cc.real), (cc.real / r2c) * cz.imag - (cz.real / r2c) * cc.imag)
    if long_wrap:
        theta = 2.0 * np.pi - theta
    if adjust:
        sense = -1.0 if long_wrap else 1.0
        for _ in range(_MAX_ADJUST):
            dz = z2 - z1
            x = theta * radius
            seg = math.sqrt(x.real * x.real + dz.real * dz.real) / 0.002
            n_seg = int(seg) if seg == seg and seg < 1e18 else 1
            if n_seg < 2:
                break
            tt = 1.0 / n_seg
            new1, adj1 = _slide(p1, x1, y1, z1, _spiral_point(x1, y1, z1, dz, theta * (sense * tt), tt))
            b1 = new1 if adj1 else z1
            new2, adj2 = _slide(p2, x2, y2, z2,
                                _spiral_point(x1, y1, b1, dz, theta * (sense * (1.0 - tt)), 1.0 - tt))
            if not (adj1 or adj2):
                break
            z1 = b1
            z2 = new2 if adj2 else z2
    x = theta * radius
    dz = z2 - z1
    return code, (x1, y1, z1), (x2, y2, z2), csqrt(x * x + dz * dz)
