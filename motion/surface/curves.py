"""Curve tools for surface wrapping: arc-length resampling and rotation-minimising frames.

All functions work on a whole motion at once: curves are (F, P, 3) arrays, frame axis first.
The only Python loops run over the (tens of) samples of a curve, never over frames.

Rotation-minimising frames use the double-reflection method of Wang, Juettler, Zheng & Liu,
"Computation of rotation minimizing frames", ACM Trans. Graph. 27(1), 2008: each frame is
carried to the next sample by two reflections, which is fourth-order accurate and, unlike
Frenet frames, defined on straight segments and smooth in the curve points.
"""
from __future__ import annotations

import numpy as np

__all__ = ["resample_polylines", "arc_fractions", "curve_tangents", "rotation_minimizing_frames",
           "transport_vector", "any_perpendicular", "smoothed_tangents", "trim_polylines", "point_at_arc_length",
           "closest_on_polyline", "catmull_rom_weights", "round_corners"]

_TINY = 1e-15


def _fill_nan_forward(points: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """Replace NaN rows (padding after the last valid point) by the last valid point; ``valid``
    (F, P): the rows' finiteness, if known."""
    bad = ~(np.isfinite(points).all(axis=-1) if valid is None else valid)  # (F, P)
    if not bad.any():
        return points
    if bad[:, 0].any():
        raise ValueError("a curve starts with a missing (NaN) point")
    index = np.where(bad, 0, np.arange(points.shape[1])[None, :])
    index = np.maximum.accumulate(index, axis=1)
    return np.take_along_axis(points, index[..., None], axis=1)


def resample_polylines(points, n_samples: int, *, anchors=None, anchor_fractions=None) -> np.ndarray:
    """Resample polylines at ``n_samples`` points equally spaced in arc length.

    Parameters
    ----------
    points : (P, 3) or (F, P, 3) float
        Polyline vertices per frame; trailing NaN rows are padding (a path that has fewer
        points in some frames) and are ignored.
    n_samples : int
        Number of output samples, at least 2; the first and last are the polyline's ends.
    anchors : (K,) or (F, K) int, keyword-only
        Indices of anchor vertices in each frame's polyline (first = 0, last = the last valid
        point). With ``anchor_fractions`` (K,) -- the arc fractions of the anchors at rest --
        the arc length is matched piece by piece: the samples between anchors k and k + 1
        stay between them, spaced evenly there. A piece whose two anchors ride the same body
        then keeps its samples fixed on that body while the free pieces stretch.

    Returns
    -------
    (n_samples, 3) or (F, n_samples, 3) float
    """
    pts = np.asarray(points, dtype=float)
    single = pts.ndim == 2
    if single:
        pts = pts[None]
    if pts.ndim != 3 or pts.shape[-1] != 3 or pts.shape[1] < 2:
        raise ValueError(f"points must be (P, 3) or (F, P, 3) with P >= 2, got shape {np.shape(points)}")
    n = int(n_samples)
    if n < 2:
        raise ValueError("n_samples must be at least 2")
    pts = _fill_nan_forward(pts)
    seg = np.linalg.norm(np.diff(pts, axis=1), axis=-1)  # (F, P-1)
    cum = np.concatenate([np.zeros((pts.shape[0], 1)), np.cumsum(seg, axis=1)], axis=1)
    u = np.linspace(0.0, 1.0, n)
    if anchors is None:
        target = cum[:, -1:] * u[None, :]  # (F, n)
    else:
        idx = np.broadcast_to(np.asarray(anchors, dtype=np.int64), (pts.shape[0], len(anchor_fractions)))
        s = np.asarray(anchor_fractions, dtype=float)
        arc = np.take_along_axis(cum, idx, axis=1)                    # (F, K)
        piece = np.clip(np.searchsorted(s, u, side="right") - 1, 0, len(s) - 2)
        width = np.maximum(s[piece + 1] - s[piece], 1e-15)
        t = np.clip((u - s[piece]) / width, 0.0, 1.0)
        target = arc[:, piece] + t[None] * (arc[:, piece + 1] - arc[:, piece])
    # index of the segment holding each target: count of interior vertices at or before it
    j = np.sum(cum[:, None, 1:-1] <= target[:, :, None], axis=-1)  # (F, n) in [0, P-2]
    s0 = np.take_along_axis(cum, j, axis=1)
    length = np.take_along_axis(seg, j, axis=1)
    t = np.where(length > _TINY, (target - s0) / np.where(length > _TINY, length, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)[..., None]
    a = np.take_along_axis(pts, j[..., None], axis=1)
    b = np.take_along_axis(pts, (j + 1)[..., None], axis=1)
    out = a + t * (b - a)
    out[:, 0] = pts[:, 0]
    out[:, -1] = pts[:, -1]
    return out[0] if single else out


def arc_fractions(points, anchors) -> np.ndarray:
    """Arc-length fractions (K,) of anchor vertices ``anchors`` (K,) of one polyline (P, 3)."""
    pts = np.asarray(points, dtype=float)
    pts = pts[np.isfinite(pts).all(axis=1)]
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=-1))])
    return cum[np.asarray(anchors, dtype=np.int64)] / cum[-1]


