"""Numpy oracle of the compiled polyline kernel (`motion.wrapping.path_points._polyline_loop`):
the same sums written with array operations, for `test_action_lines`. Not part of the package.
"""
from __future__ import annotations

import numpy as np

from motion.wrapping.path_points import _moving_local, _point_set_active


def unwrapped_paths_numpy(plan, model, q_used, jac, tf, twist, out) -> None:
    """`motion.wrapping.action_lines._unwrapped_paths` with the numpy polyline instead of the kernel."""
    lengths, dldq, points, mask, order = out
    ps = plan.points
    n_slots = ps.shape[1]
    locals_ = [_moving_local(pt, model, q_used, jac) for _, pt in ps.moving]
    moving_loc = np.stack([x[0] for x in locals_], axis=1) if locals_ else np.zeros((len(q_used), 0, 3))
    act = _point_set_active(ps, q_used)
    p_n, arm = point_set_positions(ps, tf, moving_loc)
    length, g, pts, msk, ordr = polyline_numpy(plan, p_n, arm, act, twist, dldq)
    g_moving = g[:, [n for n, _ in ps.moving]]
    lengths[:, plan.unwrapped] = length
    points[:, plan.unwrapped, :n_slots] = pts
    mask[:, plan.unwrapped, :n_slots] = msk
    order[:, plan.unwrapped, :n_slots] = ordr
    for i, (m, n, _) in enumerate(plan.moving):
        gr = np.einsum("fk,fkj->fj", g_moving[:, i], tf[:, ps.bodies[n], :3, :3])
        dldq[:, m] += np.einsum("fj,fcj->fc", gr, locals_[i][1])


def point_set_positions(ps, tf_ground_body: np.ndarray, moving_loc: np.ndarray) -> tuple:
    """Ground positions (F, N, 3) of a `_PointSet`'s points and the same minus their body's
    origin (F, N, 3); ``moving_loc`` (F, n_moving, 3) are the moving points' body positions.

    Same arithmetic as `path_points`: ``p_body @ R^T + t`` per body for fixed points,
    ``R p_body(q) + t`` for moving points.
    """
    n_frames = tf_ground_body.shape[0]
    pts = np.empty((n_frames, len(ps.flat), 3))
    for b, idx in ps.by_body:                          # a model has few bodies
        rot, trans = tf_ground_body[:, b, :3, :3], tf_ground_body[:, b, :3, 3]
        pts[:, idx] = ps.loc[idx] @ np.swapaxes(rot, 1, 2) + trans[:, None]
    for i, (n, _) in enumerate(ps.moving):             # few moving points
        b = ps.bodies[n]
        rot, trans = tf_ground_body[:, b, :3, :3], tf_ground_body[:, b, :3, 3]
        pts[:, n] = np.einsum("fij,fj->fi", rot, moving_loc[:, i]) + trans
    arm = np.empty_like(pts)                           # p - t_body (moment arms about body origins)
    for b in np.unique(ps.bodies):
        on_b = slice(*np.searchsorted(ps.bodies, [b, b + 1]))
        arm[:, on_b] = pts[:, on_b] - tf_ground_body[:, b, None, :3, 3]
    return pts, arm


def polyline_numpy(plan, p_n, arm, act, twist, dldq) -> tuple:
    """The numpy version of `motion.wrapping.path_points._polyline_kernel`: length (F, M_u), g (F, N, 3),
    points, mask, order; adds the rigid-body terms to ``dldq`` (one matrix product per body)."""
    ps = plan.points
    n_paths, n_slots = ps.shape
    n_frames, n_points = p_n.shape[:2]
    act = act.reshape(n_frames, n_paths, n_slots)
    slots = np.arange(n_slots)
    base = (np.arange(n_paths) * n_slots)[:, None]
    idx = np.where(act, slots, n_slots)
    # next active point after i: running minimum from the right, shifted by one (grid slots)
    nxt = np.minimum.accumulate(idx[..., ::-1], axis=2)[..., ::-1]
    nxt = np.concatenate([nxt[..., 1:], np.full((n_frames, n_paths, 1), n_slots)], axis=2)
    nxt = np.where(act & (nxt < n_slots), base + nxt, n_paths * n_slots)
    prv = np.maximum.accumulate(np.where(act, slots, -1), axis=2)
    prv = np.concatenate([np.full((n_frames, n_paths, 1), -1), prv[..., :-1]], axis=2)
    prv = np.where(act & (prv >= 0), base + prv, n_paths * n_slots)
    # as point indices n (N = none): the segment n -> nxt_n leaves n, prv_n -> n arrives at n
    rows = (np.arange(n_frames) * (n_points + 1))[:, None]
    nxt_n = plan.slot_point[nxt.reshape(n_frames, -1)[:, ps.flat]] + rows
    prv_n = plan.slot_point[prv.reshape(n_frames, -1)[:, ps.flat]] + rows
    valid = nxt_n - rows < n_points
    ext = np.zeros((n_frames, n_points + 1, 3))
    ext[:, :n_points] = p_n
    seg = ext.reshape(-1, 3)[nxt_n] - p_n
    seg_len = np.sqrt(np.einsum("fni,fni->fn", seg, seg))
    grid = np.zeros((n_frames, n_paths * n_slots))
    grid[:, ps.flat] = np.where(valid, seg_len, 0.0)
    length = grid.reshape(n_frames, n_paths, n_slots).sum(axis=2)
    ok = valid & (seg_len > 0)
    ext[:, :n_points] = seg / np.where(ok, seg_len, 1.0)[..., None] * ok[..., None]     # unit, leaving n
    g = ext.reshape(-1, 3)[prv_n] - ext[:, :n_points]
    moment = np.empty((n_frames, n_points, 6))                       # (F, N, 6): (p - t) x g, g
    moment[..., 0] = arm[..., 1] * g[..., 2] - arm[..., 2] * g[..., 1]
    moment[..., 1] = arm[..., 2] * g[..., 0] - arm[..., 0] * g[..., 2]
    moment[..., 2] = arm[..., 0] * g[..., 1] - arm[..., 1] * g[..., 0]
    moment[..., 3:] = g
    moment = np.add.reduceat(moment, plan.starts, axis=1)            # (F, J, 6) per (body, path)
    for tw, pairs, paths, coords in plan.groups:                     # bodies in ascending order
        dldq[:, paths[:, None], coords] += moment[:, pairs] @ np.swapaxes(twist[:, tw], 1, 2)
    # active points keep their order; inactive ones move to the end as -1 (stable sort)
    order = np.take_along_axis(np.where(act, slots, -1), np.argsort(~act, axis=2, kind="stable"), axis=2)
    points = np.full((n_frames, n_paths * n_slots, 3), np.nan)
    act = act.reshape(n_frames, -1)
    points[:, ps.flat] = np.where(act[:, ps.flat, None], p_n, np.nan)
    return length, g, points.reshape(n_frames, n_paths, n_slots, 3), act.reshape(n_frames, n_paths, n_slots), order
