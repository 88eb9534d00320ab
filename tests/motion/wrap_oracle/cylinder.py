"""Numpy oracle of `motion.wrapping.cylinder_line`: a path segment over an OpenSim WrapCylinder.

Reproduces OpenSim 4.6 ``WrapCylinder::wrapLine`` and ``_make_spiral_path`` (Peter Loan's
algorithm, inherited from SIMM), read from OpenSim's public source for the facts; this is an
independent numpy implementation:

1. No wrap if either end point lies inside the infinite cylinder (``insideRadius``).
2. ``quadrant = all``: wrap only if the straight segment passes within ``radius`` of the
   cylinder's axis segment (closest points of the two lines, WrapMath::IntersectLines), which
   is a ``mandatoryWrap``. With a quadrant (``x``, ``-y`` ...) the segment may also wrap
   without touching (``wrapped``) when its end points lie on opposite sides and the closest
   point on the segment is on the inactive side; no wrap if neither rule holds.
3. Preliminary tangent points in the planes normal to the axis through each end point; the
   pair is chosen by the most-parallel rule (all) or by the active side (quadrant).
4. The tangent points are slid along the axis to the plane through p1, p2 and an "apex" on
   the cylinder; no wrap if both end up beyond the half length.
5. The surface path is a helix; its length is ``sqrt((R theta)^2 + axial^2)`` with theta the
   angle between the tangent points signed about the axis (``atan2``; ``2 pi - theta`` for a
   long wrap), as in OpenSim 4.6. Except for paths with a single wrap object (OpenSim's
   ``WrapResult::singleWrap`` optimisation when visualisation is off), the tangent points are
   then re-adjusted along the axis until the straight lines meet the helix within 0.1 degree
   (up to 100 restarts); OpenSim 4.6's spiral points follow the current r1, so r2 is tested
   against a spiral point taken after r1 moved in the same pass (older releases' source used
   the pass's initial r1; 4.6 is what is reproduced, to ~1e-15 m against live OpenSim).

Everything is computed on `wrap_oracle.dual.Dual` arrays, so the returned length carries
its exact derivative with respect to whatever the inputs were seeded with.
"""
from __future__ import annotations

import numpy as np

from motion.wrapping.cylinder_line import quadrant_axis_sign  # the quadrant names, not under test

from . import dual as ad
from .dual import Dual

__all__ = ["wrap_cylinder", "cylinder_wrap_line", "NO_WRAP", "INSIDE_RADIUS", "WRAPPED",
           "MANDATORY_WRAP", "quadrant_axis_sign"]

# OpenSim WrapObject::WrapAction
NO_WRAP, INSIDE_RADIUS, WRAPPED, MANDATORY_WRAP = 0, 1, 2, 3

_TANGENCY_THRESHOLD = 0.1 * np.pi / 180.0
_MAX_ITERATIONS = 100
_LINE_EPSILON = 1e-5


def dsign(x) -> np.ndarray:
    """SIMM's DSIGN: +1 for x >= 0, else -1."""
    return np.where(ad.value(x) >= 0.0, 1, -1)


def _vec(x, y, z) -> Dual:
    return ad.stack([x, y, z])


def closest_point_on_line(pt, line_pt, line) -> Dual:
    """WrapMath::GetClosestPointOnLineToPoint (``line`` is a direction, normalised here)."""
    n, _ = ad.normalize_or_zero(line)
    t = ad.dot(ad.lift(pt) - line_pt, n)
    return ad.lift(line_pt) + t.expand(-1) * n


def intersect_lines(p1, p2, p3, p4):
    """WrapMath::IntersectLines: closest points of lines p1p2 and p3p4.

    Returns (pint1, s, pint2, t, ok) with ``s``, ``t`` the parameters along p1->p2 and p3->p4
    (0 at the first point, 1 at the second); ``ok`` False where the lines are parallel.
    """
    vec1, mag1 = ad.normalize_or_zero(ad.lift(p2) - p1)
    vec2, mag2 = ad.normalize_or_zero(ad.lift(p4) - p3)
    cp = ad.cross(vec1, vec2)
    denom = ad.dot(cp, cp)
    ok = np.abs(denom.v) > 2e-13  # EQUAL_WITHIN_ERROR(denom, 0)
    denom = ad.where(ok, denom, 1.0)
    row0 = ad.lift(p3) - p1
    t = ad.dot(row0, ad.cross(vec1, cp)) / denom
    pint2 = ad.lift(p3) + t.expand(-1) * vec2
    s = ad.dot(row0, ad.cross(vec2, cp)) / denom
    pint1 = ad.lift(p1) + s.expand(-1) * vec1
    return pint1, s / mag1, pint2, t / mag2, ok


