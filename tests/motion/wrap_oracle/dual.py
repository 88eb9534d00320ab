"""Forward-mode automatic differentiation on numpy arrays, for the numpy oracle of the wrapping.

OpenSim's wrap algorithms (WrapCylinder, WrapSphere, WrapEllipsoid, WrapTorus) are heuristic
and iterative: the length they return is not exactly a geodesic, so the textbook derivative
("unit vector from the tangent point") does not match OpenSim's -dL/dq to 1e-5 m. Instead the
wrap code is written once on `Dual` arrays: every value carries its exact derivative with
respect to D seed variables (the end points in the wrap frame, or the model coordinates), and
each arithmetic step applies the chain rule. Branches and loop counts are taken from the values
(as OpenSim takes them), so the derivative is the exact derivative of the same piecewise-smooth
function that OpenSim evaluates.

A `Dual` holds ``v`` (S) and ``d`` (S + (D,)); constants have ``d`` of trailing size 1 (zeros)
and broadcast. Only what the wrap code needs is implemented.
"""
from __future__ import annotations

import numpy as np

__all__ = ["Dual", "lift", "where", "sqrt", "arccos", "arcsin", "sin", "cos", "arctan2",
           "stack", "dot", "cross", "norm", "normalize_or_zero", "value", "solve", "scatter", "dsize",
           "SegmentWrap", "segment_wrap", "seed_points"]


class Dual:
    """An array of values ``v`` (S) with derivatives ``d`` (S + (D,))."""

    __slots__ = ("v", "d")
    __array_priority__ = 1000

    def __init__(self, v, d=None):
        v = np.asarray(v, dtype=float)
        if d is None:
            d = np.zeros(v.shape + (1,))
        self.v = v
        self.d = np.asarray(d, dtype=float)

    # -- shape ---------------------------------------------------------------------------
    @property
    def shape(self):
        return self.v.shape

    def __getitem__(self, key):
        if not isinstance(key, tuple):
            key = (key,)
        dkey = key + (slice(None),) if any(k is Ellipsis for k in key) else key
        return Dual(self.v[key], self.d[dkey])

    def sum(self, axis=-1):
        """Sum over one axis of the value (negative axes count from the value's end)."""
        ax = axis if axis < 0 else axis - self.v.ndim
        return Dual(self.v.sum(axis=ax), self.d.sum(axis=ax - 1))

    def expand(self, axis=-1):
        """Insert a length-1 axis in the value (negative axis counts from the value's end)."""
        ax = axis if axis < 0 else axis - self.v.ndim - 1
        return Dual(np.expand_dims(self.v, ax), np.expand_dims(self.d, ax - 1))

    # -- arithmetic ------------------------------------------------------------------------
    def __neg__(self):
        return Dual(-self.v, -self.d)

    def __add__(self, o):
        if isinstance(o, Dual):
            return Dual(self.v + o.v, self.d + o.d)
        return Dual(self.v + o, self.d + np.zeros(np.shape(o) + (1,)))

    __radd__ = __add__

    def __sub__(self, o):
        if isinstance(o, Dual):
            return Dual(self.v - o.v, self.d - o.d)
        return Dual(self.v - o, self.d + np.zeros(np.shape(o) + (1,)))

    def __rsub__(self, o):
        return Dual(o - self.v, -self.d + np.zeros(np.shape(o) + (1,)))

    def __mul__(self, o):
        if isinstance(o, Dual):
            d = self.d * o.v[..., None]
            other = self.v[..., None] * o.d
            if d.shape == np.broadcast_shapes(d.shape, other.shape):
                d += other          # in place: one temporary fewer on (S, D) arrays
            else:
                d = d + other
            return Dual(self.v * o.v, d)
        o = np.asarray(o, dtype=float)
        return Dual(self.v * o, self.d * o[..., None])

    __rmul__ = __mul__

    def __truediv__(self, o):
        if isinstance(o, Dual):
            q = self.v / o.v
            return Dual(q, (self.d - q[..., None] * o.d) / o.v[..., None])
        o = np.asarray(o, dtype=float)
        return Dual(self.v / o, self.d / o[..., None])

    def __rtruediv__(self, o):
        q = o / self.v
        return Dual(q, -q[..., None] * self.d / self.v[..., None])

    def __pow__(self, n):
        n = float(n)
        return Dual(self.v ** n, (n * self.v ** (n - 1))[..., None] * self.d)

    # comparisons act on values only
    def __lt__(self, o):
        return self.v < value(o)

    def __le__(self, o):
        return self.v <= value(o)

    def __gt__(self, o):
        return self.v > value(o)

    def __ge__(self, o):
        return self.v >= value(o)

    def __repr__(self):
        return f"Dual(v={self.v!r}, d.shape={self.d.shape})"