def _unit(v: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(norm, _TINY)


def curve_tangents(curve: np.ndarray) -> np.ndarray:
    """Unit tangents of sampled curves: central differences inside, one-sided at the ends.

    Parameters
    ----------
    curve : (F, n, 3) float

    Returns
    -------
    (F, n, 3) float
    """
    d = np.empty_like(curve)
    d[:, 1:-1] = curve[:, 2:] - curve[:, :-2]
    d[:, 0] = curve[:, 1] - curve[:, 0]
    d[:, -1] = curve[:, -1] - curve[:, -2]
    return _unit(d)


def any_perpendicular(t: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each unit vector ``t`` (..., 3), deterministic."""
    t = np.asarray(t, dtype=float)
    axis = np.zeros_like(t)
    idx = np.argmin(np.abs(t), axis=-1)
    np.put_along_axis(axis, idx[..., None], 1.0, axis=-1)
    return _unit(np.cross(t, axis))


def transport_vector(r: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotate ``r`` by the minimal rotation that takes unit ``a`` to unit ``b`` (..., 3).

    Rodrigues' formula without trigonometry: ``R r = (a.b) r + w x r + w (w.r) / (1 + a.b)``
    with ``w = a x b``; smooth everywhere except ``b = -a``.
    """
    w = np.cross(a, b)
    c = np.sum(a * b, axis=-1, keepdims=True)
    return c * r + np.cross(w, r) + w * np.sum(w * r, axis=-1, keepdims=True) / np.maximum(1.0 + c, 1e-12)


def rotation_minimizing_frames(curve, r0, *, tangents=None) -> np.ndarray:
    """Rotation-minimising frames along sampled curves (double reflection, Wang et al. 2008).

    Parameters
    ----------
    curve : (F, n, 3) float
    r0 : (F, 3) float
        Reference vector at the first sample; it is made perpendicular to the first tangent.
    tangents : (F, n, 3) float, optional
        Unit tangents; default `curve_tangents`.

    Returns
    -------
    (F, n, 3, 3) float
        Orthonormal frames whose columns are (normal r, binormal t x r, tangent t).
    """
    x = np.asarray(curve, dtype=float)
    t = curve_tangents(x) if tangents is None else np.asarray(tangents, dtype=float)
    r = np.asarray(r0, dtype=float)
    r = _unit(r - np.sum(r * t[:, 0], axis=-1, keepdims=True) * t[:, 0])
    normals = np.empty_like(x)
    normals[:, 0] = r
    # the reflections' vectors and factors do not depend on r: all samples at once (a factor 0
    # where a vector vanishes leaves r as it is)
    v1 = x[:, 1:] - x[:, :-1]                                                    # (F, n-1, 3)
    c1 = np.sum(v1 * v1, axis=-1, keepdims=True)
    a1 = np.where(c1 > _TINY, 2.0 / np.where(c1 > _TINY, c1, 1.0), 0.0)
    t_l = t[:, :-1] - a1 * np.sum(v1 * t[:, :-1], axis=-1, keepdims=True) * v1
    v2 = t[:, 1:] - t_l
    c2 = np.sum(v2 * v2, axis=-1, keepdims=True)
    a2 = np.where(c2 > _TINY, 2.0 / np.where(c2 > _TINY, c2, 1.0), 0.0)
    # the sweep below on component-major copies (3, n, F): each step works on contiguous
    # rows of F values and writes its dot products out (the same sums in the same order)
    w1s, w2s = np.ascontiguousarray(v1.transpose(2, 1, 0)), np.ascontiguousarray(v2.transpose(2, 1, 0))
    ts = np.ascontiguousarray(t.transpose(2, 1, 0))
    a1s, a2s = np.ascontiguousarray(a1[..., 0].T), np.ascontiguousarray(a2[..., 0].T)   # (n-1, F)
    r0, r1, r2 = r[:, 0].copy(), r[:, 1].copy(), r[:, 2].copy()
    out = np.empty((3, x.shape[1], x.shape[0]))
    out[:, 0] = r.T
    for i in range(x.shape[1] - 1):  # loop over the curve's samples (tens), vectorised over frames
        for w, a in ((w1s[:, i], a1s[i]), (w2s[:, i], a2s[i])):       # the two reflections
            f = a * (w[0] * r0 + w[1] * r1 + w[2] * r2)
            r0, r1, r2 = r0 - f * w[0], r1 - f * w[1], r2 - f * w[2]
        # re-orthogonalise against the tangent to stop round-off drift
        t0, t1, t2 = ts[0, i + 1], ts[1, i + 1], ts[2, i + 1]
        d = r0 * t0 + r1 * t1 + r2 * t2
        r0, r1, r2 = r0 - d * t0, r1 - d * t1, r2 - d * t2
        norm = np.maximum(np.sqrt(r0 * r0 + r1 * r1 + r2 * r2), _TINY)
        r0, r1, r2 = r0 / norm, r1 / norm, r2 / norm
        out[0, i + 1], out[1, i + 1], out[2, i + 1] = r0, r1, r2
    normals[:] = out.transpose(2, 1, 0)
    binormals = np.cross(t, normals)
    return np.stack([normals, binormals, t], axis=-1)


def twist_frames(frames: np.ndarray, angle: np.ndarray, fraction: np.ndarray) -> np.ndarray:
    """Rotate each frame about its tangent by ``angle * fraction``.

    Parameters
    ----------
    frames : (F, n, 3, 3) float
        Columns (normal, binormal, tangent).
    angle : (F,) float
        Total twist at the last sample.
    fraction : (n,) float
        Share of the twist at each sample (0 at the start, 1 at the end).
    """
    phi = angle[:, None] * fraction[None, :]
    c, s = np.cos(phi)[..., None], np.sin(phi)[..., None]
    n, b = frames[..., 0], frames[..., 1]
    return np.stack([c * n + s * b, -s * n + c * b, frames[..., 2]], axis=-1)


def twist_angle(n_have: np.ndarray, n_want: np.ndarray, tangent: np.ndarray) -> np.ndarray:
    """Signed angle (F,) about ``tangent`` that turns ``n_have`` into ``n_want`` (both ⟂ tangent)."""
    sin = np.sum(np.cross(n_have, n_want) * tangent, axis=-1)
    cos = np.sum(n_have * n_want, axis=-1)
    return np.arctan2(sin, cos)


def point_at_arc_length(points, arc) -> np.ndarray:
    """Points (F, 3) at arc length ``arc`` (F,) along polylines (F, P, 3) (NaN padding ignored;
    clamped to the ends)."""
    pts = _fill_nan_forward(np.asarray(points, dtype=float))
    seg = np.linalg.norm(np.diff(pts, axis=1), axis=-1)
    cum = np.concatenate([np.zeros((pts.shape[0], 1)), np.cumsum(seg, axis=1)], axis=1)
    return _at_arc(pts, seg, cum, arc)


def _at_arc(pts, seg, cum, arc) -> np.ndarray:
    """`point_at_arc_length` on NaN-free polylines ``pts`` with their pieces' lengths ``seg``
    (F, P - 1) and cumulative lengths ``cum`` (F, P)."""
    target = np.clip(np.asarray(arc, dtype=float), 0.0, cum[:, -1])
    j = np.sum(cum[:, 1:-1] <= target[:, None], axis=-1)                      # (F,) in [0, P-2]
    s0 = np.take_along_axis(cum, j[:, None], axis=1)[:, 0]
    length = np.take_along_axis(seg, j[:, None], axis=1)[:, 0]
    t = np.clip(np.where(length > _TINY, (target - s0) / np.where(length > _TINY, length, 1.0), 0.0), 0.0, 1.0)
    rows = np.arange(pts.shape[0])
    return pts[rows, j] + t[:, None] * (pts[rows, j + 1] - pts[rows, j])


def trim_polylines(points, start, stop) -> np.ndarray:
    """The pieces of polylines between arc lengths ``start`` and ``stop``.

    Parameters
    ----------
    points : (F, P, 3) float
        Polylines, trailing NaN rows are padding.
    start, stop : (F,) float
        Arc lengths from the first point, ``0 <= start < stop <= length``.

    Returns
    -------
    (F, P + 2, 3) float
        Per frame the point at ``start``, the original vertices strictly between, the point at
        ``stop``, then NaN padding: the piece keeps the polyline's corners (path points).
    """
    pts = np.asarray(points, dtype=float)
    start = np.asarray(start, dtype=float)
    stop = np.asarray(stop, dtype=float)
    valid = np.isfinite(pts).all(axis=-1)
    filled = _fill_nan_forward(pts, valid)
    seg = np.linalg.norm(np.diff(filled, axis=1), axis=-1)
    cum = np.concatenate([np.zeros((pts.shape[0], 1)), np.cumsum(seg, axis=1)], axis=1)
    inner = valid & (cum > start[:, None]) & (cum < stop[:, None])
    both = np.concatenate([_at_arc(filled, seg, cum, start)[:, None],
                           np.where(inner[..., None], filled, np.nan),
                           _at_arc(filled, seg, cum, stop)[:, None]], axis=1)
    keep = np.concatenate([np.ones((pts.shape[0], 1), bool), inner, np.ones((pts.shape[0], 1), bool)], axis=1)
    perm = np.argsort(~keep, axis=1, kind="stable")
    return np.take_along_axis(both, perm[..., None], axis=1)


def smoothed_tangents(curve, sigma: float) -> np.ndarray:
    """Unit tangents (F, n, 3) of sampled curves (F, n, 3), averaged with a Gaussian of standard
    deviation ``sigma`` samples (the window cut at the curve's ends, so an end's tangent is the
    mean over its last ~2 sigma and turns gradually as a corner slides out of the curve);
    ``sigma <= 0``: plain `curve_tangents`.

    Why: a belly whose line turns at a via point (a corner of the OpenSim path) would turn its
    cross-sections within one sample, and the tissue on the inner side of the corner would fold
    over itself. With tangents averaged over about the belly's thickness the cross-sections turn
    gradually, so offset curves do not fold; the centre line itself keeps its corner (its length,
    hence the moment arm, is the path's), and a straight line or a circular arc keeps its
    tangents (the average of a symmetric window), except within ~2 sigma of the arc's ends.
    """
    tan = curve_tangents(np.asarray(curve, dtype=float))
    s = float(sigma)
    if s <= 0:
        return tan
    half = int(np.ceil(3.0 * s))
    offsets = np.arange(-half, half + 1)
    weights = np.exp(-0.5 * (offsets / s) ** 2)
    n = tan.shape[1]
    raw = np.arange(n)[:, None] + offsets[None, :]                              # (n, W)
    inside = (raw >= 0) & (raw <= n - 1)        # the window is cut at the ends, not padded: an
    idx = np.clip(raw, 0, n - 1)                # end's tangent is the mean over the last ~2 sigma
    window = np.zeros((n, n))                     # the weights as one (n, n) matrix
    np.add.at(window, (np.broadcast_to(np.arange(n)[:, None], idx.shape), idx),
              np.where(inside, weights[None, :], 0.0))
    return _unit(np.matmul(window, tan))


def closest_on_polyline(points: np.ndarray, curve: np.ndarray):
    """Nearest point of a polyline (n, 3) to each point (V, 3): segment index, fraction, distance."""
    a, b = curve[:-1], curve[1:]
    ab = b - a
    denom = np.maximum(np.sum(ab * ab, axis=-1), 1e-30)
    # (V, n-1) projections, chunked over vertices to bound memory
    best_j = np.empty(points.shape[0], dtype=np.int64)
    best_t = np.empty(points.shape[0])
    best_d = np.empty(points.shape[0])
    step = max(1, 2_000_000 // max(1, len(a)))
    for s in range(0, points.shape[0], step):  # chunks of vertices, not single vertices
        p = points[s:s + step]
        # component by component on (V, n-1) arrays: no (V, n-1, 3) temporaries
        dx = [p[:, None, k] - a[None, :, k] for k in range(3)]
        t = np.clip((dx[0] * ab[:, 0] + dx[1] * ab[:, 1] + dx[2] * ab[:, 2]) / denom, 0.0, 1.0)
        e = [a[:, k] + t * ab[:, k] - p[:, None, k] for k in range(3)]
        d2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
        j = np.argmin(d2, axis=1)
        rows = np.arange(p.shape[0])
        best_j[s:s + step] = j
        best_t[s:s + step] = t[rows, j]
        best_d[s:s + step] = np.sqrt(d2[rows, j])
    return best_j, best_t, best_d


def catmull_rom_weights(j: np.ndarray, t: np.ndarray, n: int):
    """Sample indices (V, 4) and weights (V, 4) of the line point at fraction ``t`` of segment
    ``j`` of a line of ``n`` samples: the uniform Catmull-Rom spline through the samples
    (Catmull & Rom 1974), the missing neighbour at an end extrapolated linearly
    (``c_-1 = 2 c_0 - c_1``). The weights sum to 1 and reproduce straight lines exactly, so a
    straight line is the chord; on an arc the spline's sag between samples is O(dphi^4) instead
    of the chord's ``R (1 - cos(dphi / 2))`` (0.3 mm on a 20 mm pulley with 7 mm samples)."""
    t2, t3 = t * t, t * t * t
    w = np.stack([0.5 * (-t + 2.0 * t2 - t3), 0.5 * (2.0 - 5.0 * t2 + 3.0 * t3),
                  0.5 * (t + 4.0 * t2 - 3.0 * t3), 0.5 * (-t2 + t3)], axis=1)
    idx = np.stack([j - 1, j, j + 1, j + 2], axis=1)
    if n < 3:
        return np.stack([j, j + 1], axis=1), np.stack([1.0 - t, t], axis=1)
    low = idx[:, 0] < 0                       # c_-1 = 2 c_0 - c_1
    w[low, 1] += 2.0 * w[low, 0]
    w[low, 2] -= w[low, 0]
    w[low, 0] = 0.0
    idx[low, 0] = 0
    high = idx[:, 3] > n - 1                  # c_n = 2 c_(n-1) - c_(n-2)
    w[high, 2] += 2.0 * w[high, 3]
    w[high, 1] -= w[high, 3]
    w[high, 3] = 0.0
    idx[high, 3] = n - 1
    return idx, w


def round_corners(points, radius, *, n_arc: int = 8) -> np.ndarray:
    """Polylines (F, P, 3) (trailing NaN padding) with every interior corner replaced by a
    quadratic Bezier arc of ``n_arc`` points from ``V - d u_in`` over ``V`` to ``V + d u_out``,
    ``d = min(radius tan(a / 2), 0.45 min(adjacent segment lengths))`` (a: the turn angle).

    Why: a belly that slides along its path (rigid tendon, `motion.surface.tendons`) carries its
    line samples past the path's corners; a sampled curve cuts each corner by an amount that
    depends on where the corner falls between two samples, so its length ripples as the corner
    passes and its derivative -- a moment arm -- by up to several mm. Rounded over a few sample
    spacings the corner is resolved by the samples, the ripple goes; the rounding itself shortens
    the line by ``~2 d - radius a`` per corner (continuous in the poses; ``d`` shrinks to 0
    with the turn angle). ``radius``: a float, or (F, P - 2) per interior point (0 leaves that
    corner sharp: its ``n_arc`` points coincide). Returns (F, 2 + (P - 2) n_arc, 3), NaN-padded;
    point ``j >= 1`` of a polyline is at ``1 + (j - 1) n_arc`` in it (`rounded_index`).
    """
    pts = np.asarray(points, dtype=float)
    f_n, p_n = pts.shape[:2]
    if p_n < 3:
        return pts
    valid = np.isfinite(pts).all(axis=-1)
    prev, here, nxt = pts[:, :-2], pts[:, 1:-1], pts[:, 2:]
    inner = valid[:, :-2] & valid[:, 1:-1] & valid[:, 2:]
    a_in, a_out = here - prev, nxt - here
    l_in = np.linalg.norm(a_in, axis=-1)
    l_out = np.linalg.norm(a_out, axis=-1)
    u_in = a_in / np.maximum(l_in, _TINY)[..., None]
    u_out = a_out / np.maximum(l_out, _TINY)[..., None]
    cos = np.clip(np.sum(u_in * u_out, axis=-1), -1.0, 1.0)
    half = 0.5 * np.arccos(cos)                                             # a / 2
    radius = np.broadcast_to(np.asarray(radius, dtype=float), half.shape)   # per corner allowed
    d = np.minimum(radius * np.tan(np.minimum(half, 1.4)), 0.45 * np.minimum(l_in, l_out))
    d = np.where(inner, d, 0.0)
    start = here - d[..., None] * u_in
    stop = here + d[..., None] * u_out
    t = np.linspace(0.0, 1.0, int(n_arc))[None, None, :, None]
    arc = ((1 - t) ** 2 * start[:, :, None] + 2 * t * (1 - t) * here[:, :, None] + t * t * stop[:, :, None])
    arc = np.where(inner[..., None, None], arc, np.nan)                     # (F, P-2, n_arc, 3)
    both = np.concatenate([pts[:, :1], arc.reshape(f_n, -1, 3), pts[:, -1:]], axis=1)
    # the last valid point: a NaN-padded polyline's end is before the padding
    last = np.maximum(valid.sum(axis=1) - 1, 0)
    both[:, -1] = pts[np.arange(f_n), last]
    keep = np.isfinite(both).all(axis=-1)
    perm = np.argsort(~keep, axis=1, kind="stable")
    return np.take_along_axis(both, perm[..., None], axis=1)


def rounded_index(index, n_arc: int = 8) -> np.ndarray:
    """Where point ``index`` (int array) of a polyline is after `round_corners` (the first of
    its ``n_arc`` arc points; the ends stay the ends)."""
    index = np.asarray(index, dtype=np.int64)
    return np.where(index >= 1, 1 + (index - 1) * int(n_arc), index)


def round_sliding_corners(curves, anchors, sliding, radius: float):
    """Round the corners that line samples slide past, keep the anchors' (`round_corners`).

    ``curves``: per line (F, P, 3) polylines; ``anchors``: per line (F, K) anchor positions or
    None; ``sliding``: per line (F, P) bool, the points to round (ConditionalPathPoints, which
    are no anchors). Returns the rounded curves and the anchors' positions in them.

    Why: `motion.surface.binding` resamples a line piecewise between anchors, so its samples
    slide past a corner inside a piece; a sampled polyline cuts that corner by an amount that
    depends on where it falls between two samples, so the cut line's length derivative jumps
    each time a sample crosses it, and the surface's fibres inherited the jumps (LHDL iliacus:
    fibre moment arms jumping ~10 mm at four hip angles, at its pelvic-brim
    ConditionalPathPoint, while the line's changed 0.3 mm per step). Rounded over the muscle's
    thickness (the length over which its cross-sections turn anyway) the samples and the fibre
    polylines resolve the bend; the rounding shortens the line by ~``d (2 tan(a/2) - a) /
    tan(a/2)`` at such a corner, smoothly in the poses.
    """
    out_c, out_a = [], []
    for c, a, m in zip(curves, anchors, sliding):
        c = np.asarray(c, dtype=float)
        single = c.ndim == 2
        c3, m2 = (c[None], np.asarray(m)[None]) if single else (c, np.asarray(m))
        if not m2[:, 1:-1].any():
            out_c.append(c)
            out_a.append(a)
            continue
        r = np.where(m2[:, 1:c3.shape[1] - 1], float(radius), 0.0)
        rc = round_corners(c3, r)
        out_c.append(rc[0] if single else rc)
        out_a.append(None if a is None else rounded_index(a))
    return out_c, out_a
