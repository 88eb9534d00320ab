"""Wrap geometry on arrays (the numpy oracle in tests/motion/wrap_oracle, which
`test_compiled_wraps.py` ties to the compiled kernels): closed-form answers, tangency, exact
derivatives.

Closed forms used (wrap frame, everything in metres):
- A segment p1 = (-a, -b, z), p2 = (a, -b, z) with 0 < b < R over a sphere (or a cylinder with
  z = 0, whose cross-section is the same circle) of radius R at the origin wraps around the
  bottom. With D = |(a, b)|, alpha = acos(R / D), beta = atan(b / a), the shortest path is
  ``2 sqrt(D^2 - R^2) + R (pi - 2 alpha - 2 beta)`` and the tangent points are at polar angles
  ``pi + beta + alpha`` and ``2 pi - beta - alpha``.
- OpenSim's ellipsoid measures the arc as a polyline of N = int(chord / 1 mm) equal-angle pieces
  (when the wrapping plane contains the centre): ``N * 2 R sin(phi / 2N)`` for an arc angle phi.
- Derivatives: the exact (forward-mode) gradient must equal central differences of the same
  function, h = 1e-7 m (truncation ~ h^2 L''' ~ 1e-12, round-off ~ 1e-16 / h ~ 1e-9).
"""
from __future__ import annotations

import numpy as np
import pytest

from wrap_oracle.cylinder import wrap_cylinder     # tests/motion (rootdir-relative import)
from wrap_oracle.ellipsoid import closest_point_on_ellipsoid, wrap_ellipsoid
from wrap_oracle.sphere import wrap_sphere
from wrap_oracle.torus import wrap_torus

R = 0.05


def _symmetric(b_values, a=0.2, z=0.0):
    b = np.asarray(b_values, dtype=float)
    p1 = np.stack([-a + 0 * b, -b, z + 0 * b], axis=1)
    p2 = np.stack([a + 0 * b, -b, z + 0 * b], axis=1)
    d = np.hypot(a, b)
    alpha = np.arccos(R / d)
    beta = np.arctan2(b, a)
    length = 2 * np.sqrt(d * d - R * R) + R * (np.pi - 2 * alpha - 2 * beta)
    ang1 = np.pi + beta + alpha
    ang2 = 2 * np.pi - beta - alpha
    t1 = np.stack([R * np.cos(ang1), R * np.sin(ang1), z + 0 * b], axis=1)
    t2 = np.stack([R * np.cos(ang2), R * np.sin(ang2), z + 0 * b], axis=1)
    return p1, p2, length, t1, t2, R * (np.pi - 2 * alpha - 2 * beta)


B = [0.0, 0.01, 0.02, 0.035, 0.049]


def test_sphere_symmetric_closed_form():
    p1, p2, length, t1, t2, arc = _symmetric(B)
    res = wrap_sphere(p1, p2, radius=R)
    assert res.wrapped[1:].all()
    # b = 0 passes through the centre: OpenSim's degenerate case (no wrap here)
    assert not res.wrapped[0]
    np.testing.assert_allclose(res.length[1:], length[1:], atol=1e-12)
    np.testing.assert_allclose(res.arc[1:], arc[1:], atol=1e-12)
    np.testing.assert_allclose(res.t1[1:], t1[1:], atol=1e-12)
    np.testing.assert_allclose(res.t2[1:], t2[1:], atol=1e-12)


def test_cylinder_symmetric_closed_form():
    p1, p2, length, t1, t2, arc = _symmetric(B[1:])
    for adjust in (False, True):
        res = wrap_cylinder(p1, p2, radius=R, length=0.2, adjust_tangents=adjust)
        assert res.wrapped.all()
        np.testing.assert_allclose(res.length, length, atol=1e-12)
        np.testing.assert_allclose(res.t1, t1, atol=1e-12)
        np.testing.assert_allclose(res.t2, t2, atol=1e-12)


def test_cylinder_helix_length():
    # p1 below, p2 above: the geodesic unrolls to a straight line of the same planar length
    p1, p2, planar, *_ = _symmetric([0.02])
    dz = 0.03
    p1[:, 2] -= dz
    p2[:, 2] += dz
    exact = np.hypot(planar, 2 * dz)
    loose = wrap_cylinder(p1, p2, radius=R, length=0.5, adjust_tangents=False)
    tight = wrap_cylinder(p1, p2, radius=R, length=0.5, adjust_tangents=True)
    # OpenSim's plane heuristic is longer than the geodesic; the 0.1-degree re-adjustment
    # brings it to within ~1e-7 m (the error is second order in the residual angle)
    assert loose.length[0] >= exact[0] - 1e-12
    assert tight.length[0] >= exact[0] - 1e-12
    assert tight.length[0] - exact[0] < 2e-7
    assert tight.length[0] <= loose.length[0] + 1e-12


