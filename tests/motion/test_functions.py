"""OpenSim functions: against OpenSim 4.6 itself, and analytic properties."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion.osim.functions import (Constant, LinearFunction, MultiplierFunction, PiecewiseLinearFunction,
                              PolynomialFunction, SimmSpline)

# knots of the Gait2392 knee translation (a real SimmSpline) and random ones
KNEE_X = np.array([-2.0944, -1.74533, -1.39626, -1.0472, -0.698132, -0.349066, -0.174533, 0.197344,
                   0.337395, 0.490178, 1.52146, 2.0944])
KNEE_Y = np.array([-0.0032, 0.00179, 0.00411, 0.0041, 0.00212, -0.001, -0.0031, -0.005227, -0.005435,
                   -0.005574, -0.005435, -0.005250])


def _opensim_xy(osim, cls, x, y):
    f = cls()
    for a, b in zip(x, y):
        f.addPoint(float(a), float(b))
    return f


def _osim_eval(osim, f, t):
    val = np.array([f.calcValue(osim.Vector(1, float(s))) for s in t])
    der = np.array([f.calcDerivative(osim.StdVectorInt([0]), osim.Vector(1, float(s))) for s in t])
    return val, der


@pytest.mark.parametrize("n", [2, 3, 4, 5, 12])
def test_simmspline_matches_opensim(osim, n):
    rng = np.random.default_rng(n)
    if n == 12:
        x, y = KNEE_X, KNEE_Y
    else:
        x, y = np.sort(rng.uniform(-2, 2, n)), rng.normal(size=n)
    ours = SimmSpline(x, y)
    theirs = _opensim_xy(osim, osim.SimmSpline, x, y)
    # inside, outside (linear extrapolation) and exactly at the knots
    t = np.concatenate([rng.uniform(x[0] - 1, x[-1] + 1, 300), x])
    val, der = _osim_eval(osim, theirs, t)
    # 1e-12: same algorithm, same operation order; only rounding may differ
    np.testing.assert_allclose(ours.value(t), val, rtol=0, atol=1e-12)
    interior = (t > x[0] + 1e-9) & (t < x[-1] - 1e-9) & ~np.isin(t, x)
    np.testing.assert_allclose(ours.derivative(t[interior]), der[interior], rtol=0, atol=1e-12)


def test_piecewise_linear_matches_opensim(osim):
    rng = np.random.default_rng(7)
    x, y = np.sort(rng.uniform(-3, 3, 6)), rng.normal(size=6)
    theirs = _opensim_xy(osim, osim.PiecewiseLinearFunction, x, y)
    t = rng.uniform(-5, 5, 200)
    val, der = _osim_eval(osim, theirs, t)
    f = PiecewiseLinearFunction(x, y)
    np.testing.assert_allclose(f.value(t), val, rtol=0, atol=1e-13)
    np.testing.assert_allclose(f.derivative(t), der, rtol=0, atol=1e-13)


def test_linear_and_constant_match_opensim(osim):
    t = np.linspace(-3, 3, 11)
    lf = osim.LinearFunction(-1.5, 0.25)
    val, der = _osim_eval(osim, lf, t)
    np.testing.assert_allclose(LinearFunction(-1.5, 0.25).value(t), val, atol=1e-15)
    np.testing.assert_allclose(LinearFunction(-1.5, 0.25).derivative(t), der, atol=1e-15)
    c = Constant(0.3)
    assert np.all(c.value(t) == 0.3) and np.all(c.derivative(t) == 0.0)


def test_spline_interpolates_knots_and_is_c1():
    f = SimmSpline(KNEE_X, KNEE_Y)
    np.testing.assert_allclose(f.value(KNEE_X), KNEE_Y, atol=1e-15)
    # C1 at interior knots: left and right derivatives agree (cubic spline property)
    eps = 1e-9
    left, right = f.derivative(KNEE_X[1:-1] - eps), f.derivative(KNEE_X[1:-1] + eps)
    np.testing.assert_allclose(left, right, atol=1e-6)   # second derivative bounded: |f''| eps << 1e-6


def test_two_point_spline_is_a_line():
    f = SimmSpline([0.0, 2.0], [1.0, 5.0])
    t = np.linspace(-1, 3, 9)
    np.testing.assert_allclose(f.value(t), 1.0 + 2.0 * t, atol=1e-14)
    np.testing.assert_allclose(f.derivative(t), 2.0, atol=1e-14)


def test_spline_reproduces_cubic_with_not_a_knot_like_ends():
    # FMM end conditions match the third divided differences: a cubic is reproduced exactly
    x = np.array([-1.0, -0.3, 0.2, 0.9, 1.4, 2.0])
    cubic = np.array([0.5, -1.0, 0.3, 2.0])
    f = SimmSpline(x, np.polyval(cubic, x))
    t = np.linspace(x[0], x[-1], 57)
    np.testing.assert_allclose(f.value(t), np.polyval(cubic, t), atol=1e-12)
    np.testing.assert_allclose(f.derivative(t), np.polyval(np.polyder(cubic), t), atol=1e-11)


def test_polynomial_and_multiplier():
    p = PolynomialFunction([2.0, -1.0, 0.5])          # 2x^2 - x + 0.5
    t = np.array([-1.0, 0.0, 2.0])
    np.testing.assert_allclose(p.value(t), [3.5, 0.5, 6.5])
    np.testing.assert_allclose(p.derivative(t), [-5.0, -1.0, 7.0])
    m = MultiplierFunction(p, -2.0)
    np.testing.assert_allclose(m.value(t), -2.0 * p.value(t))
    np.testing.assert_allclose(m.derivative(t), -2.0 * p.derivative(t))


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=9), st.floats(-2.5, 2.5))
def test_derivative_is_the_slope_of_value(ys, t):
    x = np.linspace(-2.0, 2.0, len(ys))
    f = SimmSpline(x, np.array(ys))
    h = 1e-6
    if np.min(np.abs(t - x)) < 2 * h:      # the one-sided ends of the extrapolation are kinks
        return
    fd = (f.value(t + h) - f.value(t - h)) / (2 * h)
    # central difference error ~ h^2 |f'''| + rounding 1e-16/h: well below 1e-6 here
    assert abs(fd - f.derivative(t)) < 1e-6


def test_bad_knots_raise():
    with pytest.raises(ValueError, match="non-decreasing"):
        SimmSpline([0.0, 2.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="at least 2"):
        PiecewiseLinearFunction([0.0], [1.0])


def test_polynomial_matches_opensim(osim):
    coefficients = [2.0, -1.0, 0.5, 0.3]          # OpenSim: highest power first
    vec = osim.Vector(len(coefficients), 0.0)
    for i, c in enumerate(coefficients):
        vec.set(i, c)
    theirs = osim.PolynomialFunction(vec)
    t = np.array([-1.3, 0.2, 1.7])
    val, der = _osim_eval(osim, theirs, t)
    np.testing.assert_allclose(PolynomialFunction(coefficients).value(t), val, rtol=0, atol=1e-13)
    np.testing.assert_allclose(PolynomialFunction(coefficients).derivative(t), der, rtol=0, atol=1e-13)


def test_multiplier_function_xml_is_read(tmp_path):
    """The XML OpenSim 4.6 prints for a MultiplierFunction (checked with MultiplierFunction.printToXML)."""
    from motion.osim.xml_document import Node, parse_function
    import xml.etree.ElementTree as ET

    el = ET.fromstring("<MultiplierFunction><function><SimmSpline><x> -2 -1 0</x><y> 0.01 0.03 0</y>"
                       "</SimmSpline></function><scale>1.7</scale></MultiplierFunction>")
    f = parse_function(Node(el, "/MultiplierFunction", "x.osim"))
    ref = SimmSpline([-2, -1, 0], [0.01, 0.03, 0])
    t = np.linspace(-3, 1, 9)
    np.testing.assert_allclose(f.value(t), 1.7 * ref.value(t), rtol=0, atol=1e-16)
