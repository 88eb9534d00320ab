"""Rectangle <-> contour correspondence of Kohout et al. (GRAPP 2012, section 3.3, Fig. 7).

Both polygons are clockwise. The template rectangle in the plane frame is
``Q0=(0,0), Q1=(0,ey), Q2=(ex,ey), Q3=(ex,0)`` (sides ey, ex, ey, ex). The contour chain
``P0..Pm`` (``Pm = P0``) starts at the contour vertex closest to ``Q0`` and is split into
four parts, part ``j`` matching rectangle side ``Qj -> Qj+1``. With ``k`` the ratio of the
rectangle perimeter to the contour perimeter, the error of a part is
``(side_j - k * length(part_j))**2`` and the split minimises the sum of the four errors.
Each side is then subdivided into as many segments as its part with the same length
ratios, and ``Pi <-> Qi``.

Continuous rule (used by `fibres.morph.slice_maps`; a departure from the paper). The
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
from math import erf, erfc, exp, pi, sqrt

import numpy as np

__all__ = ["rectangle", "start_vertex", "split_chain", "subdivide_rectangle", "correspond",
           "split_fractions", "closest_points", "soft_start", "ratio_points",
           "insert_points", "correspond_continuous"]

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
    sides = np.hypot(*(np.roll(rect, -1, axis=0) - rect).T)
    return np.cumsum(sides)[:3] / sides.sum()


def _contour_segments(pts, m, offs):
    """Plane, local index, next vertex and length of every segment of contours stored back
    to back: (K,) each."""
    sl = np.repeat(np.arange(m.size), m)
    j = np.arange(offs[-1]) - offs[sl]
    nxt = offs[sl] + (j + 1) % m[sl]
    d = pts[nxt] - pts
    return sl, j, nxt, np.hypot(d[:, 0], d[:, 1])


def closest_points(pts, m, offs, targets):
    """Exact closest point of every contour to each of its plane's targets.

    Parameters
    ----------
    pts : (K, 2) float
        Closed contours back to back (plane ``s`` is ``pts[offs[s]:offs[s + 1]]``).
    m : (S,) int
        Vertices per contour (``offs = [0, cumsum(m)]``).
    offs : (S + 1,) int
    targets : (S, A, 2) float

    Returns
    -------
    seg : (S, A) int64
        Local index ``j`` of the segment ``P_j -> P_{j+1}`` carrying the point (the first
        one on ties: the closest point is a continuous function of the target except where
        two parts of the contour are equally near).
    tau : (S, A) float
        Position along that segment, in [0, 1].
    point : (S, A, 2) float
    """
    m = np.asarray(m, dtype=np.int64)
    offs = np.asarray(offs, dtype=np.int64)
    targets = np.asarray(targets, dtype=float)
    n_s, n_a = targets.shape[:2]
    sl, _, nxt, _ = _contour_segments(pts, m, offs)
    d = pts[nxt] - pts                                                # (K, 2)
    dx, dy = d[:, 0:1], d[:, 1:2]
    dd = dx * dx + dy * dy
    rx = targets[sl, :, 0] - pts[:, 0:1]                              # (K, A)
    ry = targets[sl, :, 1] - pts[:, 1:2]
    tau = np.clip((rx * dx + ry * dy) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    gx, gy = rx - tau * dx, ry - tau * dy
    g2 = gx * gx + gy * gy
    best = g2 == np.minimum.reduceat(g2, offs[:-1], axis=0)[sl]
    seg = np.empty((n_s, n_a), dtype=np.int64)
    for a in range(n_a):                                  # targets per plane (1 or 4)
        hit = np.flatnonzero(best[:, a])
        seg[:, a] = hit[np.searchsorted(sl[hit], np.arange(n_s))]        # first minimum
    tk = np.take_along_axis(tau[seg], np.arange(n_a)[None, :, None], axis=2)[..., 0]
    point = pts[seg] + tk[..., None] * d[seg]
    return seg - offs[:-1, None], tk, point


def ratio_points(pts, m, offs, seg0, tau0, fractions):
    """Points at given fractions of each contour's length after a start point.

    Parameters
    ----------
    pts : (K, 2) float
    m : (S,) int
    offs : (S + 1,) int
    seg0 : (S,) int
    tau0 : (S,) float
        The start point of each contour: segment and position along it.
    fractions : (F,) float
        In [0, 1), e.g. `split_fractions`.

    Returns
    -------
    seg : (S, F) int64
    tau : (S, F) float
    point : (S, F, 2) float
        The points at arc length ``a0 + f * length`` (cyclic), ``a0`` the start's. A point
        at a vertex is reported at the start of the next segment of nonzero length.
    """
    m = np.asarray(m, dtype=np.int64)
    offs = np.asarray(offs, dtype=np.int64)
    _, _, nxt, seg_len = _contour_segments(pts, m, offs)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])                 # (K + 1,) global
    lo, hi = offs[:-1], offs[1:]
    base = cum[lo]
    length = cum[hi] - base
    g0 = lo + np.asarray(seg0, dtype=np.int64)
    a0 = cum[g0] - base + np.asarray(tau0, dtype=float) * seg_len[g0]
    a = a0[:, None] + np.asarray(fractions, dtype=float)[None, :] * length[:, None]
    a = np.where(a >= length[:, None], a - length[:, None], a)        # once round at most
    target = base[:, None] + a
    g = np.clip(np.searchsorted(cum, target, side="right") - 1, lo[:, None], hi[:, None] - 1)
    span = seg_len[g]
    tk = np.where(span > 0, np.clip((target - cum[g]) / np.where(span > 0, span, 1.0), 0.0,
                                    1.0), 0.0)
    point = pts[g] + tk[..., None] * (pts[nxt[g]] - pts[g])
    return g - lo[:, None], tk, point


def insert_points(pts, m, offs, seg, tau, point, *, shift_kernel=None):
    """Insert points lying on the contours' segments as new vertices.

    Parameters
    ----------
    pts : (K, 2) float
    m : (S,) int
    offs : (S + 1,) int
    seg, tau : (S, A) int, float
        Where the points lie (`closest_points`, `ratio_points`).
    point : (S, A, 2) float
    shift_kernel : callable, optional
        Compiled ``(pts, m, offs, seg, offs2) -> new`` moving the old vertices
        (`fibres.morph`'s ``_insert_loop``); default: the array expression.

    Returns
    -------
    new : (K + S A, 2) float
        The contours with the points inserted after vertex ``seg`` in the order
        ``(seg, tau, a)``; back to back with ``m + A`` vertices each.
    index : (S, A) int64
        Local index of each inserted point in its new contour.
    """
    m = np.asarray(m, dtype=np.int64)
    offs = np.asarray(offs, dtype=np.int64)
    seg = np.asarray(seg, dtype=np.int64)
    tau = np.asarray(tau, dtype=float)
    n_s, n_a = seg.shape
    aa = np.arange(n_a)
    same = seg[:, None, :] == seg[:, :, None]
    before = ((seg[:, None, :] < seg[:, :, None])
              | (same & (tau[:, None, :] < tau[:, :, None]))
              | (same & (tau[:, None, :] == tau[:, :, None])
                 & (aa[None, None, :] < aa[None, :, None])))
    index = seg + 1 + before.sum(axis=2)                               # (S, A)
    offs2 = np.concatenate([[0], np.cumsum(m + n_a)])
    if shift_kernel is not None:
        new = shift_kernel(pts, m, offs, seg, offs2)
    else:
        sl = np.repeat(np.arange(n_s), m)
        j = np.arange(offs[-1]) - offs[sl]
        shift = (seg[sl] < j[:, None]).sum(axis=1)                     # points before j
        new = np.empty((offs2[-1], 2))
        new[offs2[sl] + j + shift] = pts
    new[(offs2[:-1, None] + index).ravel()] = np.asarray(point, dtype=float).reshape(-1, 2)
    return new, index


def correspond_continuous(contour, rect):
    """Match a clockwise contour to the template rectangle with the continuous rule.

    Kohout 2012 §3.3 with the start and split points off the vertices (module docstring):
    ``P0`` is the soft closest contour point to ``Q0`` (`soft_start`) and the split points
    lie at the arc fractions `split_fractions` after it; the four points are inserted as
    vertices. Reference implementation of what `fibres.morph.slice_maps` does for all
    planes.

    Parameters
    ----------
    contour : (m, 2) float
        Clockwise, not closed, m >= 3.
    rect : (4, 2) float
        Clockwise ``Q0..Q3``.

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
    new, index = insert_points(contour, m, offs, seg, tau, np.concatenate([p0[:, None], p1], axis=1))
    start = int(index[0, 0])
    P = np.roll(new, -start, axis=0)
    splits = (index[0, 1:] - start) % new.shape[0]
    Q = subdivide_rectangle(rect, np.hypot(*(np.roll(P, -1, axis=0) - P).T), splits)
    return P, Q, seg[0], tau[0]


#: Smallest arc length between consecutive start/split points of an anchored contour, as a
#: fraction of its length, where `_order_arcs` has to restore their order.
ARC_GAP = 1e-3

#: Split point k of an anchored contour is searched within this fraction of the contour
#: length around its nominal position after the start (the rectangle corner's arc fraction).
ARC_WINDOW = 0.25


def _order_arcs(a, lo, hi):  # pragma: no cover - compiled by numba (and called by it)
    """Euclidean projection of ``a`` (3,) onto ``lo <= a0 <= a1 <= a2 <= hi``: pool adjacent
    violators (isotonic regression), then clip -- a continuous (1-Lipschitz) map that is
    the identity on ordered input (Barlow et al. 1972, "Statistical inference under order
    restrictions"; clipping the isotonic fit gives the bounded projection)."""
    val = np.empty(3)
    size = np.empty(3, dtype=np.int64)
    nb = 0
    for i in range(3):
        val[nb] = a[i]
        size[nb] = 1
        nb += 1
        while nb > 1 and val[nb - 2] > val[nb - 1]:
            tot = size[nb - 2] + size[nb - 1]
            val[nb - 2] = (val[nb - 2] * size[nb - 2] + val[nb - 1] * size[nb - 1]) / tot
            size[nb - 2] = tot
            nb -= 1
    out = np.empty(3)
    i = 0
    for b in range(nb):
        for _ in range(size[b]):
            out[i] = min(max(val[b], lo), hi)
            i += 1
    return out


# ---------------------------------------------------------------------------------------
# Correspondence points carried by a plan (`fibres.morph.anchored_maps`)

#: Width of the soft closest point: the Gaussian weight of a contour point at distance d
#: from an anchor is ``exp(-(d^2 - d_min^2) / sigma^2)`` with
#: ``sigma^2 = (SOFT_SPREAD d_min)^2 + (SOFT_FLOOR L)^2``.
SOFT_SPREAD = 0.5
SOFT_FLOOR = 1e-7
#: Segments whose weight is below exp(-SOFT_CUTOFF) of the nearest one's are skipped (a
#: change of at most ~1e-17 relative, below rounding).
SOFT_CUTOFF = 40.0


def _erfcx(x):  # pragma: no cover - compiled by numba (and called by it)
    """exp(x^2) erfc(x), x >= 0 (asymptotic series beyond 20, relative error < 1e-11)."""
    if x < 20.0:
        return exp(x * x) * erfc(x)
    y = 1.0 / (x * x)
    return (1.0 - 0.5 * y * (1.0 - 1.5 * y * (1.0 - 2.5 * y * (1.0 - 3.5 * y)))) / (x * sqrt(pi))


def _gauss_segment(ax, px, dx, dim, sigma2):  # pragma: no cover - numba
    """Integral over t in [0, 1] of exp(-(|A - P - t D|^2 - d_c^2) / sigma^2) (d_c the
    distance to the segment's closest point, so the result is <= 1) and the mean t
    under that weight; exact (error functions), so splitting a segment in two changes
    nothing. Returns (integral, mean t, d_c^2)."""
    dd = 0.0
    rd = 0.0
    r2 = 0.0
    for c in range(dim):
        dd += dx[c] * dx[c]
        rd += (ax[c] - px[c]) * dx[c]
        r2 += (ax[c] - px[c]) * (ax[c] - px[c])
    if dd <= 1e-300:
        return 1.0, 0.5, r2
    ts = rd / dd                                   # unclamped projection
    tc = min(max(ts, 0.0), 1.0)
    dc2 = max(r2 - ts * ts * dd + (tc - ts) * (tc - ts) * dd, 0.0)
    beta = dd / sigma2
    sb = sqrt(beta)
    a = -sb * ts
    b = sb * (1.0 - ts)
    if a <= 0.0 <= b:
        f = 0.5 * sqrt(pi) * (erf(b) - erf(a))
        m2 = 0.0
    elif a > 0.0:
        f = 0.5 * sqrt(pi) * (_erfcx(a) - exp(a * a - b * b) * _erfcx(b))
        m2 = a * a
    else:
        f = 0.5 * sqrt(pi) * (_erfcx(-b) - exp(b * b - a * a) * _erfcx(-a))
        m2 = b * b
    i0 = f / sb
    if i0 <= 0.0:
        return 0.0, tc, dc2
    # first moment: t* I0 + (exp(-beta t*^2) - exp(-beta (1 - t*)^2)) / (2 beta), scaled
    i1 = ts * i0 + (exp(-(a * a - m2)) - exp(-(b * b - m2))) / (2.0 * beta)
    return i0, min(max(i1 / i0, 0.0), 1.0), dc2


def _soft_anchor_loop(pts, X, NX, m, offs, AX, NAX, nominal, gap, window,
                      spread, floor):  # pragma: no cover - compiled by numba
    """The four correspondence points of every plane from a plan's anchors, as smooth
    functions of the contour (a soft closest point instead of an argmin).

    For anchor ``A`` the contour is weighted by ``exp(-(d^2 - d_min^2) / sigma^2)`` (d: the
    distance in the matching coordinates ``X`` (K, D) to ``AX`` (S, 4, D); sigma as in
    `SOFT_SPREAD`), times ``max(0, cos)`` of the angle between the contour normal
    (``NX[j] + NX[j+1]``) and the anchor's (``NAX``; zero normals: factor 1), integrated
    exactly along each segment against arc length in the plane (`_gauss_segment`), and
    the point is the weighted mean arc position. Near the contour this is its closest
    point (sigma -> floor); where two far parts of the contour are about as near (a plane
    that has moved through the material), it moves smoothly between them instead of
    jumping. The start is averaged within half a contour around its hard closest point;
    split point k within ``window`` of the length around its nominal place after the
    start, with a weight tapering to zero at the window's ends; the three split
    positions are then put in order (`_order_arcs`, the identity on ordered input).

    Returns segment (S, 4), parameter (S, 4), the points in the plane (S, 4, 2) and
    which planes were reordered (S,)."""
    n_s = m.size
    dim = X.shape[1]
    dn = NX.shape[1]
    seg = np.empty((n_s, 4), dtype=np.int64)
    tk = np.empty((n_s, 4))
    point = np.empty((n_s, 4, 2))
    moved = np.zeros(n_s, dtype=np.bool_)
    arc = np.empty(4)
    b = np.empty(3)
    px = np.empty(dim)
    dx = np.empty(dim)
    ax = np.empty(dim)
    for s in range(n_s):
        o = offs[s]
        ms = m[s]
        cum = np.empty(ms + 1)
        cum[0] = 0.0
        for j in range(ms):
            a = o + j
            nb = o + (j + 1) % ms
            cum[j + 1] = cum[j] + np.hypot(pts[nb, 0] - pts[a, 0], pts[nb, 1] - pts[a, 1])
        length = cum[ms]
        face = np.ones(ms)
        gi = np.empty(ms)
        gt = np.empty(ms)
        gd = np.empty(ms)
        for k in range(4):
            for c in range(dim):
                ax[c] = AX[s, k, c]
            na = 0.0
            for c in range(dn):
                na += NAX[s, k, c] * NAX[s, k, c]
            any_face = False
            if na == 0.0:                               # no normals: every segment
                face[:] = 1.0
                any_face = True
            for j in range(ms if na > 0.0 else 0):
                a = o + j
                nb = o + (j + 1) % ms
                dot = 0.0
                nn = 0.0
                for c in range(dn):
                    nc = NX[a, c] + NX[nb, c]
                    dot += nc * NAX[s, k, c]
                    nn += nc * nc
                face[j] = max(dot, 0.0) / sqrt(nn * na) if nn * na > 0 else 1.0
                if face[j] > 0:
                    any_face = True
            if not any_face:
                face[:] = 1.0
            # window factor of the split points, from the start's arc position
            wf = np.ones(ms)
            if k > 0 and length > 0:
                nom = nominal[k - 1] * length
                for j in range(ms):
                    mid = 0.5 * (cum[j] + cum[j + 1])
                    rel = (mid - arc[0]) % length
                    if rel - nom > 0.5 * length:
                        rel -= length
                    elif rel - nom < -0.5 * length:
                        rel += length
                    z = (rel - nom) / (window * length)
                    wf[j] = max(1.0 - z * z, 0.0)
            # hard closest point (first minimum) among the admissible segments -> d_min
            best = np.inf
            bj = 0
            bt = 0.0
            for j in range(ms):
                if face[j] * wf[j] <= 0 and k > 0:
                    continue
                if face[j] <= 0:
                    continue
                a = o + j
                nb = o + (j + 1) % ms
                dd = 0.0
                rd = 0.0
                for c in range(dim):
                    dc = X[nb, c] - X[a, c]
                    dd += dc * dc
                    rd += (ax[c] - X[a, c]) * dc
                tau = min(max(rd / (dd if dd > 0 else 1.0), 0.0), 1.0)
                g2 = 0.0
                for c in range(dim):
                    gc = ax[c] - X[a, c] - tau * (X[nb, c] - X[a, c])
                    g2 += gc * gc
                gd[j] = g2
                if g2 < best:
                    best = g2
                    bj = j
                    bt = tau
            if best == np.inf or length <= 0:          # nothing admissible: hard point
                arc[k] = cum[bj] + bt * (cum[bj + 1] - cum[bj])
                if k > 0 and length > 0:
                    arc[k] = (arc[k] - arc[0]) % length
                continue
            sigma2 = spread * spread * best + (floor * length) ** 2
            ref = cum[bj] + bt * (cum[bj + 1] - cum[bj]) if k == 0 else arc[0]
            wsum = 0.0
            msum = 0.0
            for j in range(ms):
                w0 = face[j] * wf[j]
                if w0 <= 0 or gd[j] - best > SOFT_CUTOFF * sigma2:
                    continue                    # weight below exp(-SOFT_CUTOFF) of the best
                a = o + j
                nb = o + (j + 1) % ms
                for c in range(dim):
                    px[c] = X[a, c]
                    dx[c] = X[nb, c] - X[a, c]
                i0, tm, dc2 = _gauss_segment(ax, px, dx, dim, sigma2)
                w = w0 * (cum[j + 1] - cum[j]) * exp(-(dc2 - best) / sigma2) * i0
                if w <= 0:
                    continue
                # arc position of the weighted mean point, relative to ref, unwrapped
                pos = cum[j] + tm * (cum[j + 1] - cum[j]) - ref
                centre = 0.0 if k == 0 else nominal[k - 1] * length
                pos = (pos - centre + 0.5 * length) % length - 0.5 * length + centre
                wsum += w
                msum += w * pos
            if wsum > 0:
                arc[k] = (ref + msum / wsum) % length if k == 0 else msum / wsum
            else:
                arc[k] = cum[bj] + bt * (cum[bj + 1] - cum[bj]) if k == 0 else \
                    (cum[bj] + bt * (cum[bj + 1] - cum[bj]) - arc[0]) % length
        # splits: relative arc positions, put in order with gaps (continuous)
        out = b
        if length > 0:
            g = gap * length
            for k in range(3):
                b[k] = arc[k + 1] - (k + 1) * g
            ordered = b[0] >= 0.0 and b[0] <= b[1] and b[1] <= b[2] and b[2] <= length - 4 * g
            out = b
            if not ordered:
                moved[s] = True
                out = _order_arcs(b, 0.0, length - 4 * g)
        for k in range(4):
            if length > 0:
                t = arc[0] if k == 0 else arc[0] + out[k - 1] + k * gap * length
                t = t % length
            else:
                t = 0.0
            j = np.searchsorted(cum, t, side="right") - 1
            j = min(max(j, 0), ms - 1)
            while j > 0 and cum[j + 1] - cum[j] <= 0:
                j -= 1
            span = cum[j + 1] - cum[j]
            seg[s, k] = j
            tk[s, k] = min(max((t - cum[j]) / span, 0.0), 1.0) if span > 0 else 0.0
            a = o + seg[s, k]
            nb = o + (seg[s, k] + 1) % ms
            point[s, k, 0] = pts[a, 0] + tk[s, k] * (pts[nb, 0] - pts[a, 0])
            point[s, k, 1] = pts[a, 1] + tk[s, k] * (pts[nb, 1] - pts[a, 1])
    return seg, tk, point, moved


_ANCHOR_KERNEL = []


def anchor_kernel():
    """`_soft_anchor_loop` compiled with numba (with its helpers), or the Python version."""
    if not _ANCHOR_KERNEL:
        try:
            import numba
        except ImportError:                                 # pragma: no cover - optional
            _ANCHOR_KERNEL.append(_soft_anchor_loop)
        else:
            global _order_arcs, _erfcx, _gauss_segment
            jit = numba.njit(cache=True, nogil=True, error_model="numpy")
            _order_arcs, _erfcx = jit(_order_arcs), jit(_erfcx)
            _gauss_segment = jit(_gauss_segment)
            _ANCHOR_KERNEL.append(jit(_soft_anchor_loop))
    return _ANCHOR_KERNEL[0]


def _soft_start_loop(pts, m, offs, q0, fractions, spread, floor):  # pragma: no cover
    """`soft_start` as one loop over the planes (see there), followed by the points at the
    arc ``fractions`` after the start (`ratio_points`); compiled by numba, or run by
    Python without it. Returns seg (S, 1 + F), tau (S, 1 + F), point (S, 1 + F, 2)."""
    n_s = m.size
    n_p = 1 + fractions.size
    seg = np.zeros((n_s, n_p), dtype=np.int64)
    tk = np.zeros((n_s, n_p))
    point = np.zeros((n_s, n_p, 2))
    px = np.empty(2)
    dx = np.empty(2)
    for s in range(n_s):
        o = offs[s]
        ms = m[s]
        cum = np.empty(ms + 1)
        cum[0] = 0.0
        gd = np.empty(ms)
        best = np.inf
        bj = 0
        bt = 0.0
        for j in range(ms):
            a = o + j
            b = o + (j + 1) % ms
            ex = pts[b, 0] - pts[a, 0]
            ey = pts[b, 1] - pts[a, 1]
            cum[j + 1] = cum[j] + np.hypot(ex, ey)
            dd = ex * ex + ey * ey
            rx = q0[0] - pts[a, 0]
            ry = q0[1] - pts[a, 1]
            tau = min(max((rx * ex + ry * ey) / (dd if dd > 0 else 1.0), 0.0), 1.0)
            g2 = (rx - tau * ex) ** 2 + (ry - tau * ey) ** 2
            gd[j] = g2
            if g2 < best:
                best = g2
                bj = j
                bt = tau
        length = cum[ms]
        pos = cum[bj] + bt * (cum[bj + 1] - cum[bj])
        if length > 0:
            sigma2 = spread * spread * best + (floor * length) ** 2
            w = np.zeros(ms)
            mid = np.zeros(ms)
            cs = 0.0
            sn = 0.0
            for j in range(ms):
                if gd[j] - best > SOFT_CUTOFF * sigma2:
                    continue                    # weight below exp(-SOFT_CUTOFF) of the best
                a = o + j
                b = o + (j + 1) % ms
                px[0], px[1] = pts[a, 0], pts[a, 1]
                dx[0], dx[1] = pts[b, 0] - pts[a, 0], pts[b, 1] - pts[a, 1]
                i0, tm, dc2 = _gauss_segment(q0, px, dx, 2, sigma2)
                w[j] = (cum[j + 1] - cum[j]) * exp(-(dc2 - best) / sigma2) * i0
                mid[j] = cum[j] + tm * (cum[j + 1] - cum[j])
                cs += w[j] * np.cos(2.0 * pi * mid[j] / length)
                sn += w[j] * np.sin(2.0 * pi * mid[j] / length)
            if cs != 0.0 or sn != 0.0:
                # the exact weighted mean arc position, unwrapped around the circular mean
                # (continuous, unlike an unwrapping around the hard closest point)
                ref = (np.arctan2(sn, cs) / (2.0 * pi) * length) % length
                wsum = 0.0
                msum = 0.0
                for j in range(ms):
                    if w[j] > 0:
                        wsum += w[j]
                        msum += w[j] * ((mid[j] - ref + 0.5 * length) % length - 0.5 * length)
                pos = (ref + msum / wsum) % length
        for k in range(n_p):
            if k == 0:
                j, t = bj, bt
                if length > 0:
                    j, t = _arc_segment(cum, ms, pos)
            else:
                # ratio_points: arc a0 + f L, once round at most; the segment found as
                # searchsorted(cum, ., "right") - 1 does
                target = pos + fractions[k - 1] * length
                if target >= length:
                    target -= length
                j = 0
                while j < ms - 1 and cum[j + 1] <= target:
                    j += 1
                span = cum[j + 1] - cum[j]
                t = min(max((target - cum[j]) / span, 0.0), 1.0) if span > 0 else 0.0
            seg[s, k] = j
            tk[s, k] = t
            a = o + j
            b = o + (j + 1) % ms
            point[s, k, 0] = pts[a, 0] + t * (pts[b, 0] - pts[a, 0])
            point[s, k, 1] = pts[a, 1] + t * (pts[b, 1] - pts[a, 1])
    return seg, tk, point


def _arc_segment(cum, ms, pos):  # pragma: no cover - compiled by numba (and called by it)
    """(segment, tau) of arc position ``pos`` on a contour with cumulated lengths ``cum``:
    a zero-length segment is avoided by stepping back."""
    j = 0
    while j < ms - 1 and cum[j + 1] <= pos:
        j += 1
    while j > 0 and cum[j + 1] - cum[j] <= 0:
        j -= 1
    span = cum[j + 1] - cum[j]
    return j, min(max((pos - cum[j]) / span, 0.0), 1.0) if span > 0 else 0.0


_START_KERNEL = []


def _start_kernel():
    """`_soft_start_loop` compiled with numba (with `_gauss_segment`), or the Python one."""
    if not _START_KERNEL:
        anchor_kernel()                          # compiles the shared helpers, if numba is there
        try:
            import numba
        except ImportError:                                 # pragma: no cover - optional
            _START_KERNEL.append(_soft_start_loop)
        else:
            global _arc_segment
            jit = numba.njit(cache=True, nogil=True, error_model="numpy")
            _arc_segment = jit(_arc_segment)
            _START_KERNEL.append(jit(_soft_start_loop))
    return _START_KERNEL[0]


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
        Use the numba kernel (default) or the same loop in Python (tests).

    Returns
    -------
    seg : (S,) int64, or (S, 1 + F) with ``fractions``
        Local segment index of each start (and split point).
    tau : (S,) float, or (S, 1 + F)
    point : (S, 2) float, or (S, 1 + F, 2)
    """
    kernel = _start_kernel() if compiled else _soft_start_loop
    f = np.ascontiguousarray(fractions, dtype=float).reshape(-1)
    seg, tk, point = kernel(np.ascontiguousarray(pts, dtype=float),
                            np.ascontiguousarray(m, dtype=np.int64),
                            np.ascontiguousarray(offs, dtype=np.int64),
                            np.ascontiguousarray(q0, dtype=float), f, SOFT_SPREAD, SOFT_FLOOR)
    if np.ndim(fractions) == 0 or len(fractions) == 0:
        return seg[:, 0], tk[:, 0], point[:, 0]
    return seg, tk, point
