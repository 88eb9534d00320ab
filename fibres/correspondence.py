"""Rectangle <-> contour correspondence of Kohout et al. (GRAPP 2012, section 3.3, Fig. 7).

Both polygons are clockwise. The template rectangle in the plane frame is
``Q0=(0,0), Q1=(0,ey), Q2=(ex,ey), Q3=(ex,0)`` (sides ey, ex, ey, ex). The contour chain
``P0..Pm`` (``Pm = P0``) starts at the contour vertex closest to ``Q0`` and is split into
four parts, part ``j`` matching rectangle side ``Qj -> Qj+1``. With ``k`` the ratio of the
rectangle perimeter to the contour perimeter, the error of a part is
``(side_j - k * length(part_j))**2`` and the split minimises the sum of the four errors.
Each side is then subdivided into as many segments as its part with the same length
ratios, and ``Pi <-> Qi``.

Exact minimisation. With ``x_i = k * (arc length from P0 to Pi)`` and the ideal split
positions ``X = (a0, a0+a1, a0+a1+a2)``, the error of a split ``(i1, i2, i3)`` is the
quadratic form ``y^T A y`` in ``y_j = x_{i_j} - X_j`` with ``A = tridiag(-1, 2, -1)``
(3x3). Any split no worse than a feasible one of error ``E0`` has
``|y_j| <= sqrt(E0 * inv(A)_jj)``, ``inv(A) = [[3,2,1],[2,4,2],[1,2,3]] / 4``; the few
vertices inside those windows are enumerated exhaustively, so the minimum is exact
(ties: the lexicographically smallest split).
"""
from __future__ import annotations

from bisect import bisect_left, bisect_right
from math import sqrt

import numpy as np

__all__ = ["rectangle", "start_vertex", "split_chain", "subdivide_rectangle", "correspond"]

_AINV_DIAG = (0.75, 1.0, 0.75)


def rectangle(ex: float, ey: float) -> np.ndarray:
    """The clockwise template rectangle ``Q0..Q3`` of a box cross-section.

    Parameters
    ----------
    ex, ey : float
        Box extents along its x and y axes.

    Returns
    -------
    (4, 2) float
    """
    return np.array([[0.0, 0.0], [0.0, ey], [ex, ey], [ex, 0.0]])


def start_vertex(contour, q0) -> int:
    """Index of the contour vertex closest to the rectangle's first vertex ``Q0``.

    Parameters
    ----------
    contour : (m, 2) float
    q0 : (2,) float

    Returns
    -------
    int
    """
    d = np.asarray(contour, dtype=float) - np.asarray(q0, dtype=float)
    return int(np.argmin(np.einsum("ij,ij->i", d, d)))


def split_chain(seg_lengths, sides) -> np.ndarray:
    """Split a closed chain of m segments into four parts matching four rectangle sides.

    Parameters
    ----------
    seg_lengths : (m,) float
        Lengths of segments ``P0P1, ..., P(m-1)Pm``; m >= 4.
    sides : (4,) float
        Rectangle side lengths in order ``Q0Q1, Q1Q2, Q2Q3, Q3Q0``.

    Returns
    -------
    (3,) int64
        ``i1 < i2 < i3``: part j runs from ``P_{i_j}`` to ``P_{i_{j+1}}`` (``i0 = 0``,
        ``i4 = m``); each part has at least one segment. Minimises
        ``sum_j (sides_j - k * length_j)**2`` exactly, ``k = sum(sides) / sum(seg_lengths)``.
    """
    seg = np.asarray(seg_lengths, dtype=float)
    m = seg.size
    if m < 4:
        raise ValueError(f"a chain of {m} segments cannot be split into four parts")
    a = [float(v) for v in np.asarray(sides, dtype=float)]
    cum = np.cumsum(seg)
    perimeter = float(cum[-1])
    k = sum(a) / perimeter if perimeter > 0 else 0.0
    xs = [0.0] + (k * cum).tolist()                  # x_i, i = 0..m, nondecreasing
    X = (a[0], a[0] + a[1], a[0] + a[1] + a[2])

    def err(c):
        y1, y2, y3 = xs[c[0]] - X[0], xs[c[1]] - X[1], xs[c[2]] - X[2]
        return y1 * y1 + (y2 - y1) ** 2 + (y3 - y2) ** 2 + y3 * y3

    # a feasible start: the vertex nearest to each ideal position, made strictly increasing
    near = []
    for t in X:
        i = min(max(bisect_left(xs, t), 1), m - 1)
        near.append(i - 1 if abs(xs[i - 1] - t) <= abs(xs[i] - t) else i)
    i1 = min(max(near[0], 1), m - 3)
    i2 = min(max(near[1], i1 + 1), m - 2)
    i3 = min(max(near[2], i2 + 1), m - 1)
    best = (i1, i2, i3)
    best_err = err(best)
    win = [sqrt(best_err * d) * (1.0 + 1e-12) + 1e-300 for d in _AINV_DIAG]
    lo = [max(bisect_left(xs, X[j] - win[j]), 1) for j in range(3)]
    hi = [min(bisect_right(xs, X[j] + win[j]), m) for j in range(3)]
    for c1 in range(lo[0], hi[0]):                  # lexicographic: first minimum wins
        for c2 in range(max(lo[1], c1 + 1), hi[1]):
            for c3 in range(max(lo[2], c2 + 1), hi[2]):
                e = err((c1, c2, c3))
                if e < best_err or (e == best_err and (c1, c2, c3) < best):
                    best, best_err = (c1, c2, c3), e
    return np.array(best, dtype=np.int64)


