"""Ground positions of a path's points per frame, which of them are active, and their derivatives.

Point kinds (OpenSim's PathPoint, ConditionalPathPoint, MovingPathPoint):
- fixed: ``location`` in its body.
- conditional: fixed in its body, active when ``range[0] - 1e-5 <= q <= range[1] + 1e-5``
  (OpenSim 4.6 ConditionalPathPoint::isActive, the coordinate's value after assembly).
- moving: location ``(fx(qx), fy(qy), fz(qz))`` in its body (MovingPathPoint; an axis without
  function keeps ``location``).

``p_ground = R_ground_body p_body + t_ground_body``; its derivative w.r.t. coordinate k is
``dR/dq_k p_body + dt/dq_k + R dp_body/dq_k`` with ``dp_body/dq_k = f'(q_c) dq_c/dq_k``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import Model, Path

__all__ = ["PathPoints", "path_points", "CONDITIONAL_TOLERANCE"]   # + private batched `_PointSet`

CONDITIONAL_TOLERANCE = 1e-5   # OpenSim ConditionalPathPoint::isActive


@dataclass(frozen=True, eq=False)
class PathPoints:
    """The points of one path for all frames.

    Attributes
    ----------
    points : (F, P, 3) float
        Ground positions of every defined point (active or not).
    active : (F, P) bool
        Whether each point is part of the path in that frame.
    d_points : (F, P, C, 3) float or None
        d points / d q_k (see `motion.kinematics.coordinate_values` for the meaning of k).
    names : (P,) tuple of str
    bodies : (P,) int
        Body index of each point.
    """

    points: np.ndarray
    active: np.ndarray
    d_points: np.ndarray | None
    names: tuple
    bodies: np.ndarray


def _local_positions(path: Path, model: Model, q: np.ndarray, jac: np.ndarray | None) -> tuple:
    """Body-frame positions (F, P, 3) and their derivatives (F, P, C, 3) or None."""
    n_frames = q.shape[0]
    n_points = len(path.points)
    loc = np.broadcast_to(np.array([p.location for p in path.points]), (n_frames, n_points, 3)).copy()
    dloc = None if jac is None else np.zeros((n_frames, n_points, q.shape[1], 3))
    for i, p in enumerate(path.points):          # only the (few) moving points
        if p.kind == "moving":
            loc[:, i], d = _moving_local(p, model, q, jac)
            if dloc is not None:
                dloc[:, i] = d
    return loc, dloc


def active_mask(path: Path, model: Model, q: np.ndarray) -> np.ndarray:
    """(F, P) bool: conditional points inside their range (+-1e-5), all others True."""
    act = np.ones((q.shape[0], len(path.points)), dtype=bool)
    for i, p in enumerate(path.points):
        if p.kind == "conditional":
            x = q[:, model.coordinate_index(p.coordinate)]
            act[:, i] = (x >= p.range[0] - CONDITIONAL_TOLERANCE) & (x <= p.range[1] + CONDITIONAL_TOLERANCE)
    return act


def path_points(path: Path, model: Model, q_used: np.ndarray, tf_ground_body: np.ndarray,
                *, jac: np.ndarray | None = None, d_tf_ground_body: np.ndarray | None = None) -> PathPoints:
    """Ground positions, active mask and derivatives of a path's points.

    Parameters
    ----------
    path : Path
    model : Model
    q_used : (F, C) float
        Assembled coordinates (`motion.kinematics.coordinate_values`).
    tf_ground_body : (F, B, 4, 4) float
    jac : (F, C, C) float, optional
        dq_used/dq_k; with ``d_tf_ground_body`` gives ``d_points``.
    d_tf_ground_body : (F, B, C, 4, 4) float, optional

    Returns
    -------
    PathPoints
    """
    bodies = np.array([model.body_index(p.body) for p in path.points], dtype=int)
    want_d = jac is not None and d_tf_ground_body is not None
    loc, dloc = _local_positions(path, model, q_used, jac if want_d else None)
    n_frames, n_points = loc.shape[:2]
    moving = np.array([p.kind == "moving" for p in path.points])
    pts = np.empty((n_frames, n_points, 3))
    d_pts = np.empty((n_frames, n_points, q_used.shape[1], 3)) if want_d else None
    for b in np.unique(bodies):                       # a path touches a few bodies
        rot, trans = tf_ground_body[:, b, :3, :3], tf_ground_body[:, b, :3, 3]
        fixed = np.flatnonzero((bodies == b) & ~moving)
        if len(fixed):
            p_body = loc[0, fixed]                                           # (P_b, 3), same every frame
            pts[:, fixed] = p_body @ np.swapaxes(rot, 1, 2) + trans[:, None]
            if want_d:
                drot = d_tf_ground_body[:, b, :, :3, :3]                     # (F, C, 3, 3)
                dtrans = d_tf_ground_body[:, b, :, :3, 3]                    # (F, C, 3)
                # one matrix product for all frames and coordinates: (F C 3, 3) @ (3, P_b)
                dp = (drot.reshape(-1, 3) @ p_body.T).reshape(drot.shape[:3] + (len(fixed),))
                d_pts[:, fixed] = np.moveaxis(dp, 3, 1) + dtrans[:, None]
        for i in np.flatnonzero((bodies == b) & moving):                     # few moving points
            pts[:, i] = np.einsum("fij,fj->fi", rot, loc[:, i]) + trans
            if want_d:
                drot = d_tf_ground_body[:, b, :, :3, :3]
                d_pts[:, i] = (np.einsum("fcij,fj->fci", drot, loc[:, i]) + d_tf_ground_body[:, b, :, :3, 3]
                               + np.einsum("fij,fcj->fci", rot, dloc[:, i]))
    return PathPoints(pts, active_mask(path, model, q_used), d_pts,
                      tuple(p.name for p in path.points), bodies)


@dataclass(frozen=True, eq=False)
class _PointSet:
    """Index arrays of the points of several paths, stacked (built once per model and paths).

    The paths' points sit in a padded (M, K) grid (K = most points of a path); ``flat`` (N,)
    gives each real point's slot in the flattened grid. The N points are sorted by body, then
    path, then path order (each body's points are contiguous).

    Attributes
    ----------
    shape : (M, K)
    flat, bodies : (N,) int
    loc : (N, 3) float
        Body-frame locations (``location``; moving points are replaced per frame).
    by_body : tuple of (body, (N_b,) int)
        Fixed (not moving) points grouped by body.
    cond, cond_coord : (Q,) int
        Conditional points (indices into N) and their coordinate.
    cond_lo, cond_hi : (Q,) float
        Their ranges widened by CONDITIONAL_TOLERANCE.
    moving : tuple of (n, PathPoint)
    """

    shape: tuple
    flat: np.ndarray
    bodies: np.ndarray
    loc: np.ndarray
    by_body: tuple
    cond: np.ndarray
    cond_coord: np.ndarray
    cond_lo: np.ndarray
    cond_hi: np.ndarray
    moving: tuple


def _point_set(model: Model, paths: list) -> _PointSet:
    """Stack the points of ``paths`` (see `_PointSet`)."""
    n_slots = max((len(p.points) for p in paths), default=0)
    pts = sorted(((model.body_index(pt.body), m * n_slots + k, pt) for m, path in enumerate(paths)
                  for k, pt in enumerate(path.points)), key=lambda t: t[:2])
    pts = [(f, pt) for _, f, pt in pts]                 # by body, then path, then path order
    flat = np.array([f for f, _ in pts], dtype=np.int64)
    bodies = np.array([model.body_index(pt.body) for _, pt in pts], dtype=np.int64)
    loc = np.array([pt.location for _, pt in pts], dtype=float).reshape(len(pts), 3)
    moving = tuple((n, pt) for n, (_, pt) in enumerate(pts) if pt.kind == "moving")
    is_moving = np.zeros(len(pts), dtype=bool)
    is_moving[[n for n, _ in moving]] = True
    by_body = tuple((int(b), np.flatnonzero((bodies == b) & ~is_moving)) for b in np.unique(bodies))
    cond = [(n, pt) for n, (_, pt) in enumerate(pts) if pt.kind == "conditional"]
    return _PointSet((len(paths), n_slots), flat, bodies, loc, tuple((b, i) for b, i in by_body if len(i)),
                     np.array([n for n, _ in cond], dtype=np.int64),
                     np.array([model.coordinate_index(pt.coordinate) for _, pt in cond], dtype=np.int64),
                     np.array([pt.range[0] - CONDITIONAL_TOLERANCE for _, pt in cond], dtype=float),
                     np.array([pt.range[1] + CONDITIONAL_TOLERANCE for _, pt in cond], dtype=float), moving)


def _moving_local(pt, model: Model, q: np.ndarray, jac: np.ndarray | None) -> tuple:
    """Body-frame position (F, 3) of one MovingPathPoint and its derivative (F, C, 3) or None."""
    loc = np.broadcast_to(pt.location, (q.shape[0], 3)).copy()
    dloc = None if jac is None else np.zeros((q.shape[0], q.shape[1], 3))
    for axis in range(3):
        f, c = pt.moving_functions[axis], pt.moving_coordinates[axis]
        if f is None:
            continue
        if c is None:
            loc[:, axis] = float(f.value(0.0))
            continue
        k = model.coordinate_index(c)
        loc[:, axis] = f.value(q[:, k])
        if dloc is not None:
            dloc[:, :, axis] = f.derivative(q[:, k])[:, None] * jac[:, k, :]
    return loc, dloc


def _point_set_positions(ps: _PointSet, model: Model, q_used: np.ndarray, tf_ground_body: np.ndarray) -> tuple:
    """Ground positions (F, N, 3) of a `_PointSet`'s points, the same minus their body's origin
    (F, N, 3), and the active grid (F, M*K) bool.

    Same arithmetic as `path_points`: ``p_body @ R^T + t`` per body for fixed points,
    ``R p_body(q) + t`` for moving points; conditional points active inside their range.
    """
    n_frames = q_used.shape[0]
    pts = np.empty((n_frames, len(ps.flat), 3))
    for b, idx in ps.by_body:                          # a model has few bodies
        rot, trans = tf_ground_body[:, b, :3, :3], tf_ground_body[:, b, :3, 3]
        pts[:, idx] = ps.loc[idx] @ np.swapaxes(rot, 1, 2) + trans[:, None]
    for n, pt in ps.moving:                            # few moving points
        b = ps.bodies[n]
        loc, _ = _moving_local(pt, model, q_used, None)
        pts[:, n] = np.einsum("fij,fj->fi", tf_ground_body[:, b, :3, :3], loc) + tf_ground_body[:, b, :3, 3]
    act = np.zeros((n_frames, ps.shape[0] * ps.shape[1]), dtype=bool)
    act[:, ps.flat] = True
    if len(ps.cond):
        x = q_used[:, ps.cond_coord]
        act[:, ps.flat[ps.cond]] = (x >= ps.cond_lo) & (x <= ps.cond_hi)
    arm = np.empty_like(pts)                           # p - t_body (moment arms about body origins)
    for b in np.unique(ps.bodies):
        on_b = slice(*np.searchsorted(ps.bodies, [b, b + 1]))
        arm[:, on_b] = pts[:, on_b] - tf_ground_body[:, b, None, :3, 3]
    return pts, arm, act
