"""Rectangle <-> contour correspondence of Kohout et al. (GRAPP 2012, section 3.3, Fig. 7).

Both polygons are clockwise. The template rectangle in the plane frame is
``Q0=(0,0), Q1=(0,ey), Q2=(ex,ey), Q3=(ex,0)`` (sides ey, ex, ey, ex). The contour chain
``P0..Pm`` (``Pm = P0``) starts at the contour vertex closest to ``Q0`` and is split into
four parts, part ``j`` matching rectangle side ``Qj -> Qj+1``. With ``k`` the ratio of the
rectangle perimeter to the contour perimeter, the error of a part is
``(side_j - k * length(part_j))**2`` and the split minimises the sum of the four errors.
Each side is then subdivided into as many segments as its part with the same length
ratios, and ``Pi <-> Qi``.

Continuous rule (used by `fibres.slicing.morph.slice_maps`; a departure from the paper). The
paper snaps the start to a contour *vertex* and the split points to vertices. Between two
neighbouring planes the vertices of a general mesh slide along the contour (a plane meets
other edges), so the snapped start and splits jump by up to a contour segment from plane
to plane and the fibres wobble by about a segment (measured 7.5e-3 of the length on a
two-ring cylinder whose every section is the same 64-gon). `correspond_continuous`
instead starts at a point of the contour *curve* (on an edge: segment + fraction): the
soft closest point to ``Q0`` (`soft_start`; the exact closest point where that is
unambiguous, continuous where two parts of the contour are about as near), and puts the
three split points at the exact arc positions where ``k * length(part_j) = side_j``, i.e.
the paper's error made zero by letting the split points leave the vertices; the four
points are inserted into the contour as vertices. The same contour curve, however it is
meshed, then gets the same correspondence, and the correspondence depends continuously on
the plane height.

Exact minimisation (the paper's vertex rule, `split_chain`). With ``x_i = k * (arc
length from P0 to Pi)`` and the ideal split
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

# the plan's soft anchor points (re-exported here, where the correspondence is)
from .soft_anchor import (ARC_GAP, ARC_WINDOW, SOFT_CUTOFF, SOFT_FLOOR, SOFT_SPREAD,  # noqa: F401
                   _gauss_segment, _order_arcs, _soft_anchor_loop, anchor_kernel)
from .contour_points import (SPLIT_SMOOTHING, _contour_segments, closest_points,  # noqa: F401 - re-exported
                             insert_points, ratio_points, smooth_split_points)
from .correspondence_kernels import _soft_start_loop, _start_kernel

__all__ = ["rectangle", "start_vertex", "split_chain", "subdivide_rectangle", "correspond",
           "split_fractions", "closest_points", "soft_start", "ratio_points",
           "insert_points", "correspond_continuous", "smooth_split_points",
           "SPLIT_SMOOTHING"]

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


def _side_lengths(polygon) -> np.ndarray:
    """(n,) lengths of the sides of a closed (n, 2) polygon, side i from vertex i to i + 1."""
    return np.hypot(*(np.roll(polygon, -1, axis=0) - polygon).T)


def correspond(contour, rect, *, start=None, splits=None):
    """Match a clockwise contour to the clockwise template rectangle (Kohout 2012, Fig. 7).

    The paper's vertex rule (start vertex, minimal-error split), kept as the reference;
    the decomposition uses `correspond_continuous` (see the module docstring).

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
    seg = _side_lengths(P)
    if splits is None:
        sides = _side_lengths(rect)
        splits = split_chain(seg, sides)
    Q = subdivide_rectangle(rect, seg, splits)
    return P, Q, int(start), np.asarray(splits, dtype=np.int64)



def split_fractions(rect) -> np.ndarray:
    """Arc fractions of the corners ``Q1, Q2, Q3`` along the rectangle's perimeter from ``Q0``.

    Parameters
    ----------
    rect : (4, 2) float

    Returns
    -------
    (3,) float
        Where the continuous rule puts the split points on the contour, as fractions of
        its length after the start (``k * length(part_j) = side_j``).
    """
    rect = np.asarray(rect, dtype=float)
    sides = _side_lengths(rect)
    return np.cumsum(sides)[:3] / sides.sum()