def _dist2(a, b) -> Dual:
    d = ad.lift(a) - b
    return ad.dot(d, d)


def _signed_theta(xy1, xy2, long_wrap):
    """Helix angle as OpenSim 4.6: signed about +z (atan2 of cross and dot); long: 2 pi - theta."""
    cz = xy1[:, 0] * xy2[:, 1] - xy1[:, 1] * xy2[:, 0]
    cc = xy1[:, 0] * xy2[:, 0] + xy1[:, 1] * xy2[:, 1]
    theta = ad.arctan2(cz, cc)
    return ad.where(long_wrap, 2.0 * np.pi - theta, theta)


def _spiral_path(p1, p2, r1, r2, long_wrap, radius, adjust, need):
    """WrapCylinder::_make_spiral_path (OpenSim 4.6): helix length and tangent re-adjustment.

    OpenSim 4.6 measures the helix angle ``theta`` signed about the axis (``atan2``; a long
    wrap takes ``2 pi - theta``) and turns r1 by ``sense * t * theta`` about the axis, ``sense``
    -1 for a long wrap; the length is ``sqrt((R theta)^2 + axial^2)``. The re-adjustment only
    slides r1 and r2 along the axis, so the loop carries their z coordinates (theta is fixed).
    Each pass is OpenSim's: compare the angles to the axis of p->r and of r->w (w the spiral
    point 1/n of the way from r), and if they differ by more than 0.1 degree move r 1.5 times
    the way to the point of r's axial line closest to the line p->w. As in OpenSim 4.6, whose
    spiral points are computed from the *current* r1 (a lambda capturing the result by
    reference), r2's spiral point is taken after r1 was moved in the same pass, with the
    pass's axial distance and angle. Checked against live OpenSim 4.6 to ~1e-15 m.
    The loop runs on the frames of ``need`` (those that wrap) only; elsewhere r1, r2 stay.
    """
    xy1, xy2 = r1[:, :2], r2[:, :2]
    z1, z2 = r1[:, 2], r2[:, 2]
    theta = _signed_theta(xy1, xy2, long_wrap)
    if adjust:
        sense = np.where(long_wrap, -1.0, 1.0)
        iterations = np.zeros(long_wrap.shape, dtype=int)
        active = np.array(need, dtype=bool, copy=True)
        while active.any():
            idx = np.nonzero(active)[0]
            a1, a2, th = _rows(z1, idx), _rows(z2, idx), _rows(theta, idx)
            c1, c2 = _rows(xy1, idx), _rows(xy2, idx)
            q1, q2 = _rows(p1, idx), _rows(p2, idx)
            dz = a2 - a1
            x = th * radius[idx]
            n_seg = np.maximum((np.sqrt(x.v * x.v + dz.v * dz.v) / 0.002).astype(int), 1)
            can = (n_seg >= 2) & (iterations[idx] < _MAX_ITERATIONS)
            t = 1.0 / n_seg
            w1 = _spiral_xyz(c1, a1, dz, th * (sense[idx] * t), t)
            new1, adj1 = _slide(q1, c1, a1, w1)
            b1 = ad.where(adj1, new1, a1)
            w2 = _spiral_xyz(c1, b1, dz, th * (sense[idx] * (1.0 - t)), 1.0 - t)
            new2, adj2 = _slide(q2, c2, a2, w2)
            changed = can & (adj1 | adj2)
            active[idx[~changed]] = False
            if not changed.any():
                break
            new2 = ad.where(adj2, new2, a2)
            z1 = ad.scatter(z1, idx[changed], _rows(b1, changed))
            z2 = ad.scatter(z2, idx[changed], _rows(new2, changed))
            iterations[idx[changed]] += 1
        r1 = ad.stack([xy1[:, 0], xy1[:, 1], z1])
        r2 = ad.stack([xy2[:, 0], xy2[:, 1], z2])
    x = theta * radius
    dz = z2 - z1
    return r1, r2, ad.sqrt(x * x + dz * dz)


