"""Fairing of fibres (`fibres.finishing.fairing`): the linear fairing map and the spread pull."""
import numpy as np
import pytest

from fibres.finishing.fairing import (SPREAD, TURNING, fairing_matrices, fairing_operator,
                                      spread_pull)


def _turns(points):
    seg = np.diff(points, axis=-2)
    u = seg / np.linalg.norm(seg, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.einsum("...ij,...ij->...i", u[..., 1:, :],
                                                  u[..., :-1, :]), -1.0, 1.0)))


def _l_shape(p=17):
    """A polyline of p evenly spaced points along two unit legs meeting at a right angle."""
    s = np.linspace(0.0, 2.0, p)
    return np.stack([np.minimum(s, 1.0), np.maximum(s - 1.0, 0.0), np.zeros(p)], axis=1)


@pytest.mark.parametrize("iterations", [0, 7])
def test_rows_are_affine_and_the_ends_stay(iterations):
    """Every faired point is an affine combination of the fibre's points (Taubin smoothing,
    the spline and the blends all reproduce constants), so the map commutes with any rigid
    motion of the muscle; the ends (on the attachment patches) are kept exactly."""
    pts = _l_shape()[None]
    F = fairing_matrices(pts, iterations=iterations)[0]
    np.testing.assert_allclose(F.sum(axis=1), 1.0, atol=1e-12)
    q = F @ pts[0]
    np.testing.assert_array_equal(q[[0, -1]], pts[0, [0, -1]])
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(F @ (pts[0] @ rot.T + 0.3), q @ rot.T + 0.3, atol=1e-12)


def test_a_straight_fibre_gets_even_points():
    """No turning: the measure is arc length alone, so unevenly spaced points on a line come
    out evenly spaced on the same line."""
    s = np.array([0.0, 0.05, 0.1, 0.4, 0.45, 0.5, 0.9, 1.0])
    pts = np.stack([s, 2 * s, -s], axis=1)[None]
    q = fairing_operator(pts, iterations=0) @ pts.reshape(-1, 3)
    even = np.linspace(0.0, 1.0, len(s))
    np.testing.assert_allclose(q, np.stack([even, 2 * even, -even], axis=1), atol=1e-9)


def _bend(p=17, r=0.2):
    """p evenly spaced points along a unit leg, a quarter circle of radius r, a unit leg."""
    arc = 0.5 * np.pi * r
    u = np.linspace(0.0, 2.0 + arc, p)
    a = np.clip((u - 1.0) / r, 0.0, 0.5 * np.pi)
    x = np.where(u <= 1.0, u, 1.0 + r * np.sin(a))
    y = np.where(u <= 1.0 + arc, r * (1.0 - np.cos(a)), r + (u - 1.0 - arc))
    return np.stack([x, y, np.zeros(p)], axis=1)


@pytest.mark.parametrize("shape, iterations", [(_bend, 0), (_bend, 7), (_l_shape, 7)])
def test_a_bend_is_spread_over_many_joints(shape, iterations):
    """A right-angle bend over one or two joints (before: up to 41 and 90 degrees at a joint):
    the measure's turning part is TURNING * (pi/2) / pi = 2 against the length part 1, so
    each of the 16 segments gets 3 / 16 of the measure and a joint in the bend turns by
    about (3 / 16) / TURNING * 180 = 8.4 degrees; the spline's overshoot beside the bend and
    the dense sampling add a few degrees (bound: 12). A corner at one joint is rounded by the
    Taubin smoothing first (without it the interpolating spline keeps a curvature spike at
    the corner point that 8 dense points per segment do not resolve)."""
    assert TURNING == 4.0
    pts = shape()[None]
    assert _turns(pts[0]).max() >= 40.0
    q = fairing_matrices(pts, iterations=iterations)[0] @ pts[0]
    after = _turns(q)
    assert after.max() <= 12.0
    assert 90.0 <= after.sum() <= 110.0


def test_spread_pull_moves_a_run_rigidly_and_tapers_beside_it():
    """Shepard normalisation: a run of points pulled by the same d moves by exactly d; the
    points beside it get d times the tent weight of the nearest pulled point over the summed
    weights of the pulled points around (1, 2, 3, 4 joints away: SPREAD)."""
    p = 16
    line = np.stack([np.linspace(0.0, 0.15, p), np.zeros(p), np.zeros(p)], axis=1)[None]
    d = np.array([0.0, 1e-3, 0.0])
    after = line.copy()
    after[0, 6:9] += d                       # points 6, 7, 8 pulled alike
    out = spread_pull(line, after)
    moved = out - line
    np.testing.assert_allclose(moved[0, 6:9], np.tile(d, (3, 1)), atol=1e-15)
    # point 9: neighbours 8, 7, 6 at 1, 2, 3 joints -> (0.8 + 0.6 + 0.4) d / max(1, same)
    w = SPREAD[0] + SPREAD[1] + SPREAD[2]
    np.testing.assert_allclose(moved[0, 9], w / max(1.0, w) * d, atol=1e-15)
    # point 12: only point 8 is within four joints -> 0.2 d
    np.testing.assert_allclose(moved[0, 12], SPREAD[3] * d, atol=1e-15)
    assert not moved[0, [0, -1]].any()       # the ends never move
    assert not moved[0, 13:].any()


