"""fibres.finishing.smoothing.smooth: P'_i = (P_{i-1} + k P_i + P_{i+1}) / (k + 2), ends fixed."""
import numpy as np
import pytest

from fibres.finishing.smoothing import smooth


def _noisy(n=30, p=20, seed=0):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(size=(n, p, 3)), axis=1)


def test_end_points_fixed_and_input_untouched():
    pts = _noisy()
    keep = pts.copy()
    out = smooth(pts, iterations=50)
    np.testing.assert_array_equal(out[:, [0, -1]], pts[:, [0, -1]])
    np.testing.assert_array_equal(pts, keep)


def test_one_step_is_the_formula():
    pts = _noisy(3, 6)
    out = smooth(pts, k=4.0, iterations=1)
    ref = (pts[:, :-2] + 4 * pts[:, 1:-1] + pts[:, 2:]) / 6
    np.testing.assert_allclose(out[:, 1:-1], ref, atol=1e-14)


def test_evenly_spaced_straight_line_is_a_fixed_point():
    t = np.linspace(0, 1, 20)[:, None]
    line = (np.array([0.1, -0.2, 0.3]) + t * np.array([1.0, 2.0, -0.5]))[None]
    np.testing.assert_allclose(smooth(line, iterations=100), line, atol=1e-14)


def test_points_of_a_line_stay_on_the_line():
    t = np.sort(np.random.default_rng(1).random(15))
    t[0], t[-1] = 0.0, 1.0
    d = np.array([1.0, 2.0, -0.5])
    line = t[:, None] * d
    out = smooth(line[None], iterations=7)[0]
    np.testing.assert_allclose(np.cross(out, d), 0.0, atol=1e-14)


@pytest.mark.parametrize("k", [4.0, 1.0])
def test_converges_to_the_chord_at_the_predicted_rate(k):
    pts = _noisy(5, 20)
    p = pts.shape[1]
    t = np.linspace(0, 1, p)[None, :, None]
    chord = pts[:, :1] + t * (pts[:, -1:] - pts[:, :1])
    n = 400
    err0 = np.linalg.norm(pts - chord)
    err = np.linalg.norm(smooth(pts, k=k, iterations=n) - chord)
    # spectral radius of the fixed-end Jacobi-type iteration (module docstring)
    rho = 1 - 2 * (1 - np.cos(np.pi / (p - 1))) / (k + 2)
    assert err <= rho**n * err0 * (1 + 1e-9)
    assert err < 0.2 * err0


def test_validation():
    with pytest.raises(ValueError, match="k must"):
        smooth(_noisy(), k=0)
    with pytest.raises(ValueError, match="iterations"):
        smooth(_noisy(), iterations=-1)
    two = np.zeros((4, 2, 3))
    np.testing.assert_array_equal(smooth(two), two)  # nothing inside to move


def test_max_shift_bounds_every_displacement_softly():
    # a semicircle of radius 1 (a fibre around a curved muscle): plain smoothing pulls the
    # middle towards the chord; with max_shift s every point moves by < s, and for tiny
    # moves (|D| << s) the bound changes nothing to first order: D' = D (1 - |D|^2 / 2s^2)
    t = np.linspace(0, np.pi, 21)
    arc = np.c_[np.cos(t), np.sin(t), np.zeros_like(t)][None]
    free = smooth(arc, iterations=20)
    assert np.linalg.norm(free - arc, axis=-1).max() > 0.05
    s = 0.01
    capped = smooth(arc, iterations=20, max_shift=s)
    shift = np.linalg.norm(capped - arc, axis=-1)
    assert shift.max() < s
    d_free = np.linalg.norm(free - arc, axis=-1)
    np.testing.assert_allclose(shift, d_free / np.sqrt(1 + (d_free / s) ** 2), rtol=1e-12)
    np.testing.assert_array_equal(capped[:, [0, -1]], arc[:, [0, -1]])
    tiny = smooth(arc * 1e-4, iterations=1, max_shift=s)
    np.testing.assert_allclose(tiny, smooth(arc * 1e-4, iterations=1), atol=1e-12)
    with pytest.raises(ValueError, match="max_shift"):
        smooth(arc, max_shift=0.0)