def _spiral_xyz(xy1, z1, dz, angle, t):
    """Spiral point: r1's radial direction turned by ``angle`` about z, axial fraction t."""
    c, s = ad.cos(angle), ad.sin(angle)
    x = xy1[:, 0] * c - xy1[:, 1] * s
    y = xy1[:, 0] * s + xy1[:, 1] * c
    return ad.stack([x, y, z1 + dz * np.asarray(t)])


def _slide(pt, xy, z, w):
    """WrapCylinder::_adjust_tangent_point for r = (xy, z): (new z, adjusted mask)."""
    # the tangency test needs values only
    r = np.concatenate([xy.v, z.v[:, None]], axis=1)
    pr = r - pt.v
    rw = w.v - r
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_a = pr[:, 2] / np.linalg.norm(pr, axis=1)
        cos_o = rw[:, 2] / np.linalg.norm(rw, axis=1)
    alpha = np.arccos(np.clip(np.nan_to_num(cos_a), -1.0, 1.0))
    omega = np.arccos(np.clip(np.nan_to_num(cos_o), -1.0, 1.0))
    adjust = np.abs(alpha - omega) > _TANGENCY_THRESHOLD
    # closest point of r's axial line (x, y fixed) to the line pt -> w (WrapMath::IntersectLines)
    d = w - pt
    w0x, w0y, w0z = pt[:, 0] - xy[:, 0], pt[:, 1] - xy[:, 1], pt[:, 2]
    a = ad.dot(d, d)
    b = d[:, 2]
    dd = d[:, 0] * w0x + d[:, 1] * w0y + d[:, 2] * w0z
    denom = a - b * b
    ok = np.abs(denom.v) > 1e-300
    zint = (a * w0z - b * dd) / ad.where(ok, denom, 1.0)
    new = z + (zint - z) * 1.5
    return new, adjust & ok


def _rows(x, idx):
    x = ad.lift(x)
    return Dual(x.v[idx], x.d[idx] if x.d.shape[0] == x.v.shape[0] else x.d)


def _prelim_tangents(p, radius):
    """Two candidate tangent points in the plane normal to the axis through ``p``."""
    dn = np.array([0.0, 0.0, 1.0])
    zero = 0.0 * p[..., 0]
    p11 = _vec(zero, zero, p[..., 2])
    vv, dist_axis = ad.normalize_or_zero(p - p11)
    dist = (radius * radius) / dist_axis
    pp = p11 + vv * dist.expand(-1)
    h = ad.sqrt(radius * radius - dist * dist)
    uu = ad.cross(dn, vv)
    return pp + uu * h.expand(-1), pp - uu * h.expand(-1), p11, dist_axis


