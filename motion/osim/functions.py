"""OpenSim's one-variable functions, vectorised, with first derivatives.

Every class is a frozen dataclass with ``value(x)`` and ``derivative(x)`` taking an array of
any shape and returning an array of the same shape. Values reproduce OpenSim 4.6 to rounding:

- `Constant` (OpenSim ``Constant``), `LinearFunction` (``coefficients = [slope, intercept]``),
  `PolynomialFunction` (``coefficients`` highest power first, as SimTK::Function::Polynomial).
- `SimmSpline` (also used for OpenSim's ``NaturalCubicSpline``, which OpenSim fits with the very
  same algorithm): the cubic spline of Forsythe, Malcolm & Moler (1977, *Computer Methods for
  Mathematical Computations*, routine SPLINE) as in OpenSim's ``SimmSpline::calcCoefficients``.
  Its end conditions are not "natural": the third derivative at each end matches the third
  divided difference of the four end knots (n > 3); with n = 3 the end third derivatives are 0;
  n = 2 is a straight line. Outside the knots it extrapolates linearly with the end slope;
  within 2e-13 of an end knot the value is that knot's y (OpenSim's EQUAL_WITHIN_ERROR).
  Knot spacings are floored at 1e-7 (OpenSim's TINY_NUMBER).
- `PiecewiseLinearFunction`: linear interpolation; linear extrapolation with the end segments'
  slopes (OpenSim's ``PiecewiseLinearFunction``).
- `MultiplierFunction`: ``scale * function(x)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import readonly_array

__all__ = [
    "Constant", "LinearFunction", "PolynomialFunction", "SimmSpline", "PiecewiseLinearFunction",
    "MultiplierFunction", "FUNCTION_TYPES",
]

_TINY = 1e-7        # OpenSim SimmMacros TINY_NUMBER: smallest knot spacing
_ROUNDOFF = 2e-13   # OpenSim SimmMacros ROUNDOFF_ERROR: "equal within error"


def _freeze(obj, **arrays) -> None:
    """Set each of ``arrays`` on the frozen dataclass ``obj`` as a read-only float copy."""
    for name, a in arrays.items():
        object.__setattr__(obj, name, readonly_array(a))


@dataclass(frozen=True, eq=False)
class Constant:
    """f(x) = value."""

    constant: float

    def value(self, x):
        return np.full(np.shape(x), float(self.constant))

    def derivative(self, x):
        return np.zeros(np.shape(x))


@dataclass(frozen=True, eq=False)
class LinearFunction:
    """f(x) = slope * x + intercept (OpenSim coefficients [slope, intercept])."""

    slope: float
    intercept: float = 0.0

    def value(self, x):
        return self.slope * np.asarray(x, dtype=float) + self.intercept

    def derivative(self, x):
        return np.full(np.shape(x), float(self.slope))


@dataclass(frozen=True, eq=False)
class PolynomialFunction:
    """f(x) = sum_k c_k x^(n-k), coefficients highest power first (SimTK Polynomial)."""

    coefficients: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "coefficients", readonly_array(np.atleast_1d(self.coefficients)))

    def value(self, x):
        return np.polyval(self.coefficients, np.asarray(x, dtype=float))

    def derivative(self, x):
        x = np.asarray(x, dtype=float)
        if len(self.coefficients) < 2:
            return np.zeros(x.shape)
        return np.polyval(np.polyder(self.coefficients), x)


def _fmm_coefficients(x: np.ndarray, y: np.ndarray):
    """Cubic coefficients b, c, d (n,) of Forsythe-Malcolm-Moler's SPLINE.

    On [x_k, x_k+1]: s(t) = y_k + b_k dt + c_k dt^2 + d_k dt^3, dt = t - x_k. End conditions:
    third derivatives from divided differences (n > 3), zero for n = 3. Follows the order of
    operations of OpenSim's SimmSpline::calcCoefficients so that results agree to rounding.
    """
    n = len(x)
    b, c, d = np.zeros(n), np.zeros(n), np.zeros(n)
    if n == 2:
        slope = (y[1] - y[0]) / max(_TINY, x[1] - x[0])
        b[:] = slope
        return b, c, d
    last = n - 1
    # tridiagonal system: diagonal in b, off-diagonal in d, right-hand side in c
    d[0] = max(_TINY, x[1] - x[0])
    c[1] = (y[1] - y[0]) / d[0]
    for i in range(1, last):
        d[i] = max(_TINY, x[i + 1] - x[i])
        b[i] = 2.0 * (d[i - 1] + d[i])
        c[i + 1] = (y[i + 1] - y[i]) / d[i]
        c[i] = c[i + 1] - c[i]
    b[0] = -d[0]
    b[last] = -d[last - 1]
    c[0] = 0.0
    c[last] = 0.0
    if n > 3:
        d31 = max(_TINY, x[3] - x[1])
        d20 = max(_TINY, x[2] - x[0])
        d1 = max(_TINY, x[last] - x[n - 3])
        d2 = max(_TINY, x[last - 1] - x[n - 4])
        d30 = max(_TINY, x[3] - x[0])
        d3 = max(_TINY, x[last] - x[n - 4])
        c0 = c[2] / d31 - c[1] / d20
        cl = c[last - 1] / d1 - c[n - 3] / d2
        c[0] = c0 * d[0] * d[0] / d30
        c[last] = -cl * d[last - 1] * d[last - 1] / d3
    for i in range(1, n):                       # forward elimination
        t = d[i - 1] / b[i - 1]
        b[i] -= t * d[i - 1]
        c[i] -= t * c[i - 1]
    c[last] /= b[last]                          # back substitution
    for i in range(last - 1, -1, -1):
        c[i] = (c[i] - d[i] * c[i + 1]) / b[i]
    b[last] = (y[last] - y[last - 1]) / d[last - 1] + d[last - 1] * (c[last - 1] + 2.0 * c[last])
    for i in range(last):
        b[i] = (y[i + 1] - y[i]) / d[i] - d[i] * (c[i + 1] + 2.0 * c[i])
        d[i] = (c[i + 1] - c[i]) / d[i]
        c[i] *= 3.0
    c[last] *= 3.0
    d[last] = d[last - 1]
    return b, c, d


def _check_knots(x, y, name):
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.ndim != 1 or x.shape != y.shape:
        raise ValueError(f"{name}: x and y must be 1-D arrays of one length, got {x.shape} and {y.shape}")
    if len(x) < 2:
        raise ValueError(f"{name}: needs at least 2 points, got {len(x)}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError(f"{name}: x and y must be finite")
    if np.any(np.diff(x) < 0):
        raise ValueError(f"{name}: x must be non-decreasing")
    return x, y


def _segment(xk: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Index k of the knot interval [x_k, x_k+1] holding each t (clipped to the ends)."""
    return np.clip(np.searchsorted(xk, t, side="right") - 1, 0, len(xk) - 2)


