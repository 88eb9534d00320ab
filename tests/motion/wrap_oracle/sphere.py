"""Numpy oracle of `motion.wrapping.sphere_torus_line.sphere_line`: a segment over a WrapSphere.

Reproduces OpenSim 4.6 ``WrapSphere::wrapLine`` (Peter Loan, from SIMM), read from OpenSim's
public source for the facts; an independent numpy implementation:

1. No wrap if an end point is inside the sphere (``insideRadius``), or if the straight
   segment does not pass through the sphere (both intersection parameters in (0, 1)).
2. Tangent-point candidates: for each end point P, the two points where the plane through the
   centre, p1 and p2 touches the tangent cone from P (angle ``asin(R/|P|)``). The pair whose
   unit vectors from the centre are most parallel is chosen (the short great-circle arc).
3. With a quadrant (``x``, ``-y`` ...): a segment crossing the sphere with an end point on the
   active side is a ``mandatoryWrap`` if the segment's closest point to the centre is within R
   and its parameter -- OpenSim compares a distance in metres with (0, 1) here -- is in (0, 1);
   otherwise it wraps only if the end points are on opposite sides and that closest point is
   on the inactive side. Unless both end points are on the active side, the tangent points are
   chosen facing the active side, and a far-side (long way round) wrap is detected.
4. Arc length ``R * angle``; for a far-side wrap OpenSim uses ``-(2 pi - angle)``, i.e. a
   *negative* arc length. That is what OpenSim 4.6 does, and it is reproduced.

The degenerate case of a segment through the centre (OpenSim then reuses the previous frame's
tangent points) returns no wrap here.
"""
from __future__ import annotations

import numpy as np

from . import dual as ad
from .cylinder import INSIDE_RADIUS, MANDATORY_WRAP, NO_WRAP, WRAPPED, dsign, quadrant_axis_sign

__all__ = ["wrap_sphere", "sphere_wrap_line"]


def _candidates(p, n, radius):
    """Two tangent-point candidates from end point ``p`` in the plane with normal ``n``."""
    y, dist = ad.normalize_or_zero(-p)
    z = ad.cross(n, y)
    a = ad.arcsin(radius / dist)
    ca, sa = ad.cos(a), ad.sin(a)
    scale = (dist * ca).expand(-1)
    ra = p + (y * ca.expand(-1) - z * sa.expand(-1)) * scale
    rb = p + (y * ca.expand(-1) + z * sa.expand(-1)) * scale
    return ra, rb