def dsize(*items) -> int:
    """Common number of derivative directions (a constant's 1 broadcasts, also to 0)."""
    return int(np.broadcast_shapes(*[(lift(i).d.shape[-1],) for i in items])[0])


def value(x):
    """The value array of a Dual, or ``x`` itself."""
    return x.v if isinstance(x, Dual) else np.asarray(x, dtype=float)


def lift(x) -> Dual:
    """``x`` as a Dual (constants get zero derivatives)."""
    return x if isinstance(x, Dual) else Dual(x)


def where(mask, a, b) -> Dual:
    """Elementwise choice by a value-shaped boolean mask (broadcasts like np.where)."""
    a, b = lift(a), lift(b)
    mask = np.asarray(mask, dtype=bool)
    return Dual(np.where(mask, a.v, b.v), np.where(mask[..., None], a.d, b.d))


def _unary(x, f, df):
    x = lift(x)
    return Dual(f(x.v), df(x.v)[..., None] * x.d)


def sqrt(x) -> Dual:
    """Square root; at 0 the derivative is taken as 0 (a zero-length vector's norm)."""
    x = lift(x)
    s = np.sqrt(x.v)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(s > 0.0, 0.5 / s, 0.0)
    return Dual(s, g[..., None] * x.d)


def _asin_slope(v):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.abs(v) < 1.0, 1.0 / np.sqrt(1.0 - v * v), 0.0)


def arccos(x) -> Dual:
    """arccos; at +-1 (coincident directions) the derivative is taken as 0."""
    return _unary(x, np.arccos, lambda v: -_asin_slope(v))


def arcsin(x) -> Dual:
    return _unary(x, np.arcsin, _asin_slope)


def sin(x) -> Dual:
    return _unary(x, np.sin, np.cos)


def cos(x) -> Dual:
    return _unary(x, np.cos, lambda v: -np.sin(v))


def arctan2(y, x) -> Dual:
    y, x = lift(y), lift(x)
    r2 = x.v * x.v + y.v * y.v
    return Dual(np.arctan2(y.v, x.v), (x.v / r2)[..., None] * y.d - (y.v / r2)[..., None] * x.d)


def stack(items, axis=-1) -> Dual:
    """Stack Duals of equal value shape along a new last value axis (axis must be -1)."""
    if axis != -1:
        raise ValueError("only axis=-1 is supported")
    items = [lift(i) for i in items]
    shape = np.broadcast_shapes(*[i.v.shape for i in items])
    nd = dsize(*items)
    v = np.stack([np.broadcast_to(i.v, shape) for i in items], axis=-1)
    d = np.stack([np.broadcast_to(i.d, shape + (nd,)) for i in items], axis=-2)
    return Dual(v, d)


def dot(a, b) -> Dual:
    """Dot product over the last value axis (length 3).

    d(a . b) = da . b + a . db, summed component by component rather than as a product array
    summed over its middle axis (2.5x faster on (8000, 3, 5) derivative arrays; ``einsum``
    is faster on equal shapes but much slower where the operands broadcast).
    """
    a, b = lift(a), lift(b)
    av, bv, ad, bd = a.v, b.v, a.d, b.d
    v = av[..., 0] * bv[..., 0] + av[..., 1] * bv[..., 1] + av[..., 2] * bv[..., 2]
    d = (ad[..., 0, :] * bv[..., 0, None] + ad[..., 1, :] * bv[..., 1, None] + ad[..., 2, :] * bv[..., 2, None]
         + bd[..., 0, :] * av[..., 0, None] + bd[..., 1, :] * av[..., 1, None] + bd[..., 2, :] * av[..., 2, None])
    return Dual(v, d)


def cross(a, b) -> Dual:
    """Cross product over the last value axis (length 3); d(a x b) = da x b + a x db."""
    a, b = lift(a), lift(b)
    av, bv, ad, bd = a.v, b.v, a.d, b.d
    shape = np.broadcast_shapes(av.shape, bv.shape)
    v = np.empty(shape)
    d = np.empty(shape + (dsize(a, b),))
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        v[..., i] = av[..., j] * bv[..., k] - av[..., k] * bv[..., j]
        d[..., i, :] = (ad[..., j, :] * bv[..., k, None] - ad[..., k, :] * bv[..., j, None]
                        + av[..., j, None] * bd[..., k, :] - av[..., k, None] * bd[..., j, :])
    return Dual(v, d)


