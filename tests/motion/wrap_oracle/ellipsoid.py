"""Numpy oracle of `motion.wrapping.ellipsoid_line`: a path segment over an OpenSim WrapEllipsoid.

Reproduces OpenSim 4.6 ``WrapEllipsoid::wrapLine`` (Peter Loan, Frans van der Helm's method,
from SIMM), read from OpenSim's public source for the facts; an independent numpy
implementation of the same steps:

1. All coordinates are scaled by ``3 / (a + b + c)``. No wrap if an end point is inside the
   ellipsoid (``insideRadius``), if p1 and p2 are seen in the same direction from the centre,
   or if the straight *segment* does not pass through the ellipsoid: an ellipsoid wraps only
   when penetrated, and then it is always a ``mandatoryWrap``.
2. The wrapping plane contains p1, p2 and a surface point c1 found from the chord r1r2 (the
   segment's intersections with the ellipsoid), depending on ``method``:
   ``axial`` (Frans' technique: c1 = closest surface point to where the chord crosses the
   plane normal to the most parallel axis), ``midpoint`` (closest point to the chord's
   midpoint), or ``hybrid`` (the default: Frans' technique faded into the "fan" technique --
   the average direction from 298 chord samples to their closest surface points -- between
   ``|cos| = 0.7073`` and ``0.9``). Closest points use Eberly's Newton iteration (Graphics
   Gems IV), with OpenSim's 2-D special case near the coordinate planes.
3. With a quadrant, c1 is mirrored to the active side (and, for fan solutions, pulled towards
   the bisecting plane) -- OpenSim's exact rules, including its quirk that a pure Frans
   solution is never pulled.
4. The tangent points r1, r2 start at c1 and are moved within the plane by OpenSim's damped
   Gauss-Newton iteration (``calcTangentPoint``, stopping at a squared residual of 1e-8).
5. The arc is the polyline of ``int(|r1 r2| / 1 mm)`` pieces (at most 499) obtained by rotating
   in the plane about a point of it on the axis most normal to the plane and projecting onto
   the ellipsoid; its length is the sum of the pieces (as OpenSim; short chords < 1 mm count
   straight). A quadrant-constrained wrap that starts the wrong way is redone the far way.

Everything runs on `wrap_oracle.dual.Dual` arrays; the derivative is the exact derivative
of this (iterative, piecewise smooth) function.
"""
from __future__ import annotations

import numpy as np

from . import dual as ad
from .dual import Dual
from .cylinder import INSIDE_RADIUS, MANDATORY_WRAP, NO_WRAP, dsign, quadrant_axis_sign

__all__ = ["wrap_ellipsoid", "ellipsoid_wrap_line", "closest_point_on_ellipsoid"]

# OpenSim's constants of the algorithm, shared with the compiled implementation under test
from motion.wrapping.ellipsoid_closest import _FAN, _ROUNDOFF  # noqa: E402
from motion.wrapping.ellipsoid_line import _MU_MAX, _MU_MIN, _TINY  # noqa: E402
_SV_BLEND = 0.3
METHODS = ("hybrid", "midpoint", "axial")


def _near0(x) -> np.ndarray:
    return np.abs(ad.value(x)) <= _ROUNDOFF