def sphere_wrap_line(p1, p2, *, radius, quadrant="all"):
    """OpenSim's WrapSphere::wrapLine on frames, in the sphere's own frame (centre at 0).

    Parameters
    ----------
    p1, p2 : (F, 3) float or Dual
        Segment end points in the wrap frame.
    radius : float
    quadrant : str

    Returns
    -------
    code : (F,) int
    r1, r2 : (F, 3) Dual
        Tangent points.
    arc : (F,) Dual
        Signed arc length (negative for far-side wraps, as OpenSim).
    """
    p1, p2 = ad.lift(p1), ad.lift(p2)
    axis, sign = quadrant_axis_sign(quadrant)
    nf = p1.shape[0]
    code = np.full(nf, WRAPPED, dtype=int)
    done = np.zeros(nf, dtype=bool)

    inside = (ad.norm(p1).v < radius) | (ad.norm(p2).v < radius)
    code[inside] = INSIDE_RADIUS
    done |= inside

    ri = p1 - p2
    mp = -p2
    a = ad.dot(ri, ri)
    b = ad.dot(mp, ri) * -2.0
    c = ad.dot(mp, mp) - radius * radius
    disc = b * b - a * c * 4.0
    root = np.sqrt(np.maximum(disc.v, 0.0))
    l1 = (-b.v + root) / (2.0 * a.v)
    l2 = (-b.v - root) / (2.0 * a.v)
    miss = (disc.v < 0.0) | ~((0.0 < l1) & (l1 < 1.0)) | ~((0.0 < l2) & (l2 < 1.0)) | (l1 < l2)
    code[~done & miss] = NO_WRAP
    done |= miss

    u12, _ = ad.normalize_or_zero(p1 - p2)
    np2, _ = ad.normalize_or_zero(p2)
    hp2 = ad.cross(u12, np2)
    degenerate = ad.norm(hp2).v < 1e-5
    code[~done & degenerate] = NO_WRAP
    done |= degenerate

    n, _ = ad.normalize_or_zero(hp2)
    r1a, r1b = _candidates(p1, n, radius)
    r2a, r2b = _candidates(p2, n, radius)
    n1a, _ = ad.normalize_or_zero(r1a)
    n1b, _ = ad.normalize_or_zero(r1b)
    n2a, _ = ad.normalize_or_zero(r2a)
    n2b, _ = ad.normalize_or_zero(r2b)
    j = np.stack([ad.dot(n1a, n2a).v, ad.dot(n1a, n2b).v,
                  ad.dot(n1b, n2a).v, ad.dot(n1b, n2b).v], axis=-1)
    pick = np.full(nf, 3)
    pick = np.where(j[:, 2] > j[:, 3], 2, pick)
    pick = np.where((j[:, 1] > j[:, 2]) & (j[:, 1] > j[:, 3]), 1, pick)
    pick = np.where((j[:, 0] > j[:, 1]) & (j[:, 0] > j[:, 2]) & (j[:, 0] > j[:, 3]), 0, pick)
    first_a = pick <= 1
    second_a = (pick == 0) | (pick == 2)
    r1 = ad.where(first_a[:, None], r1a, r1b)
    r2 = ad.where(second_a[:, None], r2a, r2b)
    r11 = ad.where(first_a[:, None], r1b, r1a)
    r22 = ad.where(second_a[:, None], r2b, r2a)
    far = np.zeros(nf, dtype=bool)

    if sign != 0:
        s1, s2 = dsign(p1[:, axis]), dsign(p2[:, axis])
        either = (s1 == sign) | (s2 == sign)
        # closest point of the line to the centre; OpenSim's "tt" is a distance (see docstring)
        tt = ad.dot(-p1, -u12)
        mm = p1 + (-u12) * tt.expand(-1)
        mand = (ad.dot(mm, mm).v < radius * radius) & (tt.v > 0.0) & (tt.v < 1.0)
        maybe = (s1 != s2) & (dsign(mm[:, axis]) != sign)
        code[~done & either & mand] = MANDATORY_WRAP
        stop = either & ~mand & ~maybe
        code[~done & stop] = NO_WRAP
        done |= stop

        face = (s1 != sign) | (s2 != sign)
        sm, _ = ad.normalize_or_zero(-p1 - p2)
        take1a = ad.dot(n1a, sm).v > ad.dot(n1b, sm).v
        take2a = ad.dot(n2a, sm).v > ad.dot(n2b, sm).v
        c1 = ad.where(take1a[:, None], r1a, r1b)
        o1 = ad.where(take1a[:, None], r1b, r1a)
        c2 = ad.where(take2a[:, None], r2a, r2b)
        o2 = ad.where(take2a[:, None], r2b, r2a)
        sm2, _ = ad.normalize_or_zero((c1 - p1) + (c2 - p2))
        flip = sm2.v[:, axis] * sign < 0.0
        c1, c2 = ad.where(flip[:, None], o1, c1), ad.where(flip[:, None], o2, c2)
        r1 = ad.where(face[:, None], c1, r1)
        r2 = ad.where(face[:, None], c2, r2)
        sum_musc = (r1 - p1) + (r2 - p2)
        sum_r = r1 + r2
        far = face & (ad.dot(sum_r, sum_musc).v < 0.0)
        del r11, r22

    r1n, _ = ad.normalize_or_zero(r1)
    r2n, _ = ad.normalize_or_zero(r2)
    cosang = ad.dot(r1n, r2n)
    cosang = ad.where(np.abs(cosang.v) <= 1.0, cosang, np.sign(cosang.v))
    angle = ad.arccos(cosang)
    angle = ad.where(far, (2.0 * np.pi - angle) * -1.0, angle)
    return code, r1, r2, angle * radius


def wrap_sphere(p1, p2, *, radius, quadrant="all"):
    """Wrap segments p1->p2 over a WrapSphere; tangent points, lengths and exact gradients.

    Parameters
    ----------
    p1, p2 : (F, 3) float
        End points in the sphere frame.
    radius : float
    quadrant : str

    Returns
    -------
    wrap_oracle.dual.SegmentWrap
    """
    return ad.segment_wrap(sphere_wrap_line, p1, p2, radius=radius, quadrant=quadrant)