def test_no_wrap_when_segment_misses():
    p1 = np.array([[-0.2, 0.08, 0.0], [-0.2, 0.0, 0.0]])
    p2 = np.array([[0.2, 0.08, 0.0], [-0.1, 0.0, 0.0]])  # above the object; short of it
    for res in (wrap_sphere(p1, p2, radius=R), wrap_cylinder(p1, p2, radius=R, length=0.2),
                wrap_ellipsoid(p1, p2, dimensions=[R, R, R])):
        assert not res.wrapped.any()
        np.testing.assert_allclose(res.length, np.linalg.norm(p2 - p1, axis=1), rtol=1e-15)
        np.testing.assert_allclose(res.dl_dp2, (p2 - p1) / res.length[:, None], atol=1e-15)


def test_inside_is_reported():
    p1 = np.array([[0.0, 0.01, 0.0]])
    p2 = np.array([[0.2, 0.0, 0.0]])
    assert wrap_sphere(p1, p2, radius=R).code[0] == 1
    assert wrap_cylinder(p1, p2, radius=R, length=0.2).code[0] == 1
    assert wrap_ellipsoid(p1, p2, dimensions=[R, R, R]).code[0] == 1


def test_quadrant_picks_the_active_side():
    # both end points on +y, the line misses the cylinder: only a "-y" cylinder wraps, around -y
    p1 = np.array([[-0.2, 0.06, 0.0]])
    p2 = np.array([[0.2, 0.06, 0.0]])
    assert not wrap_cylinder(p1, p2, radius=R, length=0.2).wrapped[0]
    res = wrap_cylinder(p1, p2, radius=R, length=0.2, quadrant="-y")
    assert res.wrapped[0] and res.t1[0, 1] < 0 and res.t2[0, 1] < 0
    # a line through the cylinder on the -y side: "+y" forces the long way round (+y side)
    p1 = np.array([[-0.2, -0.03, 0.0]])
    p2 = np.array([[0.2, -0.03, 0.0]])
    short = wrap_cylinder(p1, p2, radius=R, length=0.2, quadrant="all")
    long = wrap_cylinder(p1, p2, radius=R, length=0.2, quadrant="+y")
    assert short.t1[0, 1] < 0 and long.t1[0, 1] > 0
    assert long.length[0] > short.length[0]


def test_ellipsoid_sphere_polyline():
    p1, p2, length, t1, t2, arc = _symmetric([0.01, 0.02, 0.035])
    res = wrap_ellipsoid(p1, p2, dimensions=[R, R, R])
    assert res.wrapped.all() and (res.code == 3).all()
    # tangent points from calcTangentPoint: squared residual < 1e-8 in units of ~R, so
    # positions agree to ~1e-4 R = 5e-6 m
    np.testing.assert_allclose(res.t1, t1, atol=5e-6)
    np.testing.assert_allclose(res.t2, t2, atol=5e-6)
    # the wrapping plane is z = 0 through the centre: interior polyline points are on the
    # sphere at equal angles between the directions of t1 and t2
    chord = np.linalg.norm(res.t1 - res.t2, axis=1)
    n = np.minimum((chord / 0.001).astype(int), 499)
    u1 = res.t1 / np.linalg.norm(res.t1, axis=1, keepdims=True)
    u2 = res.t2 / np.linalg.norm(res.t2, axis=1, keepdims=True)
    phi = np.arccos(np.sum(u1 * u2, axis=1))
    first = R * (np.cos(phi / n)[:, None] * u1 + np.sin(phi / n)[:, None]
                 * np.cross(np.cross(u1, u2), u1) / np.sin(phi)[:, None])
    last = R * (np.cos(phi / n)[:, None] * u2 + np.sin(phi / n)[:, None]
                * np.cross(np.cross(u2, u1), u2) / np.sin(phi)[:, None])
    expected = (np.linalg.norm(first - res.t1, axis=1) + (n - 2) * 2 * R * np.sin(phi / (2 * n))
                + np.linalg.norm(res.t2 - last, axis=1))
    np.testing.assert_allclose(res.arc, expected, atol=1e-12)