def _error(x, X, trip) -> np.ndarray:
    """Total squared error (n,) of splits ``trip`` (n, 3), via ``y^T A y``."""
    y = x[trip] - X
    return y[:, 0] ** 2 + (y[:, 1] - y[:, 0]) ** 2 + (y[:, 2] - y[:, 1]) ** 2 + y[:, 2] ** 2


def subdivide_rectangle(rect, seg_lengths, splits) -> np.ndarray:
    """Subdivide each rectangle side like its part of the chain (same length ratios).

    Parameters
    ----------
    rect : (4, 2) float
        ``Q0..Q3``.
    seg_lengths : (m,) float
    splits : (3,) int

    Returns
    -------
    (m, 2) float
        ``Q_i`` for ``i = 0..m-1``; ``Q_{splits[j-1]}`` is corner ``j``.
    """
    seg = np.asarray(seg_lengths, dtype=float)
    m = seg.size
    bounds = np.concatenate([[0], np.asarray(splits, dtype=np.int64), [m]])
    c = np.concatenate([[0.0], np.cumsum(seg)])
    i = np.arange(m)
    part = np.searchsorted(bounds, i, side="right") - 1          # (m,)
    b0, b1 = bounds[part], bounds[part + 1]
    span = c[b1] - c[b0]
    frac = np.where(span > 0, (c[i] - c[b0]) / np.where(span > 0, span, 1.0),
                    (i - b0) / (b1 - b0))
    corners = np.asarray(rect, dtype=float)
    q_from = corners[part]
    q_to = corners[(part + 1) % 4]
    return q_from + frac[:, None] * (q_to - q_from)


def correspond(contour, rect, *, start=None, splits=None):
    """Match a clockwise contour to the clockwise template rectangle (Kohout 2012, Fig. 7).

    Parameters
    ----------
    contour : (m, 2) float
        Clockwise, not closed, m >= 4.
    rect : (4, 2) float
        Clockwise ``Q0..Q3``.
    start : int, optional
        Contour index to use as ``P0`` (a reused plan); default: closest to ``Q0``.
    splits : (3,) int, optional
        Split to use (relative to ``start``; a reused plan); default: the minimiser.

    Returns
    -------
    P : (m, 2) float
        The contour rolled so that ``P[0]`` is the start vertex.
    Q : (m, 2) float
        The subdivided rectangle, ``P[i] <-> Q[i]``.
    start : int
    splits : (3,) int64
    """
    contour = np.asarray(contour, dtype=float)
    rect = np.asarray(rect, dtype=float)
    if start is None:
        start = start_vertex(contour, rect[0])
    P = np.roll(contour, -int(start), axis=0)
    seg = np.hypot(*(np.roll(P, -1, axis=0) - P).T)
    if splits is None:
        sides = np.hypot(*(np.roll(rect, -1, axis=0) - rect).T)
        splits = split_chain(seg, sides)
    Q = subdivide_rectangle(rect, seg, splits)
    return P, Q, int(start), np.asarray(splits, dtype=np.int64)
