"""Numpy oracle of `motion.wrapping.sphere_torus_line.torus_line`: a segment over a WrapTorus.

OpenSim 4.6's ``WrapTorus::wrapLine`` (read from its public source for the facts; this is an
independent numpy implementation) does not compute a geodesic on the torus. It:

1. Finds a point on the line p1p2 "closest" to the torus' centre circle (radius
   ``outer_radius`` in the z = 0 plane), by driving the residual ``calcCircleResids`` to zero
   with MINPACK's lmdif from u = 0, once from p1 towards p2 and once from p2 towards p1. That
   residual is *not* the derivative of the distance to the circle: its circle term carries a
   factor 2 too many, so the stationary point found is the one for a circle of radius
   ``2 * outer_radius`` (one of OpenSim's torus oddities). With a quadrant, only results on the
   active side count; otherwise the pass with the smaller distance to the real circle wins.
   The line point is projected radially onto the circle: ``c``.
2. Puts a WrapCylinder of radius ``inner_radius`` and length 10000 at ``c``, its axis tangent
   to the circle and its +x axis pointing to the torus' centre, and wraps the segment over it
   with the cylinder's algorithm (quadrant "+x" set on an object that is never finalised, so
   OpenSim's cylinder sees no quadrant constraint -- the live-OpenSim tests check which).
3. Returns ``wrapped`` whenever step 1 succeeds; a cylinder that does not wrap leaves no
   wrap points, so the path does not wrap.

Differences from OpenSim: lmdif stops at a relative tolerance of 1e-4 while this solves the
same residual to machine precision with Newton's method, so tangent points and lengths differ
by up to about that tolerance times the segment length (reported in the tests).
"""
from __future__ import annotations

import numpy as np

from . import dual as ad
from .dual import Dual
from .cylinder import NO_WRAP, WRAPPED, cylinder_wrap_line, dsign, quadrant_axis_sign

__all__ = ["wrap_torus", "torus_wrap_line"]

_CYL_LENGTH = 10000.0


def _circle_parameter(p1, p2, radius):
    """Root of OpenSim's calcCircleResids along p1 -> p2 from u = 0 (Newton, all frames)."""
    n, _ = ad.normalize_or_zero(p2 - p1)
    c2 = ad.dot(p1, n) * 2.0
    c3 = p1[:, 0] * n[:, 0] + p1[:, 1] * n[:, 1]
    c4 = n[:, 0] * n[:, 0] + n[:, 1] * n[:, 1]
    c5 = p1[:, 0] * p1[:, 0] + p1[:, 1] * p1[:, 1]
    u = Dual(np.zeros(p1.shape[0]))
    active = np.ones(p1.shape[0], dtype=bool)
    for _ in range(100):
        c6 = ad.sqrt(u * u * c4 + u * c3 * 2.0 + c5)
        g = c4 * u + c3
        res = c2 + u * 2.0 - g * (4.0 * radius) / c6
        dres = 2.0 - (c4 * c6 - g * g / c6) * (4.0 * radius) / (c6 * c6)
        step = res / dres
        active = active & (np.abs(step.v) > 1e-15 * (1.0 + np.abs(u.v)))
        u = ad.where(active, u - step, u)
        if not active.any():
            break
    point = p1 + n * u.expand(-1)
    return point


def torus_wrap_line(p1, p2, *, inner_radius, outer_radius, quadrant="all", adjust_tangents=True,
                    cylinder_quadrant="all"):
    """OpenSim's WrapTorus::wrapLine on frames, in the torus frame (axis z, centre at 0).

    Parameters
    ----------
    p1, p2 : (F, 3) float or Dual
    inner_radius, outer_radius : float
        Tube radius and centre-circle radius.
    quadrant : str
        Quadrant of the torus (chooses between the two passes of step 1).
    adjust_tangents : bool
        Passed to the cylinder (False for a path with a single wrap object).
    cylinder_quadrant : str
        Quadrant the internal cylinder effectively uses (see the module docstring).

    Returns
    -------
    code : (F,) int
    r1, r2 : (F, 3) Dual
    arc : (F,) Dual
    """
    p1, p2 = ad.lift(p1), ad.lift(p2)
    axis, sign = quadrant_axis_sign(quadrant)
    radius = float(outer_radius)
    a1 = _circle_parameter(p1, p2, radius)
    a2 = _circle_parameter(p2, p1, radius)

    def dist(p):
        rho = ad.sqrt(p[:, 0] * p[:, 0] + p[:, 1] * p[:, 1])
        return ad.sqrt(ad.dot(p, p) + radius * radius - rho * (2.0 * radius)).v

    d1, d2 = dist(a1), dist(a2)
    nf = p1.shape[0]
    ok = np.ones(nf, dtype=bool)
    if sign != 0:
        on1, on2 = dsign(a1[:, axis]) == sign, dsign(a2[:, axis]) == sign
        use2 = np.where(on1 & on2, ~(d1 < d2), ~on1 & on2)
        ok = on1 | on2
    else:
        use2 = ~(d1 < d2)
    a = ad.where(use2[:, None], a2, a1)
    rho = ad.sqrt(a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1])
    zero = 0.0 * rho
    closest = ad.stack([a[:, 0] * radius / rho, a[:, 1] * radius / rho, zero])
    # cylinder frame: x towards the torus centre, y = -z_torus, z = x cross y
    cx, _ = ad.normalize_or_zero(-closest)
    cy = np.array([0.0, 0.0, -1.0])
    cz = ad.cross(cx, cy)
    rows = [cx, ad.lift(np.broadcast_to(cy, cx.shape)), cz]
    shift = ad.stack([ad.dot(r, -closest) for r in rows])

    def to_cyl(p):
        return ad.stack([ad.dot(r, p) for r in rows]) + shift

    def from_cyl(q):
        q = q - shift
        return cx * q[:, 0].expand(-1) + cy * q[:, 1].expand(-1) + cz * q[:, 2].expand(-1)

    code, r1, r2, arc = cylinder_wrap_line(to_cyl(p1), to_cyl(p2), radius=float(inner_radius),
                                           length=_CYL_LENGTH, quadrant=cylinder_quadrant,
                                           adjust_tangents=adjust_tangents)
    wrapped = ok & (code >= WRAPPED)
    out = np.where(wrapped, WRAPPED, NO_WRAP)
    return out, from_cyl(r1), from_cyl(r2), arc


def wrap_torus(p1, p2, *, inner_radius, outer_radius, quadrant="all", adjust_tangents=False,
               cylinder_quadrant="all"):
    """Wrap segments p1->p2 over a WrapTorus; tangent points, lengths and exact gradients.

    Parameters
    ----------
    p1, p2 : (F, 3) float
        End points in the torus frame.
    inner_radius, outer_radius : float
    quadrant : str
    adjust_tangents : bool
        False reproduces a path with this torus as its only wrap object.
    cylinder_quadrant : str

    Returns
    -------
    wrap_oracle.dual.SegmentWrap
    """
    return ad.segment_wrap(torus_wrap_line, p1, p2, inner_radius=inner_radius,
                           outer_radius=outer_radius, quadrant=quadrant,
                           adjust_tangents=adjust_tangents, cylinder_quadrant=cylinder_quadrant)