def cylinder_wrap_line(p1, p2, *, radius, length, quadrant="all", adjust_tangents=True):
    """OpenSim's WrapCylinder::wrapLine on frames, in the cylinder's own frame.

    Parameters
    ----------
    p1, p2 : (F, 3) float or Dual
        Segment end points in the wrap frame (axis = z, centred at the origin).
    radius, length : float or (F,) float
        Cylinder radius and (display) length, one value or one per frame (rows of several
        paths' cylinders batched together).
    quadrant : str
        OpenSim quadrant ("all", "x", "-x", "y", "-y", "z", "-z").
    adjust_tangents : bool
        Run the 0.1-degree tangency re-adjustment (OpenSim does it unless the path has a
        single wrap object).

    Returns
    -------
    code : (F,) int
        NO_WRAP, INSIDE_RADIUS, WRAPPED or MANDATORY_WRAP (OpenSim's WrapAction).
    r1, r2 : (F, 3) Dual
        Tangent points (valid where code >= WRAPPED).
    arc : (F,) Dual
        Length of the helical path on the surface between r1 and r2.
    """
    p1, p2 = ad.lift(p1), ad.lift(p2)
    axis, sign = quadrant_axis_sign(quadrant)
    constrained = sign != 0
    nf = p1.shape[0]
    radius = np.broadcast_to(np.asarray(radius, dtype=float), (nf,))   # one per frame (or row)
    length = np.broadcast_to(np.asarray(length, dtype=float), (nf,))
    r2sq = radius * radius
    code = np.full(nf, WRAPPED, dtype=int)
    done = np.zeros(nf, dtype=bool)

    inside = (p1.v[:, 0] ** 2 + p1.v[:, 1] ** 2 < r2sq) | (p2.v[:, 0] ** 2 + p2.v[:, 1] ** 2 < r2sq)
    code[inside] = INSIDE_RADIUS
    done |= inside

    cyl_end = np.stack([0.0 * length, 0.0 * length, 0.5 * length], axis=1)
    cyl_start = -cyl_end
    near12, t12, near00, _, _ = intersect_lines(p1, p2, cyl_start, cyl_end)
    hits = (_dist2(near12, near00).v < r2sq) & (t12.v > 0.0) & (t12.v < 1.0)

    if not constrained:
        code[~done & hits] = MANDATORY_WRAP
        code[~done & ~hits] = NO_WRAP
        done |= ~hits

    r1a, r1b, p11, d1 = _prelim_tangents(p1, radius)
    r2a, r2b, p22, d2 = _prelim_tangents(p2, radius)

    far_side = np.zeros(nf, dtype=bool)
    long_wrap = np.zeros(nf, dtype=bool)
    if constrained:
        s1, s2 = dsign(p1[:, axis]), dsign(p2[:, axis])
        either = (s1 == sign) | (s2 == sign)
        mand = either & hits
        maybe = either & ~hits & (s1 != s2) & (dsign(near12[:, axis]) != sign)
        code[~done & mand] = MANDATORY_WRAP
        code[~done & either & ~hits & maybe] = WRAPPED
        stop = either & ~hits & ~maybe
        code[~done & stop] = NO_WRAP
        done |= stop

        def angle(a, b):
            c = ad.dot(a, b) / (ad.norm(a) * ad.norm(b))
            return np.arccos(np.clip(c.v, -1.0, 1.0))

        alpha = angle(r1a - p11, r2b - p22)
        beta = angle(r1b - p11, r2am := r2a - p22)
        a_gt_b = alpha > beta
        on = lambda r: dsign(r[:, axis]) == sign  # noqa: E731
        a1, b1, a2, b2 = on(r1a), on(r1b), on(r2a), on(r2b)
        # choice True: (r1b, r2a); False: (r1a, r2b)
        case_both = a1 & b1
        case_a = a1 & ~b1
        case_b = ~a1 & b1
        case_none = ~a1 & ~b1
        choose_b = np.zeros(nf, dtype=bool)
        choose_b |= case_both & a2
        choose_b |= case_b
        choose_b |= case_none & a2
        choose_b |= case_none & ~a2 & ~b2 & ~a_gt_b
        far_side = np.where(choose_b, ~a_gt_b, a_gt_b)
        far_side = np.where(case_none & ~a2 & ~b2, True, far_side)
        del case_a, r2am
        r1 = ad.where(choose_b[:, None], r1b, r1a)
        r2 = ad.where(choose_b[:, None], r2a, r2b)
        sum_musc = (r1 - p1) + (r2 - p2)
        sum_r = (r1 - p11) + (r2 - p22)
        long_wrap = ad.dot(sum_r, sum_musc).v < 0.0
    else:
        n1a, _ = ad.normalize_or_zero(r1a - p11)
        n1b, _ = ad.normalize_or_zero(r1b - p11)
        n2a, _ = ad.normalize_or_zero(r2a - p22)
        n2b, _ = ad.normalize_or_zero(r2b - p22)
        dots = np.stack([ad.dot(n1a, n2a).v, ad.dot(n1a, n2b).v,
                         ad.dot(n1b, n2a).v, ad.dot(n1b, n2b).v], axis=-1)
        # OpenSim's if/else chain with strict '>' = first maximum among ties, checked in order
        pick = np.full(nf, 3)
        pick = np.where(dots[:, 2] > dots[:, 3], 2, pick)
        pick = np.where((dots[:, 1] > dots[:, 2]) & (dots[:, 1] > dots[:, 3]), 1, pick)
        pick = np.where((dots[:, 0] > dots[:, 1]) & (dots[:, 0] > dots[:, 2])
                        & (dots[:, 0] > dots[:, 3]), 0, pick)
        use_1a = (pick <= 1)[:, None]
        use_2a = ((pick == 0) | (pick == 2))[:, None]
        r1 = ad.where(use_1a, r1a, r1b)
        r2 = ad.where(use_2a, r2a, r2b)

    # apex on the cylinder between the points, in the plane through p1, p2 and the axis
    dn = np.array([0.0, 0.0, 1.0])
    t = d1 / (d1 + d2)
    mpt = p1 + (p2 - p1) * t.expand(-1)
    zero = 0.0 * mpt[:, 0]
    axispt = _vec(zero, zero, mpt[:, 2])
    l1, _ = ad.normalize_or_zero(p1 - axispt)
    l2, _ = ad.normalize_or_zero(p2 - axispt)
    pn, _ = ad.normalize_or_zero(ad.cross(l1, l2))
    vert1, _ = ad.normalize_or_zero(ad.cross(dn, pn))
    vert2, _ = ad.normalize_or_zero(ad.cross(pn, dn))
    apex1 = axispt + vert1 * radius[:, None]
    apex2 = axispt + vert2 * radius[:, None]
    first_closer = _dist2(mpt, apex1).v < _dist2(mpt, apex2).v
    use1 = np.where(far_side, ~first_closer, first_closer)
    apex = ad.where(use1[:, None], apex1, apex2)

    uu, _ = ad.normalize_or_zero(p1 - apex)
    vv, _ = ad.normalize_or_zero(p2 - apex)
    pn, _ = ad.normalize_or_zero(ad.cross(uu, vv))
    dpl = -ad.dot(p1, pn)
    r1 = _slide_to_plane(r1, pn, dpl, p11, p22)
    r2 = _slide_to_plane(r2, pn, dpl, p22, p11)

    half = 0.5 * length
    beyond = ((r1.v[:, 2] < -half) | (r1.v[:, 2] > half)) & ((r2.v[:, 2] < -half) | (r2.v[:, 2] > half))
    code[~done & beyond] = NO_WRAP
    done |= beyond

    r1, r2, arc = _spiral_path(p1, p2, r1, r2, long_wrap, radius, adjust_tangents, ~done)
    code[done & (code >= WRAPPED)] = NO_WRAP
    return code, r1, r2, arc