def _closest_on_ellipse(a, b, u, v):
    """Eberly's closest point on the ellipse (x/a)^2 + (y/b)^2 = 1 to (u, v); OpenSim's cases."""
    u, v = ad.lift(u), ad.lift(v)
    a2, b2 = a * a, b * b
    near_x, near_y = _near0(u), _near0(v)
    a2u2, b2v2 = u * u * a2, v * v * b2
    inside = (u.v / a) ** 2 + (v.v / b) ** 2 < 1.0
    t = ad.where(inside, 0.0, ad.sqrt(u * u + v * v) * max(a, b))
    active = ~(near_x | near_y)
    p_fin, q_fin = t + a2, t + b2
    for _ in range(64):
        if not active.any():
            break
        p, q = t + a2, t + b2
        f = p * p * q * q - a2u2 * q * q - b2v2 * p * p
        p_fin = ad.where(active, p, p_fin)
        q_fin = ad.where(active, q, q_fin)
        conv = active & (np.abs(f.v) < 1e-9)
        active = active & ~conv
        fp = (p * q * (p + q) - a2u2 * q - b2v2 * p) * 2.0
        t = ad.where(active, t - f / fp, t)
    x = u * a2 / p_fin
    y = v * b2 / q_fin
    # near the y axis (u == 0)
    alt_y_on = (a >= b) | (np.abs(v.v) >= b - a2 / b)
    y_b = ad.where(alt_y_on, ad.where(v.v >= 0, b, -b), v * b2 / (b2 - a2))
    x_b = ad.where(alt_y_on, u, ad.sqrt(_abs(1.0 - (y_b / b) * (y_b / b))) * a)
    # near the x axis (v == 0)
    alt_x_on = (b >= a) | (np.abs(u.v) >= a - b2 / a)
    x_c = ad.where(alt_x_on, ad.where(u.v >= 0, a, -a), u * a2 / (a2 - b2))
    y_c = ad.where(alt_x_on, v, ad.sqrt(_abs(1.0 - (x_c / a) * (x_c / a))) * b)
    # near both
    x_d = ad.where(a < b, ad.where(u.v < 0, -a, a), u)
    y_d = ad.where(a < b, v, ad.where(v.v < 0, -b, b))
    only_x = near_x & ~near_y
    only_y = near_y & ~near_x
    both = near_x & near_y
    x = ad.where(both, x_d, ad.where(only_x, x_b, ad.where(only_y, x_c, x)))
    y = ad.where(both, y_d, ad.where(only_x, y_b, ad.where(only_y, y_c, y)))
    return x, y


def _abs(x: Dual) -> Dual:
    return ad.where(x.v >= 0, x, -x)


def closest_point_on_ellipsoid(radii, u, v, w, *, special_axis=None, dims_for_ties=None):
    """OpenSim WrapEllipsoid::findClosestPoint on arrays (Eberly, Graphics Gems IV).

    Parameters
    ----------
    radii : (3,) float
        Semi-axes a, b, c.
    u, v, w : (...) float or Dual
        Query point coordinates.
    special_axis : int or None
        Force OpenSim's 2-D reduction about this axis (the Frans technique); None detects
        points on a coordinate plane as OpenSim does.
    dims_for_ties : (3,) float, optional
        Dimensions used to pick among several coordinate planes (OpenSim uses the unscaled
        dimensions here).

    Returns
    -------
    x, y, z : Dual
    """
    a, b, c = (float(r) for r in radii)
    u, v, w = ad.lift(u), ad.lift(v), ad.lift(w)
    if special_axis == 0:
        y, z = _closest_on_ellipse(b, c, v, w)
        return u, y, z
    if special_axis == 1:
        z, x = _closest_on_ellipse(c, a, w, u)
        return x, v, z
    if special_axis == 2:
        x, y = _closest_on_ellipse(a, b, u, v)
        return x, y, w
    dims = np.asarray(radii if dims_for_ties is None else dims_for_ties, dtype=float)
    shape = np.broadcast_shapes(u.shape, v.shape, w.shape)
    axis = np.full(shape, -1)
    best = np.full(shape, np.inf)
    for i, comp in enumerate((u, v, w)):
        s = dims.sum() - dims[i]
        take = _near0(comp) & (best > s)
        axis = np.where(take, i, axis)
        best = np.where(take, s, best)
    # general case
    a2, b2, c2 = a * a, b * b, c * c
    a2u2, b2v2, c2w2 = u * u * a2, v * v * b2, w * w * c2
    inside = (u.v / a) ** 2 + (v.v / b) ** 2 + (w.v / c) ** 2 < 1.0
    t = ad.where(inside, 0.0, ad.sqrt(u * u + v * v + w * w) * max(a, b, c))
    active = np.broadcast_to(axis < 0, shape).copy()
    t_fin = t
    for _ in range(64):
        if not active.any():
            break
        p, q, r = t + a2, t + b2, t + c2
        p2, q2, r2 = p * p, q * q, r * r
        f = p2 * q2 * r2 - a2u2 * q2 * r2 - b2v2 * p2 * r2 - c2w2 * p2 * q2
        conv = active & (np.abs(f.v) < 1e-9)
        t_fin = ad.where(conv, t, t_fin)
        active = active & ~conv
        pq, pr, qr = p * q, p * r, q * r
        fp = (pq * r * (qr + pr + pq) - a2u2 * qr * (q + r) - b2v2 * pr * (p + r)
              - c2w2 * pq * (p + q)) * 2.0
        t = ad.where(active, t - f / fp, t)
    t_fin = ad.where(active, t, t_fin)
    x = u * a2 / (t_fin + a2)
    y = v * b2 / (t_fin + b2)
    z = w * c2 / (t_fin + c2)
    if (axis >= 0).any():
        for i in range(3):
            m = axis == i
            if m.any():
                xs, ys, zs = closest_point_on_ellipsoid(radii, u, v, w, special_axis=i)
                x, y, z = ad.where(m, xs, x), ad.where(m, ys, y), ad.where(m, zs, z)
    return x, y, z