@dataclass(frozen=True, eq=False)
class _KnotFunction:
    """A function of knots (x, y): checked, frozen, with the coefficients of `_coefficients`."""

    x: np.ndarray
    y: np.ndarray

    def __post_init__(self):
        x, y = _check_knots(self.x, self.y, type(self).__name__)
        _freeze(self, x=x, y=y, **self._coefficients(x, y))


@dataclass(frozen=True, eq=False)
class SimmSpline(_KnotFunction):
    """OpenSim's SimmSpline / NaturalCubicSpline (see the module docstring)."""

    @staticmethod
    def _coefficients(x, y) -> dict:
        b, c, d = _fmm_coefficients(x, y)
        return {"_b": b, "_c": c, "_d": d}

    def value(self, t):
        t = np.asarray(t, dtype=float)
        x, y, b, c, d = self.x, self.y, self._b, self._c, self._d
        k = _segment(x, t)
        dt = t - x[k]
        out = y[k] + dt * (b[k] + dt * (c[k] + dt * d[k]))
        out = np.where(np.abs(t - x[-1]) <= _ROUNDOFF, y[-1], out)
        out = np.where(np.abs(t - x[0]) <= _ROUNDOFF, y[0], out)
        out = np.where(t < x[0], y[0] + (t - x[0]) * b[0], out)
        out = np.where(t > x[-1], y[-1] + (t - x[-1]) * b[-1], out)
        return out

    def derivative(self, t):
        t = np.asarray(t, dtype=float)
        x, b, c, d = self.x, self._b, self._c, self._d
        k = _segment(x, t)
        dt = t - x[k]
        out = b[k] + dt * (2.0 * c[k] + 3.0 * dt * d[k])
        out = np.where((t > x[-1]) | (np.abs(t - x[-1]) <= _ROUNDOFF), b[-1], out)
        out = np.where((t < x[0]) | (np.abs(t - x[0]) <= _ROUNDOFF), b[0], out)
        return out


@dataclass(frozen=True, eq=False)
class PiecewiseLinearFunction(_KnotFunction):
    """Linear interpolation between knots, linear extrapolation with the end slopes."""

    @staticmethod
    def _coefficients(x, y) -> dict:
        slopes = np.diff(y) / np.maximum(np.diff(x), _TINY)
        return {"_b": np.append(slopes, slopes[-1])}

    def value(self, t):
        t = np.asarray(t, dtype=float)
        x, y, b = self.x, self.y, self._b
        k = _segment(x, t)
        out = y[k] + (t - x[k]) * b[k]
        out = np.where(np.abs(t - x[-1]) <= _ROUNDOFF, y[-1], out)
        out = np.where(np.abs(t - x[0]) <= _ROUNDOFF, y[0], out)
        out = np.where(t > x[-1], y[-1] + (t - x[-1]) * b[-1], out)
        return out

    def derivative(self, t):
        t = np.asarray(t, dtype=float)
        k = _segment(self.x, t)
        out = self._b[k]
        out = np.where(t > self.x[-1], self._b[-1], out)
        return out


@dataclass(frozen=True, eq=False)
class MultiplierFunction:
    """f(x) = scale * function(x) (OpenSim MultiplierFunction)."""

    function: object
    scale: float = 1.0

    def value(self, x):
        return self.scale * self.function.value(x)

    def derivative(self, x):
        return self.scale * self.function.derivative(x)


FUNCTION_TYPES = {
    "Constant": Constant,
    "LinearFunction": LinearFunction,
    "PolynomialFunction": PolynomialFunction,
    "SimmSpline": SimmSpline,
    "NaturalCubicSpline": SimmSpline,
    "PiecewiseLinearFunction": PiecewiseLinearFunction,
    "MultiplierFunction": MultiplierFunction,
}
