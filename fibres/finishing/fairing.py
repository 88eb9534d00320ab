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

import numpy as np
import scipy.sparse as sp

from .smoothing import smooth_taubin

__all__ = ["fairing_matrices", "fairing_operator", "spread_pull", "natural_spline_matrix",
           "taubin_pairs", "DENSE", "TURNING", "SPREAD", "PULL_ROUNDS", "PULLED",
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
    ``s`` (B, P), ``h = diff(s)``: ``m = S @ y`` (`natural_spline_matrix`). The tridiagonal
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


def _gather(x, k):
    """``x[rows, k]`` of ``x`` (B, P, ...) at ``k`` (B, M), by one flat index."""
    n, p = x.shape[:2]
    return np.take(x.reshape((n * p,) + x.shape[2:]), k + p * np.arange(n)[:, None], axis=0)


def _search(s, t, side):
    """Row by row ``searchsorted(s, t, side)`` of ``t`` (B, M) in the nondecreasing rows of
    ``s`` (B, P), both >= 0: one search in the rows laid end to end (each shifted past the
    one before), checked against the unshifted values (a shift can round a near tie either
    way); rows that fail the check are searched alone."""
    n, p = s.shape
    rows = np.arange(n)[:, None]
    shift = (2.0 * max(float(s.max(initial=0.0)), float(t.max(initial=0.0))) + 1.0) * rows
    k = np.searchsorted((s + shift).ravel(), (t + shift).ravel(), side=side)
    k = k.reshape(t.shape) - p * rows
    at = np.clip(k, 1, p - 1) + p * rows
    before, after = s.ravel()[at - 1], s.ravel()[at]
    ok = (k >= 0) & (k <= p) & ((k == 0) | ((before <= t) if side == "right" else (before < t))) \
        & ((k == p) | ((after > t) if side == "right" else (after >= t)))
    for row in np.flatnonzero(~ok.all(axis=1)):
        k[row] = np.searchsorted(s[row], t[row], side=side)
    return k


def _count_le(s, t):
    """Row by row ``searchsorted(s, t, side="right")`` (`_search`) of ``t`` (B, M) in ``s``
    (B, P), both >= 0, nondecreasing rows: by searching the shorter rows in the other."""
    n, p = s.shape
    m = t.shape[1]
    if m <= p:
        return _search(s, t, "right")
    # s_i <= t_j for the j at or after the number of t below s_i (t's rows nondecreasing)
    first = _search(t, s, "left") + (m + 1) * np.arange(n)[:, None]
    return np.cumsum(np.bincount(first.ravel(), minlength=n * (m + 1)).reshape(n, m + 1)[:, :m],
                     axis=1)


def _spline_weights(s, h, t):
    """Knot interval ``k`` (B, M) of each ``t`` (B, M) in the knots ``s`` (B, P) (row by
    row ``searchsorted(s, t, side="right") - 1``, clipped to the intervals), the linear
    weights ``a``, ``b`` and the cubic factors ``(a^3 - a) h^2 / 6``, ``(b^3 - b) h^2 / 6``."""
    p = s.shape[1]
    k = _count_le(s, t)
    np.clip(k - 1, 0, p - 2, out=k)
    hk = _gather(h, k)
    b = (t - _gather(s, k)) / hk
    a = 1.0 - b
    return k, a, b, (a ** 3 - a) * hk ** 2 / 6.0, (b ** 3 - b) * hk ** 2 / 6.0


def _spline_rows(second, k, a, b, ca, cb):
    """(B, M, P) rows of the spline matrix from `_spline_second` and `_spline_weights`."""
    n, p, _ = second.shape
    up = ca[..., None] * _gather(second, k) + cb[..., None] * _gather(second, k + 1)
    m = k.shape[1]
    flat = up.reshape(-1)
    at = (np.arange(n * m) * p).reshape(n, m) + k
    flat[at] += a
    flat[at + 1] += b
    return up


def natural_spline_matrix(knots, t):
    """(M, P) matrix ``U`` of the natural cubic spline through P values at ``knots``
    (increasing), evaluated at ``t``: ``U @ y`` are the spline's values (de Boor 1978; the
    second derivatives ``m`` solve the tridiagonal system
    ``h_{i-1} m_{i-1} + 2 (h_{i-1} + h_i) m_i + h_i m_{i+1} = 6 (dy_i / h_i - dy_{i-1} / h_{i-1})``
    with ``m_0 = m_{P-1} = 0``). Batched: ``knots`` (..., P) and ``t`` (..., M) give
    (..., M, P), one spline per leading index (the systems solved together)."""
    s = np.asarray(knots, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    lead = s.shape[:-1]
    p, m = s.shape[-1], t.shape[-1]
    s = s.reshape(-1, p)
    t = t.reshape(-1, m)
    h = np.diff(s, axis=1)                                    # (B, P - 1)
    up = _spline_rows(_spline_second(s, h), *_spline_weights(s, h, t))
    return up.reshape(lead + (m, p))


def _taubin_matrix(p, iterations):
    """(P, P) matrix of `smooth_taubin` with ``iterations`` lambda|mu pairs."""
    eye = np.eye(p)[None]                     # P "coordinates": the columns of the identity
    return smooth_taubin(eye, iterations=int(iterations))[0]


def fairing_matrices(points, *, iterations, turning=TURNING, dense=DENSE):
    """Per-fibre fairing matrices (N, P, P) of rest fibres ``points`` (N, P, 3) (module
    docstring): ``F[k] @ points[k]`` are fibre k's faired points; ``iterations`` lambda|mu
    pairs of Taubin smoothing (0: none)."""
    pts = np.asarray(points, dtype=np.float64)
    n, p, _ = pts.shape
    if p < 3:
        return np.broadcast_to(np.eye(p), (n, p, p)).copy()
    taubin = _taubin_matrix(p, iterations) if iterations else np.eye(p)
    smoothed = np.matmul(taubin, pts)
    m = (p - 1) * int(dense) + 1
    # one spline per fibre, all at once: its knots are the fibre's own chords
    seg = np.linalg.norm(np.diff(smoothed, axis=1), axis=2)                  # (N, P - 1)
    floor = 1e-12 * np.maximum(seg.sum(axis=1, keepdims=True), 1e-300)
    knots = np.concatenate([np.zeros((n, 1)), np.cumsum(np.maximum(seg, floor), axis=1)],
                           axis=1)
    t = np.linspace(0.0, knots[:, -1], m, axis=1)
    # the dense curve straight from the spline's values and second derivatives (the whole
    # (N, M, P) spline matrix is needed only at the two dense points round each new point)
    h = np.diff(knots, axis=1)
    second = _spline_second(knots, h)
    k, a, b, ca, cb = _spline_weights(knots, h, t)
    # coordinates first (6, N P): the values and second derivatives at the knots
    both = np.concatenate([smoothed, second @ smoothed], axis=2).reshape(n * p, 6).T
    at = k + p * np.arange(n)[:, None]
    g0, g1 = np.take(both, at, axis=1), np.take(both, at + 1, axis=1)        # (6, N, M)
    curve = a * g0[:3] + b * g1[:3] + ca * g0[3:] + cb * g1[3:]            # (3, N, M)
    step = np.diff(curve, axis=2)
    ds = np.sqrt((step * step).sum(axis=0))
    x, y, z = step / np.maximum(ds, 1e-300)
    x0, y0, z0, x1, y1, z1 = x[:, :-1], y[:, :-1], z[:, :-1], x[:, 1:], y[:, 1:], z[:, 1:]
    theta = np.arctan2(np.sqrt((y0 * z1 - z0 * y1) ** 2 + (z0 * x1 - x0 * z1) ** 2
                               + (x0 * y1 - y0 * x1) ** 2),
                       x0 * x1 + y0 * y1 + z0 * z1)
    share = np.zeros((n, m - 1))
    share[:, :-1] += 0.5 * theta
    share[:, 1:] += 0.5 * theta
    measure = (ds / np.maximum(ds.sum(axis=1, keepdims=True), 1e-300)
               + float(turning) * share / np.pi)
    cum = np.concatenate([np.zeros((n, 1)), np.cumsum(measure, axis=1)], axis=1)
    target = np.linspace(0.0, cum[:, -1], p, axis=1)
    j = np.clip(_count_le(cum, target) - 1, 0, m - 2)                      # (N, P)
    c0, c1 = _gather(cum, j), _gather(cum, j + 1)
    w = np.clip((target - c0) / np.maximum(c1 - c0, 1e-300), 0.0, 1.0)
    # each new point a blend of dense points j and j + 1, each a blend of the values and
    # second derivatives at the two knots round it: the values' weights ``lin`` and the
    # second derivatives' ``cub`` (N, P, P), summed per knot
    jj = np.concatenate([j, j + 1], axis=1)                                 # (N, 2 P)
    kj, aj, bj, caj, cbj = (_gather(x, jj) for x in (k, a, b, ca, cb))
    wj = np.concatenate([1.0 - w, w], axis=1)
    at = ((np.arange(n)[:, None] * p + np.arange(2 * p) % p) * p + kj).ravel()
    at = np.concatenate([at, at + 1])
    lin, cub = (np.bincount(at, np.concatenate([(wj * u).ravel(), (wj * v).ravel()]),
                            minlength=n * p * p).reshape(n, p, p)
                for u, v in ((aj, bj), (caj, cbj)))
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


def _along(a, weights):
    """``a`` (N, P, K) plus its neighbours' values along each fibre times ``weights``."""
    out = a.copy()
    for k, w in enumerate(weights, start=1):
        if k >= a.shape[1]:
            break
        out[:, k:] += w * a[:, :-k]
        out[:, :-k] += w * a[:, k:]
    return out


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