def _closest3(radii, p, special_axis=None, dims=None) -> Dual:
    x, y, z = closest_point_on_ellipsoid(radii, p[..., 0], p[..., 1], p[..., 2],
                                         special_axis=special_axis, dims_for_ties=dims)
    return ad.stack([x, y, z])


def _residuals(r1, d1, p1, a, vs, vs4):
    """OpenSim calcTangentPoint's four residuals (values only) and nr1."""
    nr1 = r1 * (2.0 / (a * a))
    e0 = ad.dot(vs, r1) + vs4
    e1 = ad.dot(r1 / a, r1 / a) - 1.0
    e2 = ad.dot(nr1, r1) + d1
    e3 = ad.dot(nr1, p1) + d1
    return ad.stack([e0, e1, e2, e3])


def _tangent_point(pe, r1, p1, a, vs, vs4):
    """OpenSim WrapEllipsoid::calcTangentPoint (damped Gauss-Newton) on all frames, masked."""
    nf = r1.shape[0]
    nr1 = r1 * (2.0 / (a * a))
    d1 = -ad.dot(nr1, r1)
    ee = _residuals(r1, d1, p1, a, vs, vs4)
    ssq = (ee.v ** 2).sum(-1)
    ssqo = ssq.copy()
    alpha = np.full(nf, 0.01)
    nit = 0
    outer = (np.abs(pe.v) >= 1e-4) & (ssq > _TINY)
    p1n, _ = ad.normalize_or_zero(p1)
    while outer.any() and nit < 50:
        nit += 1
        # dedth[i][j]: rows i = r1 x, y, z, d1; columns j = residuals 0..3
        zero = 0.0 * vs[:, 0]
        rows = [ad.stack([vs[:, i], r1[:, i] * (2.0 / a[i] ** 2), r1[:, i] * (4.0 / a[i] ** 2),
                          p1[:, i] * (2.0 / a[i] ** 2)]) for i in range(3)]
        rows.append(ad.stack([zero, zero, zero + 1.0, zero + 1.0]))
        dedth = _stack_rows(rows)  # (F, 4, 4)
        p1r1, _ = ad.normalize_or_zero(p1 - r1)
        pcos = ad.dot(p1r1, p1n)
        dd = ad.where(pcos.v > 0.1, 1.0 - pcos ** 100, 1.0)
        v = -(dedth * ee.expand(-2)).sum(-1)  # (F, 4)
        dedth2 = (dedth.expand(-2) * dedth.expand(-3)).sum(-1)  # (F, 4, 4)
        diag = np.einsum("fii->fi", dedth2.v)
        eye = np.eye(4)
        vt = Dual(np.zeros((nf, 4)))
        loop = outer.copy()
        nit2 = 0
        while loop.any():
            damp = Dual(dedth2.v * (1 - eye) + eye * (diag * (1.0 + alpha[:, None]))[:, :, None],
                        dedth2.d * (1 - eye)[..., None] + eye[..., None]
                        * (np.einsum("fiid->fid", dedth2.d) * (1.0 + alpha[:, None, None]))[:, :, None, :])
            step = ad.solve(damp, v) * (dd / 16.0).expand(-1)
            vt = ad.where(loop[:, None], step, vt)
            r1 = ad.where(loop[:, None], r1 + step[:, :3], r1)
            d1 = ad.where(loop, d1 + step[:, 3], d1)
            ee_new = _residuals(r1, d1, p1, a, vs, vs4)
            new = (ee_new.v ** 2).sum(-1)
            ssqo = np.where(loop, ssq, ssqo)
            ssq = np.where(loop, new, ssq)
            ee = ad.where(loop[:, None], ee_new, ee)
            alpha = np.where(loop, alpha * 4.0, alpha)
            nit2 += 1
            loop = loop & (ssq >= ssqo) & (nit2 < 1000)
        alpha = np.where(outer, alpha / 8.0, alpha)
        fakt = np.full(nf, 0.5)
        loop = outer & (ssq <= ssqo)
        nit2 = 0
        while loop.any():
            fakt = np.where(loop, fakt * 2.0, fakt)
            r1 = ad.where(loop[:, None], r1 + vt[:, :3] * fakt[:, None], r1)
            d1 = ad.where(loop, d1 + vt[:, 3] * fakt, d1)
            ee_new = _residuals(r1, d1, p1, a, vs, vs4)
            new = (ee_new.v ** 2).sum(-1)
            ssqo = np.where(loop, ssq, ssqo)
            ssq = np.where(loop, new, ssq)
            nit2 += 1
            loop = loop & (ssq <= ssqo) & (nit2 < 1000)
        r1 = ad.where(outer[:, None], r1 - vt[:, :3] * fakt[:, None], r1)
        d1 = ad.where(outer, d1 - vt[:, 3] * fakt, d1)
        ee_new = _residuals(r1, d1, p1, a, vs, vs4)
        ee = ad.where(outer[:, None], ee_new, ee)
        new = (ee_new.v ** 2).sum(-1)
        ssq = np.where(outer, new, ssq)
        ssqo = np.where(outer, new, ssqo)
        outer = outer & (ssq > _TINY)
    return ad.where((np.abs(pe.v) < 1e-4)[:, None], p1, r1)