def test_spread_pull_of_an_isolated_point_is_a_tent():
    p = 12
    line = np.zeros((1, p, 3))
    line[0, :, 0] = np.arange(p)
    after = line.copy()
    after[0, 5, 2] = 0.5
    moved = (spread_pull(line, after) - line)[0, :, 2]
    expected = np.zeros(p)
    expected[5] = 0.5
    for k, w in enumerate(SPREAD, start=1):
        expected[5 - k] = expected[5 + k] = w * 0.5
    expected[0] = expected[-1] = 0.0
    np.testing.assert_allclose(moved, expected, atol=1e-15)


def _spline_matrix(knots, t):
    """(M, P) matrix of the natural cubic spline through P values at ``knots``, evaluated at
    ``t``: scipy's natural CubicSpline of the identity's columns (the oracle)."""
    from scipy.interpolate import CubicSpline

    return CubicSpline(knots, np.eye(len(knots)), bc_type="natural")(t)


def test_spline_second_derivatives_and_values_match_scipy():
    """`_spline_second` (the natural spline's second derivatives at the knots, which
    `_resample` evaluates the spline with) against scipy's natural cubic spline on uneven
    knots: the derivatives, and the values by the spline formula of its docstring."""
    from scipy.interpolate import CubicSpline

    from fibres.finishing.fairing import _spline_second

    rng = np.random.default_rng(3)
    knots = np.cumsum(rng.uniform(0.2, 2.0, 9))
    y = rng.normal(size=(9, 3))
    t = np.linspace(knots[0], knots[-1], 57)
    h = np.diff(knots)
    m = _spline_second(knots[None], h[None])[0] @ y
    spline = CubicSpline(knots, y, bc_type="natural")
    np.testing.assert_allclose(m, spline(knots, 2), atol=1e-12)
    k = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(knots) - 2)
    b = (t - knots[k]) / h[k]
    a = 1.0 - b
    value = (a[:, None] * y[k] + b[:, None] * y[k + 1] + ((a ** 3 - a) * h[k] ** 2 / 6)[:, None] * m[k]
             + ((b ** 3 - b) * h[k] ** 2 / 6)[:, None] * m[k + 1])
    np.testing.assert_allclose(value, spline(t), atol=1e-12)


def test_spread_pull_has_no_step_where_a_pull_reaches_pulled():
    """A pull next to a run of 1 mm pulls, growing through PULLED: its share of the
    normalising sum grows with it (min(1, |d| / PULLED)), so the spread moves by ~1e-6 of
    the run's pull when it crosses PULLED by +-1e-6 (counted as a whole point at once, the
    neighbour's share would jump from 1.8 to 2.6: 0.3 mm)."""
    from fibres.finishing.fairing import PULLED

    p = 16
    line = np.stack([np.linspace(0.0, 0.15, p), np.zeros(p), np.zeros(p)], axis=1)[None]

    def spread(small):
        after = line.copy()
        after[0, 6:9, 1] += 1e-3
        after[0, 10, 1] += small
        return spread_pull(line, after)

    below, above = spread(PULLED * (1 - 1e-6)), spread(PULLED * (1 + 1e-6))
    assert np.abs(above - below).max() < 1e-8
    # and from zero: a pull of 1e-9 m changes the spread by about as little
    assert np.abs(spread(1e-9) - spread(0.0)).max() < 1e-6


def _fairing_oracle(points, iterations, turning=TURNING, dense=8):
    """`fairing_matrices` written plainly, fibre by fibre, from the whole spline matrix
    (`_spline_matrix`, scipy's) and the module docstring's steps."""
    from fibres.finishing.fairing import _taubin_matrix

    n, p, _ = points.shape
    taubin = _taubin_matrix(p, iterations) if iterations else np.eye(p)
    out = np.empty((n, p, p))
    for f in range(n):
        y = taubin @ points[f]
        knots = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(y, axis=0), axis=1))])
        u = _spline_matrix(knots, np.linspace(0.0, knots[-1], (p - 1) * dense + 1))
        seg = np.diff(u @ y, axis=0)
        ds = np.linalg.norm(seg, axis=1)
        e = seg / ds[:, None]
        theta = np.arctan2(np.linalg.norm(np.cross(e[:-1], e[1:]), axis=1),
                           np.einsum("ij,ij->i", e[:-1], e[1:]))
        share = np.zeros(len(ds))
        share[:-1] += 0.5 * theta
        share[1:] += 0.5 * theta
        cum = np.concatenate([[0.0], np.cumsum(ds / ds.sum() + turning * share / np.pi)])
        target = np.linspace(0.0, cum[-1], p)
        j = np.clip(np.searchsorted(cum, target, side="right") - 1, 0, len(cum) - 2)
        w = np.clip((target - cum[j]) / (cum[j + 1] - cum[j]), 0.0, 1.0)
        out[f] = ((1.0 - w)[:, None] * u[j] + w[:, None] * u[j + 1]) @ taubin
        out[f, [0, -1]] = np.eye(p)[[0, -1]]
    return out


@pytest.mark.parametrize("iterations", [0, 3])
def test_fairing_matrices_equal_the_plain_oracle(iterations):
    """The compiled resampling (`_resample`) and the matrix assembly give the plain
    fibre-by-fibre construction, to rounding, on wiggly fibres of uneven spacing."""
    rng = np.random.default_rng(5)
    pts = np.cumsum(rng.normal(size=(12, 16, 3)) * [1.0, 0.4, 0.2] + [1.0, 0.0, 0.0], axis=1)
    np.testing.assert_allclose(fairing_matrices(pts, iterations=iterations),
                               _fairing_oracle(pts, iterations), rtol=0, atol=1e-10)