def correspond_continuous(contour, rect):
    """Match a clockwise contour to the template rectangle with the continuous rule.

    Kohout 2012 §3.3 with the start and split points off the vertices (module docstring):
    ``P0`` is the soft closest contour point to ``Q0`` (`soft_start`) and the split points
    lie at the arc fractions `split_fractions` after it; the four points are inserted as
    vertices. Reference implementation of what `fibres.slicing.morph.slice_maps` does for all
    planes.

    Parameters
    ----------
    contour, rect
        As for `correspond`, with m >= 3.

    Returns
    -------
    P : (m + 4, 2) float
        The contour with the points inserted, rolled so that ``P[0]`` is the start point.
    Q : (m + 4, 2) float
        The subdivided rectangle, ``P[i] <-> Q[i]``; the corners match the four points.
    seg : (4,) int64
    tau : (4,) float
        Where the start and the three split points lie on the input contour.
    """
    contour = np.asarray(contour, dtype=float)
    rect = np.asarray(rect, dtype=float)
    m = np.array([contour.shape[0]])
    offs = np.array([0, contour.shape[0]])
    s0, t0, p0 = soft_start(contour, m, offs, rect[0])
    s1, t1, p1 = ratio_points(contour, m, offs, s0, t0, split_fractions(rect))
    seg = np.concatenate([s0[:, None], s1], axis=1)
    tau = np.concatenate([t0[:, None], t1], axis=1)
    new, index = insert_points(contour, m, offs, seg, tau,
                               np.concatenate([p0[:, None], p1], axis=1))
    start = int(index[0, 0])
    P = np.roll(new, -start, axis=0)
    splits = (index[0, 1:] - start) % new.shape[0]
    Q = subdivide_rectangle(rect, _side_lengths(P), splits)
    return P, Q, seg[0], tau[0]


def soft_start(pts, m, offs, q0, *, fractions=(), compiled=True):
    """Start point of every contour: the *soft* closest point to the rectangle corner ``Q0``.

    Kohout 2012 §3.3 starts each contour at its point closest to ``Q0``. That point jumps
    round the contour wherever two distant parts of it are about as near to ``Q0`` -- which
    happens between neighbouring planes of real muscles whose sections are far from the box
    corner (measured on the LHDL gluteus maximus: 17 mm between two planes 14 mm apart, and
    a quarter turn of the whole correspondence near its origin, both visible as seams in
    the fibres) -- and, at a grazing angle, it slides along a facet as the facets'
    directions change from plane to plane (a cylinder whose vertices are jittered round
    the circle: 1.3e-3 of the length against 1.3e-4 with this rule). Departure: the start
    is a soft closest point, as a plan places its carried start on a deformed copy
    (`_soft_anchor_loop`): the weighted mean arc position with the weight
    ``exp(-(d^2 - d_min^2) / sigma^2)``, ``sigma = SOFT_SPREAD d_min``, integrated exactly
    along each segment (`_gauss_segment`), the positions unwrapped around their circular
    mean. It is the closest point where that is well defined (a narrow weight), moves
    continuously between two about equally near parts instead of jumping, averages the
    facets' noise, and is the same for any meshing of the same contour curve (splitting a
    segment changes no integral; only the unwrapping reference, whose far side carries no
    weight).

    Parameters
    ----------
    pts : (K, 2) float
        Closed contours back to back (plane ``s`` is ``pts[offs[s]:offs[s + 1]]``).
    m : (S,) int
    offs : (S + 1,) int
    q0 : (2,) float
    fractions : (F,) float, optional
        Also return the points at these fractions of the length after the start, as
        `ratio_points` does (e.g. `split_fractions`), in the same pass.
    compiled : bool
        Kept for callers; the loop always runs in Python (no compiled kernels).

    Returns
    -------
    seg : (S,) int64, or (S, 1 + F) with ``fractions``
        Local segment index of each start (and split point).
    tau : (S,) float, or (S, 1 + F)
    point : (S, 2) float, or (S, 1 + F, 2)
    """
    kernel = _start_kernel() if compiled else _soft_start_loop
    f = np.ascontiguousarray(fractions, dtype=float).reshape(-1)
    pts = np.ascontiguousarray(pts, dtype=float)
    seg, tk, point = kernel(pts, np.ascontiguousarray(m, dtype=np.int64),
                            np.ascontiguousarray(offs, dtype=np.int64),
                            np.ascontiguousarray(q0, dtype=float), f, SOFT_SPREAD, SOFT_FLOOR,
                            np.empty(pts.shape[0]))
    if np.ndim(fractions) == 0 or len(fractions) == 0:
        return seg[:, 0], tk[:, 0], point[:, 0]
    return seg, tk, point