def _slide_to_plane(r, pn, dpl, p_own, p_other):
    """Slide a preliminary tangent point along the axis onto the plane (pn, dpl), as OpenSim."""
    dn = np.array([0.0, 0.0, 1.0])
    ra = r - dn * 10.0
    vec = np.array([0.0, 0.0, 20.0])
    dotprod = pn[:, 2] * 20.0
    ok = np.abs(dotprod.v) >= _LINE_EPSILON
    safe = ad.where(ok, dotprod, 1.0)
    t = (-dpl - ad.dot(pn, ra)) / safe
    ok &= (t.v >= -_LINE_EPSILON) & (t.v <= 1.0 + _LINE_EPSILON)
    rp = ra + t.expand(-1) * vec
    # OpenSim passes the other point p_other as the line *direction* here (kept as is)
    closest = closest_point_on_line(rp, p_own, p_other)
    accept = ok & (_dist2(closest, p_other).v < _dist2(p_own, p_other).v)
    return ad.where(accept[:, None], rp, r)


def wrap_cylinder(p1, p2, *, radius, length, quadrant="all", adjust_tangents=False):
    """Wrap segments p1->p2 over a WrapCylinder; lengths and their gradients.

    Parameters
    ----------
    p1, p2 : (F, 3) float
        End points in the cylinder frame (axis z, centre at the origin).
    radius, length : float
        Cylinder radius and length.
    quadrant : str
        OpenSim quadrant.
    adjust_tangents : bool
        See `cylinder_wrap_line`.

    Returns
    -------
    wrap_oracle.dual.SegmentWrap
        t1, t2 (F, 3), wrapped (F,), code (F,), arc (F,), length (F,), dl_dp1, dl_dp2 (F, 3).
    """
    return ad.segment_wrap(cylinder_wrap_line, p1, p2, radius=radius, length=length,
                           quadrant=quadrant, adjust_tangents=adjust_tangents)