def test_ellipsoid_tangency():
    rng = np.random.default_rng(3)
    dims = np.array([0.035, 0.02, 0.025])
    p1 = np.array([-0.08, -0.01, 0.0]) + rng.normal(scale=0.01, size=(20, 3))
    p2 = np.array([0.08, -0.012, 0.005]) + rng.normal(scale=0.01, size=(20, 3))
    for method in ("hybrid", "midpoint", "axial"):
        res = wrap_ellipsoid(p1, p2, dimensions=dims, method=method)
        w = res.wrapped
        assert w.sum() >= 10
        for p, t in ((p1, res.t1), (p2, res.t2)):
            t = t[w]
            on_surface = np.sum((t / dims) ** 2, axis=1) - 1
            normal = t / dims ** 2
            normal /= np.linalg.norm(normal, axis=1, keepdims=True)
            line = (t - p[w]) / np.linalg.norm(t - p[w], axis=1, keepdims=True)
            assert np.abs(on_surface).max() < 1e-3          # ssq < 1e-8 on scaled residuals
            assert np.abs(np.sum(normal * line, axis=1)).max() < 1e-3


def test_closest_point_on_ellipsoid():
    rng = np.random.default_rng(0)
    dims = np.array([1.2, 0.8, 1.0])
    pts = rng.normal(size=(200, 3)) * 2
    x, y, z = closest_point_on_ellipsoid(dims, pts[:, 0], pts[:, 1], pts[:, 2])
    q = np.stack([x.v, y.v, z.v], axis=1)
    np.testing.assert_allclose(np.sum((q / dims) ** 2, axis=1), 1.0, atol=1e-8)
    # the offset is along the surface normal (first-order optimality)
    normal = q / dims ** 2
    off = pts - q
    cross = np.cross(normal, off)
    assert np.abs(cross).max() < 1e-7 * np.abs(off).max() * np.abs(normal).max() * 10


def _random_cases(rng, n):
    p1 = np.array([-0.15, -0.02, -0.01]) + rng.normal(scale=0.01, size=(n, 3))
    p2 = np.array([0.15, -0.015, 0.02]) + rng.normal(scale=0.01, size=(n, 3))
    return p1, p2


WRAPS = {
    "sphere": lambda a, b: wrap_sphere(a, b, radius=R),
    "sphere -y": lambda a, b: wrap_sphere(a, b, radius=R, quadrant="-y"),
    "cylinder": lambda a, b: wrap_cylinder(a, b, radius=R, length=0.3),
    "cylinder adjusted": lambda a, b: wrap_cylinder(a, b, radius=R, length=0.3, adjust_tangents=True),
    "cylinder +y": lambda a, b: wrap_cylinder(a, b, radius=R, length=0.3, quadrant="+y"),
    "ellipsoid hybrid": lambda a, b: wrap_ellipsoid(a, b, dimensions=[0.06, 0.04, 0.05]),
    "ellipsoid midpoint": lambda a, b: wrap_ellipsoid(a, b, dimensions=[0.06, 0.04, 0.05], method="midpoint"),
    "ellipsoid axial -y": lambda a, b: wrap_ellipsoid(a, b, dimensions=[0.06, 0.04, 0.05], method="axial",
                                                      quadrant="-y"),
    # through the torus' hole: from above its centre to below and outside the ring
    # (shifted, not scaled, so that the gradients are with respect to the same points)
    "torus": lambda a, b: wrap_torus(a + [0.16, 0.025, 0.21], b + [-0.07, 0.015, -0.22],
                                     inner_radius=0.02, outer_radius=0.06),
}


@pytest.mark.parametrize("name", sorted(WRAPS))
def test_gradient_matches_central_differences(name):
    fn = WRAPS[name]
    rng = np.random.default_rng(1)
    p1, p2 = _random_cases(rng, 12)
    base = fn(p1, p2)
    assert base.wrapped.sum() >= 4, "the cases must wrap"
    h = 1e-7
    for which, grad in ((0, base.dl_dp1), (1, base.dl_dp2)):
        for k in range(3):
            a, b = [p1.copy(), p2.copy()], [p1.copy(), p2.copy()]
            a[which][:, k] += h
            b[which][:, k] -= h
            ra, rb = fn(*a), fn(*b)
            same = (ra.code == base.code) & (rb.code == base.code)
            fd = (ra.length - rb.length) / (2 * h)
            # discrete steps of OpenSim's algorithms (iteration counts, polyline pieces) can
            # fall inside +-h; they show as jumps of O(1e-8 m)/h and are skipped
            smooth = same & (np.abs(fd - grad[:, k]) < 1e-3)
            assert smooth.sum() >= same.sum() - 2
            assert np.abs(fd - grad[:, k])[smooth].max(initial=0) < 2e-6