def _stack_rows(rows) -> Dual:
    """Stack row Duals (F, 4) into (F, 4, 4)."""
    v = np.stack([r.v for r in rows], axis=1)
    nd = ad.dsize(*rows)
    d = np.stack([np.broadcast_to(r.d, r.v.shape + (nd,)) for r in rows], axis=1)
    return Dual(v, d)


def _arc(r1, r2, a, vs, vs4, factor, far):
    """OpenSim CalcDistanceOnEllipsoid: polyline length and its 2nd / second-to-last points."""
    nf = r1.shape[0]
    chord = ad.norm(r1 - r2) / factor
    short = chord.v < 0.001
    nseg = np.clip((chord.v / 0.001).astype(int), 1, 499)
    nseg = np.where(short, 1, nseg)
    imax = np.argmax(np.abs(vs.v), axis=1)  # first maximum, as OpenSim's strict '>'
    fr = np.arange(nf)
    mu = -vs4 / vs[fr, imax]
    onehot = np.eye(3)[imax]
    a0 = mu.expand(-1) * onehot
    ar1, _ = ad.normalize_or_zero(r1 - a0)
    ar2, _ = ad.normalize_or_zero(r2 - a0)
    c = ad.dot(ar1, ar2)
    c = ad.where(np.abs(c.v) <= 1.0, c, np.sign(c.v))
    phi0 = ad.arccos(c)
    dphi = ad.where(far, (2.0 * np.pi - phi0) * -1.0, phi0) / nseg
    vsz, _ = ad.normalize_or_zero(ad.cross(ar1, ar2))
    vsy = ad.cross(vsz, ar1)
    kmax = int(nseg.max())
    k = np.arange(1, kmax)  # interior point numbers 1..N-1
    phi = dphi.expand(-1) * k  # (F, K)
    r = ar1.expand(-2) * ad.cos(phi).expand(-1) + vsy.expand(-2) * ad.sin(phi).expand(-1)
    f1 = r / a
    f2 = (a0 / a).expand(-2)
    aa = ad.dot(f1, f1)
    bb = ad.dot(f1, f2) * 2.0
    cc = ad.dot(f2, f2) - 1.0
    mu3 = (-bb + ad.sqrt(bb * bb - aa * cc * 4.0)) / (aa * 2.0)
    s = a0.expand(-2) + r * mu3.expand(-1)  # (F, K, 3)
    # polyline r1, s_1..s_{N-1}, r2 ; pad beyond N with r2
    kk = np.arange(kmax + 1)[None, :]
    pts_v = np.concatenate([r1.v[:, None], s.v, r2.v[:, None]], axis=1)
    nd = ad.dsize(r1, s, r2)
    bd = lambda x: np.broadcast_to(x.d, x.v.shape + (nd,))  # noqa: E731
    pts_d = np.concatenate([bd(r1)[:, None], bd(s), bd(r2)[:, None]], axis=1)
    pts = Dual(pts_v, pts_d)
    beyond = kk >= nseg[:, None]
    pts = ad.where(beyond[..., None], r2.expand(-2), pts)
    seg = ad.norm(pts[:, 1:] - pts[:, :-1])
    length = seg.sum(-1)
    length = ad.where(short, chord * factor, length)
    w1 = pts[:, 1]
    w2 = pts[fr, np.maximum(nseg - 1, 0)]
    return length, w1, w2, (~short) & (nseg >= 2)


