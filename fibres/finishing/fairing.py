"""Fair fibres: smoothing and turn-aware resampling as one linear map, and a smooth pull.

A fibre of resolution R is judged by the turns between its consecutive segments. Points at
equal arc-length steps spend as many points on a straight stretch as on a bend, so a fibre
that bends over a short length (the psoas tendon round the pelvic brim, gluteus maximus
fibres converging on their insertion strip) turns sharply at one or two joints while the rest
of it hardly turns. `fairing_matrices` makes, per fibre, the (P, P) matrix ``F = S_R U T``
that maps the fibre's P points to P faired points:

1. ``T``: Taubin's lambda|mu smoothing (`fibres.finishing.smoothing.smooth_taubin`, linear in
   the points, so it is written as its matrix): takes out the one-joint kinks, keeps the bends.
2. ``U``: a natural cubic spline through the smoothed points, parameterised by their
   chord length at rest (de Boor, *A Practical Guide to Splines*, 1978), evaluated at
   `DENSE` points per segment: a curve whose turning is spread over the bend instead of
   sitting at the joints.
3. ``S_R``: P points on the dense curve at equal steps of the measure
   ``dm = ds / L + TURNING * dtheta / pi`` (arc length share plus turning, the dense
   polyline's joint angles shared between their two segments): a bend gets points in
   proportion to how much it turns, so every joint turns by about the same angle
   (curvature-adaptive sampling, as in adaptive polyline approximation of curves). Each new
   point is a fixed blend of two dense points.

The measure is taken on the rest fibres and frozen, so ``F`` is a fixed linear map and the
decomposition plan's ``points = W V`` stays linear in the vertices (fibre k is the same
material fibre in every frame). The two end points (on the attachment patches) are kept.

`spread_pull` smooths the containment pull (`fibres.finishing.containment`) along each fibre:
a point pulled in by ``d`` while its neighbours stay put makes a kink of about
``2 atan(|d| / h)`` (segment length h). The displacements are spread to the neighbours with
the tent weights `SPREAD` (four joints each side) and divided by the summed weight of the
pulled points around (a Shepard-style normalisation, at least 1: a run of pulled points moves
by their own displacement, not by its sum, which would push a thin muscle's fibres through
the opposite wall). A pull counts in that sum as ``min(1, |d| / PULLED)`` of a point, so a
pull that starts from zero during a motion enters the sum from zero instead of by a step.
The pull is then applied again to the spread fibres (`PULL_ROUNDS` rounds per frame, more on
the rest pose: `fibres.finishing.carried_pull`), so the fibre moves in as a smooth bump and
no point stays outside.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import scipy.sparse as sp
from numba import njit

from .smoothing import smooth_taubin

__all__ = ["fairing_matrices", "fairing_operator", "spread_pull", "taubin_pairs", "DENSE", "TURNING", "SPREAD", "PULL_ROUNDS", "PULLED",
           "PAIRS_PER_ITERATION"]

#: spline points per fibre segment on which the resampling measure is taken
DENSE = 8
#: lambda|mu pairs of Taubin smoothing per smoothing iteration of `fibres.decompose`
PAIRS_PER_ITERATION = 1.4
#: weight of a half-turn (pi) against the fibre's whole length in the resampling measure
TURNING = 4.0
#: weights of a pulled point's displacement given to its neighbours 1, 2, 3, 4 joints away
SPREAD = (0.8, 0.6, 0.4, 0.2)
#: rounds of spreading and pulling again per frame (`fibres.finishing.carried_pull.pull_rounds`)
PULL_ROUNDS = 2
#: a pull this long (metres) or longer counts as one whole point in `spread_pull`'s sum
PULLED = 1e-5


def taubin_pairs(smoothing_iterations) -> int:
    """Taubin lambda|mu pairs for ``smoothing_iterations`` of `fibres.decompose`
    (`PAIRS_PER_ITERATION` each, rounded): more pairs smooth the slices' noise, fewer keep
    fibres that bend round a concave wall (the psoas tendon) off it, so the pull has less to
    do (docs/decisions.md)."""
    return int(round(PAIRS_PER_ITERATION * int(smoothing_iterations)))


def _spline_second(s, h):
    """(B, P, P) matrices ``S`` of the natural splines' second derivatives at the knots
    ``s`` (B, P), ``h = diff(s)``: ``m = S @ y`` (de Boor 1978: ``h_{i-1} m_{i-1} + 2 (h_{i-1}
    + h_i) m_i + h_i m_{i+1} = 6 (dy_i / h_i - dy_{i-1} / h_{i-1})``, ``m_0 = m_{P-1} = 0``;
    the spline on knot interval i is ``a y_i + b y_{i+1} + (a^3 - a) h_i^2 / 6 m_i + (b^3 - b)
    h_i^2 / 6 m_{i+1}`` with ``b = (t - s_i) / h_i``, ``a = 1 - b``). The tridiagonal
    systems by elimination without pivoting (Thomas), all splines and columns at once: the
    matrix is strictly diagonally dominant (``2 (h_{i-1} + h_i) > h_{i-1} + h_i``)."""
    n, p = s.shape
    second = np.zeros((n, p, p))
    if p > 2:
        eye = np.eye(p)
        slope = (eye[1:] - eye[:-1]) / h[:, :, None]           # (B, P - 1, P): dy_i / h_i
        r = 6.0 * (slope[:, 1:] - slope[:, :-1])               # (B, P - 2, P)
        d = 2.0 * (h[:, :-1] + h[:, 1:])                        # (B, P - 2) diagonal
        e = h[:, 1:-1]                                          # (B, P - 3) off-diagonals
        for i in range(1, p - 2):
            w = e[:, i - 1] / d[:, i - 1]
            d[:, i] -= w * e[:, i - 1]
            r[:, i] -= w[:, None] * r[:, i - 1]
        x = second[:, 1:-1]
        x[:, -1] = r[:, -1] / d[:, -1, None]
        for i in range(p - 4, -1, -1):
            x[:, i] = (r[:, i] - e[:, i, None] * x[:, i + 1]) / d[:, i, None]
    return second


@functools.lru_cache(maxsize=64)
def _taubin_matrix(p, iterations):
    """(P, P) matrix of `smooth_taubin` with ``iterations`` lambda|mu pairs (read-only, made
    once per P and count)."""
    eye = np.eye(p)[None]                     # P "coordinates": the columns of the identity
    out = smooth_taubin(eye, iterations=int(iterations))[0]
    out.flags.writeable = False
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _resample(knots, values, turning, pick, coef, weight, work, dk):
    """The turn-aware resampling (module docstring, step 3) of N natural splines with
    ``knots`` (N, P) (increasing, from 0) and ``values`` (N, P, 6) (the points and the second
    derivatives at the knots): the dense curve at M = ``len(dk)`` points evenly spaced in the
    chord parameter (as ``linspace``), its measure, and P new points at equal steps of it,
    new point i a blend ``(1 - w) D_j + w D_{j+1}`` of dense points j, j + 1. Out:
    ``pick`` (N, 2 P) the knot interval of dense point j (first P) and j + 1 (last P),
    ``coef`` (N, 2 P, 4) their spline weights ``a, b, (a^3 - a) h^2 / 6, (b^3 - b) h^2 / 6``
    (`_spline_second`), ``weight`` (N, P) w. Work space: ``work`` (M, 10) (the dense
    points, their weights, segment lengths, turning shares, cumulated measure) and ``dk``
    (M,) int64 (their knot intervals)."""
    p, m = knots.shape[1], dk.shape[0]
    for n in range(knots.shape[0]):
        length = knots[n, p - 1]
        step = length / (m - 1)
        k = 0
        for j in range(m):              # the dense curve
            t = j * step if j < m - 1 else length
            while k < p - 2 and knots[n, k + 1] <= t:
                k += 1
            hk = knots[n, k + 1] - knots[n, k]
            b = (t - knots[n, k]) / hk
            a = 1.0 - b
            work[j, 3], work[j, 4] = a, b
            work[j, 5] = (a ** 3 - a) * hk ** 2 / 6.0
            work[j, 6] = (b ** 3 - b) * hk ** 2 / 6.0
            dk[j] = k
            for c in range(3):
                work[j, c] = a * values[n, k, c] + b * values[n, k + 1, c] \
                    + work[j, 5] * values[n, k, 3 + c] + work[j, 6] * values[n, k + 1, 3 + c]
        total = x0 = y0 = z0 = 0.0
        for j in range(m - 1):          # segment lengths; turns shared by their segments
            x1, y1, z1 = (work[j + 1, 0] - work[j, 0], work[j + 1, 1] - work[j, 1],
                          work[j + 1, 2] - work[j, 2])
            work[j, 7] = math.sqrt(x1 * x1 + y1 * y1 + z1 * z1)
            total += work[j, 7]
            size = max(work[j, 7], 1e-300)
            x1, y1, z1 = x1 / size, y1 / size, z1 / size
            work[j, 8] = 0.0
            if j:                       # the turn from segment j - 1 to j
                theta = math.atan2(math.sqrt((y0 * z1 - z0 * y1) ** 2 + (z0 * x1 - x0 * z1) ** 2
                                             + (x0 * y1 - y0 * x1) ** 2),
                                   x0 * x1 + y0 * y1 + z0 * z1)
                work[j - 1, 8] += 0.5 * theta
                work[j, 8] += 0.5 * theta
            x0, y0, z0 = x1, y1, z1
        work[0, 9] = 0.0
        for j in range(m - 1):
            work[j + 1, 9] = work[j, 9] + (work[j, 7] / max(total, 1e-300)
                                           + turning * work[j, 8] / np.pi)
        j = 0
        for i in range(p):               # the new points at equal steps of the measure
            target = i * (work[m - 1, 9] / (p - 1)) if i < p - 1 else work[m - 1, 9]
            while j < m - 2 and work[j + 1, 9] <= target:
                j += 1
            weight[n, i] = min(max((target - work[j, 9])
                                   / max(work[j + 1, 9] - work[j, 9], 1e-300), 0.0), 1.0)
            for r in range(2):
                pick[n, i + r * p] = dk[j + r]
                for c in range(4):
                    coef[n, i + r * p, c] = work[j + r, 3 + c]


def fairing_matrices(points, *, iterations, turning=TURNING, dense=DENSE):
    """Per-fibre fairing matrices (N, P, P) of rest fibres ``points`` (N, P, 3) (module
    docstring): ``F[k] @ points[k]`` are fibre k's faired points; ``iterations`` lambda|mu
    pairs of Taubin smoothing (0: none)."""
    pts = np.asarray(points, dtype=np.float64)
    n, p, _ = pts.shape
    if p < 3:
        return np.broadcast_to(np.eye(p), (n, p, p)).copy()
    taubin = _taubin_matrix(p, int(iterations)) if iterations else np.eye(p)
    smoothed = np.matmul(taubin, pts)
    m = (p - 1) * int(dense) + 1
    # one spline per fibre, all at once: its knots are the fibre's own chords
    seg = np.linalg.norm(np.diff(smoothed, axis=1), axis=2)                  # (N, P - 1)
    floor = 1e-12 * np.maximum(seg.sum(axis=1, keepdims=True), 1e-300)
    knots = np.concatenate([np.zeros((n, 1)), np.cumsum(np.maximum(seg, floor), axis=1)],
                           axis=1)
    h = np.diff(knots, axis=1)
    second = _spline_second(knots, h)
    # the values and second derivatives at the knots; per new point, its two dense points'
    # knot intervals and spline weights, and its share of the second one
    pick, coef, w = np.empty((n, 2 * p), np.int64), np.empty((n, 2 * p, 4)), np.empty((n, p))
    _resample(knots, np.concatenate([smoothed, second @ smoothed], axis=2), float(turning),
              pick, coef, w, np.empty((m, 10)), np.empty(m, np.int64))
    # each new point a blend of dense points j and j + 1, each a blend of the values and
    # second derivatives at the two knots round it: the values' weights ``lin`` and the
    # second derivatives' ``cub`` (N, P, P), summed per knot
    wj = np.concatenate([1.0 - w, w], axis=1)[..., None] * coef                # (N, 2 P, 4)
    at = ((np.arange(n)[:, None] * p + np.arange(2 * p) % p) * p + pick).ravel()
    at = np.concatenate([at, at + 1])
    lin, cub = (np.bincount(at, np.concatenate([wj[..., u].ravel(), wj[..., u + 1].ravel()]),
                            minlength=n * p * p).reshape(n, p, p) for u in (0, 2))
    out = (lin + cub @ second) @ taubin
    out[:, 0] = 0.0
    out[:, -1] = 0.0
    out[:, 0, 0] = 1.0
    out[:, -1, -1] = 1.0
    return out


def fairing_operator(points, *, iterations, turning=TURNING, dense=DENSE):
    """The block-diagonal sparse (N P, N P) matrix of `fairing_matrices`."""
    mats = fairing_matrices(points, iterations=iterations, turning=turning, dense=dense)
    n, p, _ = mats.shape
    cols = (np.arange(n)[:, None, None] * p + np.arange(p)[None, None, :]).repeat(p, axis=1)
    out = sp.csr_matrix((mats.reshape(-1), cols.reshape(-1), np.arange(n * p + 1) * p),
                        shape=(n * p, n * p))
    out.eliminate_zeros()
    return out


@functools.lru_cache(maxsize=64)
def _band(p, weights):
    """(P, P) band matrix: 1 on the diagonal, ``weights`` (a tuple) on the k-th off-diagonals
    (read-only, made once per P and weights)."""
    band = np.concatenate([[1.0], np.asarray(weights, dtype=np.float64), np.zeros(p)])
    out = band[np.abs(np.arange(p)[:, None] - np.arange(p)[None])]
    out.flags.writeable = False
    return out


def _along(a, weights):
    """``a`` (N, P, K) plus its neighbours' values along each fibre times ``weights``: one
    product with the (P, P) band matrix of 1 and the weights."""
    return np.matmul(_band(a.shape[1], tuple(weights)), a)


def spread_pull(before, after):
    """Fibres ``before`` (N, P, 3) moved by their pull's displacement ``after - before``
    spread along each fibre (module docstring); ends unchanged. Pull the result again."""
    b = np.asarray(before, dtype=np.float64)
    d = np.asarray(after, dtype=np.float64) - b
    share = np.minimum(1.0, np.sqrt(np.einsum("npk,npk->np", d, d)) / PULLED)[..., None]
    e = _along(d, SPREAD) / np.maximum(1.0, _along(share, SPREAD))
    e[:, 0] = 0.0
    e[:, -1] = 0.0
    return b + e
