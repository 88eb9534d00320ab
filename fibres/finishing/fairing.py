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
    n = len(s)
    h = np.diff(s, axis=1)                                    # (B, P - 1)
    eye = np.eye(p)
    second = np.zeros((n, p, p))              # m = second @ y
    if p > 2:
        a = np.zeros((n, p - 2, p - 2))
        i = np.arange(p - 2)
        a[:, i, i] = 2.0 * (h[:, :-1] + h[:, 1:])
        a[:, i[1:], i[1:] - 1] = h[:, 1:-1]
        a[:, i[:-1], i[:-1] + 1] = h[:, 1:-1]
        slope = (eye[1:] - eye[:-1]) / h[:, :, None]           # (B, P - 1, P): dy_i / h_i
        second[:, 1:-1] = np.linalg.solve(a, 6.0 * (slope[:, 1:] - slope[:, :-1]))
    # k: the knot interval of each t (searchsorted(s, t, side="right") - 1, row by row)
    k = np.clip((s[:, None, :] <= t[:, :, None]).sum(axis=2) - 1, 0, p - 2)   # (B, M)
    rows = np.arange(n)[:, None]
    hk = h[rows, k][..., None]
    sk = s[rows, k][..., None]
    b = (t[..., None] - sk) / hk
    a_ = 1.0 - b
    up = (a_ * eye[k] + b * eye[k + 1]
          + ((a_ ** 3 - a_) * second[rows, k] + (b ** 3 - b) * second[rows, k + 1]) * hk ** 2 / 6.0)
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
    smoothed = np.einsum("ij,njk->nik", taubin, pts)
    m = (p - 1) * int(dense) + 1
    # one spline per fibre, all at once: its knots are the fibre's own chords
    seg = np.linalg.norm(np.diff(smoothed, axis=1), axis=2)                  # (N, P - 1)
    floor = 1e-12 * np.maximum(seg.sum(axis=1, keepdims=True), 1e-300)
    knots = np.concatenate([np.zeros((n, 1)), np.cumsum(np.maximum(seg, floor), axis=1)],
                           axis=1)
    t = np.linspace(0.0, knots[:, -1], m, axis=1)
    up = natural_spline_matrix(knots, t)                 # (N, M, P): dense = up @ x
    curve = up @ smoothed
    step = np.diff(curve, axis=1)
    ds = np.linalg.norm(step, axis=2)
    unit = step / np.maximum(ds, 1e-300)[..., None]
    theta = np.arctan2(np.linalg.norm(np.cross(unit[:, :-1], unit[:, 1:]), axis=2),
                       np.einsum("nij,nij->ni", unit[:, 1:], unit[:, :-1]))
    share = np.zeros((n, m - 1))
    share[:, :-1] += 0.5 * theta
    share[:, 1:] += 0.5 * theta
    measure = (ds / np.maximum(ds.sum(axis=1, keepdims=True), 1e-300)
               + float(turning) * share / np.pi)
    cum = np.concatenate([np.zeros((n, 1)), np.cumsum(measure, axis=1)], axis=1)
    target = np.linspace(0.0, cum[:, -1], p, axis=1)
    j = np.clip((cum[:, None, :] <= target[:, :, None]).sum(axis=2) - 1, 0, m - 2)  # (N, P)
    rows = np.arange(n)[:, None]
    c0, c1 = cum[rows, j], cum[rows, j + 1]
    w = np.clip((target - c0) / np.maximum(c1 - c0, 1e-300), 0.0, 1.0)
    # each new point a blend of dense points j and j + 1
    out = ((1.0 - w)[..., None] * up[rows, j] + w[..., None] * up[rows, j + 1]) @ taubin
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