def ellipsoid_wrap_line(p1, p2, *, dimensions, quadrant="all", method="hybrid"):
    """OpenSim's WrapEllipsoid::wrapLine on frames, in the ellipsoid's own frame.

    Parameters
    ----------
    p1, p2 : (F, 3) float or Dual
        End points in the wrap frame (ellipsoid centred at the origin, axes along x, y, z).
    dimensions : (3,) float
        Semi-axes.
    quadrant : str
    method : {"hybrid", "midpoint", "axial"}

    Returns
    -------
    code : (F,) int
    r1, r2 : (F, 3) Dual
    arc : (F,) Dual
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    dims = np.asarray(dimensions, dtype=float)
    p1, p2 = ad.lift(p1), ad.lift(p2)
    axis, sign = quadrant_axis_sign(quadrant)
    nf = p1.shape[0]
    factor = 3.0 / dims.sum()
    a = dims * factor
    q1, q2 = p1 * factor, p2 * factor
    p1e = ad.dot(q1 / a, q1 / a) - 1.0
    p2e = ad.dot(q2 / a, q2 / a) - 1.0
    code = np.full(nf, MANDATORY_WRAP, dtype=int)
    inside = (p1e.v < -0.0001) | (p2e.v < -0.0001)
    code[inside] = INSIDE_RADIUS
    d12 = q1 - q2
    n1, _ = ad.normalize_or_zero(q1)
    n2, _ = ad.normalize_or_zero(q2)
    collinear = np.abs(ad.dot(n1, n2).v - 1.0) < 0.0001
    f1 = d12 / a
    f2 = q2 / a
    aa = ad.dot(f1, f1)
    bb = ad.dot(f1, f2) * 2.0
    cc = ad.dot(f2, f2) - 1.0
    disc = bb * bb - aa * cc * 4.0
    root = ad.sqrt(ad.where(disc.v >= 0, disc, 0.0))
    l1 = (-bb + root) / (aa * 2.0)
    l2 = (-bb - root) / (aa * 2.0)
    miss = (disc.v < 0) | ~((0 < l1.v) & (l1.v < 1)) | ~((0 < l2.v) & (l2.v < 1))
    code[~inside & (collinear | miss)] = NO_WRAP
    r1 = Dual(np.full((nf, 3), np.nan))
    r2 = Dual(np.full((nf, 3), np.nan))
    arc = Dual(np.zeros(nf))
    sel = np.nonzero(code == MANDATORY_WRAP)[0]
    if sel.size == 0:
        return code, r1, r2, arc
    s1, s2, sa = _rows(q1, sel), _rows(q2, sel), _rows(d12, sel)
    i1 = s2 + sa * _rows(l1, sel).expand(-1)
    i2 = s2 + sa * _rows(l2, sel).expand(-1)
    t1, t2, length = _wrap_subset(s1, s2, sa, i1, i2, _rows(p1e, sel), _rows(p2e, sel),
                                  a, dims, axis, sign, method, factor)
    r1 = ad.scatter(r1, sel, t1 / factor)
    r2 = ad.scatter(r2, sel, t2 / factor)
    arc = ad.scatter(arc, sel, length / factor)
    return code, r1, r2, arc


def _rows(x: Dual, sel) -> Dual:
    return Dual(x.v[sel], x.d[sel])


def _wrap_subset(p1, p2, p1p2, r1, r2, p1e, p2e, a, dims, axis, sign, method, factor):
    """Steps 2-5 of the module docstring on the frames that wrap (scaled coordinates)."""
    nf = p1.shape[0]
    fr = np.arange(nf)
    r1r2 = r2 - r1
    mu_vec, _ = ad.normalize_or_zero(p1p2)
    mu = _abs(mu_vec)  # (F, 3), with derivatives: the blend weights below depend on it
    t = -r1 / r1r2  # (F, 3): chord parameter where coordinate i is zero
    t_sv = [r1 + r1r2 * t[:, i].expand(-1) for i in range(3)]
    t_c1 = [_closest3(a, t_sv[i], special_axis=i) for i in range(3)]
    best = np.zeros(nf, dtype=int)
    for i in (1, 2):
        best = np.where(mu.v[fr, i] > mu.v[fr, best], i, best)
    mu_b = mu[fr, best]
    t_b = t[fr, best]
    sv_f = _pick(t_sv, best)
    c1_f = _pick(t_c1, best)
    # fan weight: None (OpenSim's -infinity: no fan solution) or a Dual (F,) with a mask
    has_fan = np.zeros(nf, dtype=bool)
    fan_weight = Dual(np.zeros(nf))
    if method in ("hybrid", "axial"):
        if method == "hybrid":
            tb = t_b.v
            s = ad.lift(np.ones(nf))
            s = ad.where(tb > 1.0 - _SV_BLEND, (1.0 - t_b) / _SV_BLEND, s)
            s = ad.where(tb < _SV_BLEND, t_b / _SV_BLEND, s)
            s = ad.where((tb < 0.0) | (tb > 1.0), 0.0, s)
            blend = (mu_b.v > _MU_MIN) & (s.v < 1.0)
            mu_b = ad.where(blend, (mu_b - _MU_MIN) * s + _MU_MIN, mu_b)
        use_frans = np.full(nf, method == "axial") | (mu_b.v > _MU_MIN)
        c1 = ad.where(use_frans[:, None], c1_f, Dual(np.full((nf, 3), np.nan)))
        sv = ad.where(use_frans[:, None], sv_f, Dual(np.full((nf, 3), np.nan)))
        if method == "hybrid":
            fan = mu_b.v < _MU_MAX
            if fan.any():
                mid = r1 + r1r2 * 0.5
                tt = np.arange(1, _FAN - 1) / _FAN
                samples = r1.expand(-2) + r1r2.expand(-2) * tt[None, :, None]
                close = _closest3(a, samples, dims=dims)
                blade, _ = ad.normalize_or_zero(close - samples)
                vsum, _ = ad.normalize_or_zero(blade.sum(-2))
                c_fan = _closest3(a, mid + vsum)
                w = (mu_b - _MU_MIN) / (_MU_MAX - _MU_MIN)
                pure = mu_b.v <= _MU_MIN
                mixed = c1 * w.expand(-1) + c_fan * (1.0 - w).expand(-1)
                sv_mixed = sv * w.expand(-1) + mid * (1.0 - w).expand(-1)
                c_mixed = _closest3(a, ad.where(pure[:, None], c_fan, mixed))
                c1 = ad.where(fan[:, None], ad.where(pure[:, None], c_fan, c_mixed), c1)
                sv = ad.where(fan[:, None], ad.where(pure[:, None], mid, sv_mixed), sv)
                fan_weight = ad.where(fan, ad.where(pure, 1.0, 1.0 - w), fan_weight)
                has_fan = fan
        use_c1 = (t_b.v > 0.0) & (t_b.v < 1.0) if method == "axial" else np.ones(nf, dtype=bool)
    else:
        sv = r1 + (r2 - r1) * 0.5
        c1 = _closest3(a, sv)
        use_c1 = np.ones(nf, dtype=bool)
    tr1 = ad.where(use_c1[:, None], c1, r1)
    tr2 = ad.where(use_c1[:, None], c1, r2)
    if sign != 0:
        flip = dsign(c1[:, axis]) != sign
        if flip.any():
            mirror = np.ones(3)
            mirror[axis] = -1.0
            c1m = c1 * mirror
            tr1 = ad.where(flip[:, None], c1m, tr1)
            tr2 = ad.where(flip[:, None], c1m, tr2)
            # OpenSim's EQUAL_WITHIN_ERROR(fanWeight, -inf) is never true, so a pure Frans
            # solution (no fan weight) is never pulled towards the bisecting plane.
            fw = ad.where(fan_weight.v > 1.0, 1.0, fan_weight)
            pull = flip & has_fan & (fw.v > 0.0)
            onehot = np.eye(3)[axis]
            comp = c1m[:, axis]
            moved = c1m - (comp * ad.where(pull, fw, 0.0)).expand(-1) * onehot
            pulled = _closest3(a, moved)
            c1 = ad.where(flip[:, None], ad.where(pull[:, None], pulled, c1m), c1)
    vs, _ = ad.normalize_or_zero(ad.cross(p1p2, p1 - c1))
    vs4 = -ad.dot(vs, c1)
    tr1 = _tangent_point(p1e, tr1, p1, a, vs, vs4)
    tr2 = _tangent_point(p2e, tr2, p2, a, vs, vs4)
    far = np.zeros(nf, dtype=bool)
    length, w1, w2, has_mid = _arc(tr1, tr2, a, vs, vs4, factor, far)
    if sign != 0:
        d1, _ = ad.normalize_or_zero(p1 - tr1)
        e1, _ = ad.normalize_or_zero(w1 - tr1)
        d2, _ = ad.normalize_or_zero(p2 - tr2)
        e2, _ = ad.normalize_or_zero(w2 - tr2)
        wrong = has_mid & ((ad.dot(d1, e1).v > 0.0) | (ad.dot(d2, e2).v > 0.0))
        if wrong.any():
            length2, _, _, _ = _arc(tr1, tr2, a, vs, vs4, factor, wrong)
            length = ad.where(wrong, length2, length)
    return tr1, tr2, length


def _pick(options, idx) -> Dual:
    out = options[0]
    for i in (1, 2):
        out = ad.where((idx == i)[:, None], options[i], out)
    return out


def wrap_ellipsoid(p1, p2, *, dimensions, quadrant="all", method="hybrid"):
    """Wrap segments p1->p2 over a WrapEllipsoid; tangent points, lengths and exact gradients
    (a `wrap_oracle.dual.SegmentWrap`); the arguments are those of `ellipsoid_wrap_line`,
    with plain float (F, 3) end points."""
    return ad.segment_wrap(ellipsoid_wrap_line, p1, p2, dimensions=dimensions,
                           quadrant=quadrant, method=method)
