"""The pieces of a filtered fibre (`fibres.attachments.filtering`, Kohout et al. 2012 §3.4).

A fibre the attachment filter cuts becomes the polyline [new origin end, origin cut, kept
points..., insertion cut, new insertion end], resampled uniformly by arc length back to P points.
Each output point is recorded once, at rest, as a piece (0: the new origin segment, 1: the kept
body, 2: the new insertion segment) and a parameter along it (`record_resampling`); a deformed
copy is then evaluated from the same pieces and parameters (`evaluate_pieces`), which is smooth
in every input and keeps fibre k the same material fibre in every frame.
"""
from __future__ import annotations

import numpy as np

__all__ = ["at_index", "untouched", "record_resampling", "evaluate_pieces"]


def at_index(pts, tau):
    """Points at fractional fibre indices: pts (N, P, 3), tau (N, M) -> (N, M, 3), linear
    along the poly-line (extrapolated along the first/last segment outside 0..P-1)."""
    p = pts.shape[1]
    i0 = np.clip(np.floor(tau).astype(np.int64), 0, p - 2)
    f = (tau - i0)[..., None]
    rows = np.arange(len(pts))[:, None]
    a = pts[rows, i0]
    return a + f * (pts[rows, i0 + 1] - a)



def untouched(n, p):
    """The choices' arrays of N fibres of P points that no plane cuts (cut, segment,
    cut_param, target_face, target_vertices, target_bary, piece, param)."""
    piece = np.ones((n, p), np.int8)
    param = np.broadcast_to(np.linspace(0.0, 1.0, p), (n, p)).copy()
    piece[:, 0], param[:, 0] = 0, 0.0
    if p > 1:
        piece[:, -1], param[:, -1] = 2, 1.0
    return (np.zeros((n, 2), bool), np.zeros((n, 2), np.int64), np.zeros((n, 2)),
            np.full((n, 2), -1, np.int64), np.zeros((n, 2, 3), np.int64), np.zeros((n, 2, 3)),
            piece, param)


def record_resampling(pts, verts, cut, segment, cut_param, target, piece, param):
    """Piece and parameter of every point of the uniform arc-length resampling of
    [end_o, c_o, kept points..., c_i, end_i] (dropped points collapse onto the cuts), in place."""
    sel = cut.any(axis=1)
    fib = pts[sel]
    m, p = fib.shape[:2]
    tau_o, tau_i, c_o, c_i, end_o, end_i = _geometry(fib, verts, cut[sel], segment[sel],
                                                     cut_param[sel],
                                                     (target[0][sel], target[1][sel]))
    body_tau = np.clip(np.arange(p, dtype=float)[None, :], tau_o[:, None], tau_i[:, None])
    body = np.where((body_tau == np.arange(p))[..., None], fib, at_index(fib, body_tau))
    poly = np.concatenate([end_o[:, None], c_o[:, None], body, c_i[:, None], end_i[:, None]], 1)
    tau = np.concatenate([tau_o[:, None], tau_o[:, None], body_tau, tau_i[:, None],
                          tau_i[:, None]], axis=1)
    seg = np.linalg.norm(np.diff(poly, axis=1), axis=-1)              # (M, Q-1)
    cum = np.concatenate([np.zeros((m, 1)), np.cumsum(seg, axis=1)], axis=1)
    t = cum[:, -1:] * np.linspace(0.0, 1.0, p)[None, :]               # (M, P)
    k = np.clip((cum[:, None, 1:] <= t[:, :, None]).sum(axis=2), 0, poly.shape[1] - 2)
    rows = np.arange(m)[:, None]
    c0, c1 = cum[rows, k], cum[rows, k + 1]
    frac = np.where(c1 > c0, (t - c0) / np.where(c1 > c0, c1 - c0, 1.0), 0.0)
    q = poly.shape[1]
    pc = np.where(k == 0, 0, np.where(k == q - 2, 2, 1)).astype(np.int8)
    tk = tau[rows, k] + frac * (tau[rows, k + 1] - tau[rows, k])
    alpha = (tk - tau_o[:, None]) / (tau_i - tau_o)[:, None]
    pr = np.where(pc == 1, alpha, frac)
    pc[:, 0], pr[:, 0] = 0, 0.0
    pc[:, -1], pr[:, -1] = 2, 1.0
    piece[sel], param[sel] = pc, pr


def _geometry(pts, verts, cut, segment, s, target):
    """Fractional indices and points of the two cuts and the two new ends (uncut ends: the
    fibre's own end, index 0 / P-1); ``target`` is (corners (N, 2, 3), barycentric (N, 2, 3))."""
    corner, bary = target
    ends = np.einsum("nekc,nek->nec", verts[corner], bary)             # (N, 2, 3)
    p = pts.shape[1]
    seg, st, ct = segment.T, np.ascontiguousarray(s.T), cut.T[..., None]    # both ends at once
    a = pts[np.arange(len(pts)), seg]                                         # (2, N, 3)
    c = a + st[..., None] * (pts[np.arange(len(pts)), seg + 1] - a)
    own = np.stack([pts[:, 0], pts[:, -1]])                                   # (2, N, 3)
    tau = np.where(cut.T, seg + st, np.array([[0.0], [p - 1.0]]))
    c = np.ascontiguousarray(np.where(ct, c, own))
    e = np.ascontiguousarray(np.where(ct, ends.transpose(1, 0, 2), own))
    return tau[0], tau[1], c[0], c[1], e[0], e[1]


def evaluate_pieces(fib, verts, cut, segment, s, target, piece, param):
    """Output points from the recorded pieces and parameters."""
    tau_o, tau_i, c_o, c_i, end_o, end_i = _geometry(fib, verts, cut, segment, s, target)
    lam = param[..., None]
    on_o = end_o[:, None] + lam * (c_o - end_o)[:, None]
    on_i = c_i[:, None] + lam * (end_i - c_i)[:, None]
    body = at_index(fib, tau_o[:, None] + param * (tau_i - tau_o)[:, None])
    pc = piece[..., None]
    return np.where(pc == 0, on_o, np.where(pc == 2, on_i, body))