def norm(a) -> Dual:
    """Euclidean norm over the last value axis."""
    return sqrt(dot(a, a))


def normalize_or_zero(a, tiny=0.0):
    """(unit vector, magnitude); the zero vector where the magnitude is <= tiny (WrapMath)."""
    a = lift(a)
    n = norm(a)
    ok = n.v > tiny
    safe = where(ok, n, 1.0)
    unit = a / safe.expand(-1)
    return where(ok[..., None], unit, 0.0 * a), n


def scatter(full: Dual, sel, part: Dual) -> Dual:
    """Copy of ``full`` with the leading-axis rows ``sel`` replaced by ``part``."""
    full, part = lift(full), lift(part)
    nd = dsize(full, part)
    v = full.v.copy()
    d = np.array(np.broadcast_to(full.d, full.v.shape + (nd,)))
    v[sel] = part.v
    d[sel] = np.broadcast_to(part.d, part.v.shape + (nd,))
    return Dual(v, d)


def solve(a, b) -> Dual:
    """Solve ``a x = b`` for stacks of small matrices: a (..., n, n), b (..., n)."""
    a, b = lift(a), lift(b)
    x = np.linalg.solve(a.v, b.v[..., None])[..., 0]
    # d x = a^-1 (d b - d a x)
    da_x = np.einsum("...ijk,...j->...ik", a.d, x)
    rhs = b.d - da_x
    dx = np.linalg.solve(a.v, rhs)
    return Dual(x, dx)


# --- a wrapped segment's result, for the per-object public functions ------------------------
from dataclasses import dataclass  # noqa: E402


@dataclass(frozen=True)
class SegmentWrap:
    """One straight segment p1->p2 wrapped over one wrap object, per frame.

    Attributes
    ----------
    t1, t2 : (F, 3) float
        Tangent points in the wrap frame (NaN where not wrapped).
    wrapped : (F,) bool
        OpenSim returned ``wrapped`` or ``mandatoryWrap``.
    code : (F,) int
        OpenSim's WrapAction: 0 noWrap, 1 insideRadius, 2 wrapped, 3 mandatoryWrap.
    arc : (F,) float
        Path length on the surface between t1 and t2 (0 where not wrapped).
    length : (F,) float
        ``|t1-p1| + arc + |p2-t2|`` where wrapped, else ``|p2-p1|``.
    dl_dp1, dl_dp2 : (F, 3) float
        Exact derivatives of ``length`` with respect to p1 and p2.
    """

    t1: np.ndarray
    t2: np.ndarray
    wrapped: np.ndarray
    code: np.ndarray
    arc: np.ndarray
    length: np.ndarray
    dl_dp1: np.ndarray
    dl_dp2: np.ndarray

    def __post_init__(self):
        for name in ("t1", "t2", "wrapped", "code", "arc", "length", "dl_dp1", "dl_dp2"):
            arr = np.array(getattr(self, name), copy=True)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)


def seed_points(p1, p2):
    """p1, p2 (F, 3) as Duals seeded with the identity over 6 variables (p1 then p2)."""
    p1 = np.asarray(p1, dtype=float)
    p2 = np.asarray(p2, dtype=float)
    if p1.ndim != 2 or p1.shape[-1] != 3 or p2.shape != p1.shape:
        raise ValueError(f"p1 and p2 must both be (F, 3); got {p1.shape} and {p2.shape}")
    eye = np.eye(6)
    d1 = np.broadcast_to(eye[:3], p1.shape + (6,)).copy()
    d2 = np.broadcast_to(eye[3:], p2.shape + (6,)).copy()
    return Dual(p1, d1), Dual(p2, d2)


def segment_wrap(fn, p1, p2, **options) -> SegmentWrap:
    """Run a wrap-line function on seeded points and package lengths and gradients."""
    a, b = seed_points(p1, p2)
    with np.errstate(all="ignore"):
        code, r1, r2, arc = fn(a, b, **options)
        wrapped = code >= 2
        total = norm(r1 - a) + arc + norm(b - r2)
        straight = norm(b - a)
        length = where(wrapped, total, straight)
    w = wrapped[:, None]
    return SegmentWrap(
        t1=np.where(w, r1.v, np.nan), t2=np.where(w, r2.v, np.nan), wrapped=wrapped, code=code,
        arc=np.where(wrapped, arc.v, 0.0), length=length.v,
        dl_dp1=length.d[:, :3], dl_dp2=length.d[:, 3:])