def _tangency_error_deg(pt, r, w):
    """|angle(p->r, axis) - angle(r->w, axis)| in degrees (OpenSim's tangency measure)."""
    pr = (r - pt) / np.linalg.norm(r - pt, axis=1)[:, None]
    rw = (w - r) / np.linalg.norm(w - r, axis=1)[:, None]
    return np.degrees(np.abs(np.arccos(pr[:, 2]) - np.arccos(rw[:, 2])))


@pytest.mark.parametrize("quadrant", ["all", "+y", "-x"])
def test_cylinder_readjustment_ends_tangent_and_frame_by_frame(quadrant, monkeypatch):
    # The re-adjustment loop stops when both straight lines meet the helix within 0.1 degree
    # at the spiral points 1/n of the way in (n = int(arc / 2 mm)); check that stop condition
    # independently from the returned points, and that each frame's answer does not depend on
    # the other frames of the batch (the loop runs only on the frames that wrap).
    rng = np.random.default_rng(7)
    p1, p2 = _random_cases(rng, 40)
    p2[::5, 2] += 0.2            # some steep helices
    p2[1::7, 1] += 0.12          # and some segments that miss the cylinder
    res = wrap_cylinder(p1, p2, radius=R, length=0.6, quadrant=quadrant, adjust_tangents=True)
    assert 10 <= res.wrapped.sum() < len(res.wrapped)
    # frames with a single 2 mm piece (n = 1) skip the loop in OpenSim too, and frames where
    # OpenSim's cap of 100 restarts stops it early (found by lifting the cap) are not tangent
    monkeypatch.setattr("wrap_oracle.cylinder._MAX_ITERATIONS", 100000)
    uncapped = wrap_cylinder(p1, p2, radius=R, length=0.6, quadrant=quadrant, adjust_tangents=True)
    monkeypatch.undo()
    capped = np.nan_to_num(np.abs(uncapped.t1 - res.t1).max(axis=1)) > 0
    assert capped.sum() <= 2
    w = res.wrapped & (np.nan_to_num(res.arc) >= 0.004) & ~capped
    assert w.sum() >= 10
    t1, t2 = res.t1[w], res.t2[w]
    dz = t2[:, 2] - t1[:, 2]
    phi = np.sqrt(np.maximum(res.arc[w] ** 2 - dz ** 2, 0.0)) / R
    n = np.floor(res.arc[w] / 0.002)
    # turning direction: the one that takes t1 to t2 in angle phi
    a1 = np.arctan2(t1[:, 1], t1[:, 0])
    a2 = np.arctan2(t2[:, 1], t2[:, 0])
    ccw = np.abs(np.angle(np.exp(1j * (a1 + phi - a2)))) < 1e-6
    sgn = np.where(ccw, 1.0, -1.0)

    def spiral(frac):
        ang = a1 + sgn * phi * frac
        return np.stack([R * np.cos(ang), R * np.sin(ang), t1[:, 2] + dz * frac], axis=1)

    # 0.1 degree plus round-off of the angles (~1e-12 degree)
    assert _tangency_error_deg(p1[w], t1, spiral(1.0 / n)).max() <= 0.1 + 1e-9
    assert _tangency_error_deg(p2[w], t2, spiral(1.0 - 1.0 / n)).max() <= 0.1 + 1e-9
    # the loop moved the points in some frames (else this test proves nothing)
    loose = wrap_cylinder(p1, p2, radius=R, length=0.6, quadrant=quadrant, adjust_tangents=False)
    assert np.abs(loose.t1[w] - t1).max() > 1e-5
    # frame by frame: identical to the batch
    for f in np.nonzero(w)[0][:8]:
        one = wrap_cylinder(p1[f:f + 1], p2[f:f + 1], radius=R, length=0.6, quadrant=quadrant,
                            adjust_tangents=True)
        assert one.code[0] == res.code[f]
        np.testing.assert_array_equal(one.t1[0], res.t1[f])
        assert one.length[0] == res.length[f]
