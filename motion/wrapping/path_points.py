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
from numba import njit

from ..osim.model import Model, Path

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
        d points / d q_k (see `motion.osim.kinematics.coordinate_values` for the meaning of k).
    names : (P,) tuple of str
    bodies : (P,) int
        Body index of each point.
    """

    points: np.ndarray
    active: np.ndarray
    d_points: np.ndarray | None
    names: tuple
    bodies: np.ndarray


def _path_statics(model: Model, path: Path) -> tuple:
    """What `path_points` takes from the model alone (kept with it, `Model.cached`): the points'
    body indices (P,), per body touched (body, fixed point indices, their body-frame locations
    (P_b, 3), moving point indices), and all locations (P, 3)."""
    def make():
        bodies = np.array([model.body_index(p.body) for p in path.points], dtype=int)
        locations = np.array([p.location for p in path.points], dtype=float).reshape(len(path.points), 3)
        moving = np.array([p.kind == "moving" for p in path.points], dtype=bool)
        groups = []
        for b in np.unique(bodies):
            fixed = np.flatnonzero((bodies == b) & ~moving)
            groups.append((int(b), fixed, locations[fixed], np.flatnonzero((bodies == b) & moving)))
        for arr in (bodies, locations):
            arr.setflags(write=False)
        return bodies, tuple(groups), locations
    return model.cached(("path point statics", path.name), make)


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
        Assembled coordinates (`motion.osim.kinematics.coordinate_values`).
    tf_ground_body : (F, B, 4, 4) float
    jac : (F, C, C) float, optional
        dq_used/dq_k; with ``d_tf_ground_body`` gives ``d_points``.
    d_tf_ground_body : (F, B, C, 4, 4) float, optional

    Returns
    -------
    PathPoints
    """
    bodies, groups, _ = _path_statics(model, path)
    want_d = jac is not None and d_tf_ground_body is not None
    n_frames, n_points = q_used.shape[0], len(path.points)
    pts = np.empty((n_frames, n_points, 3))
    d_pts = np.empty((n_frames, n_points, q_used.shape[1], 3)) if want_d else None
    for b, fixed, p_body, moving in groups:           # a path touches a few bodies
        rot, trans = tf_ground_body[:, b, :3, :3], tf_ground_body[:, b, :3, 3]
        if len(fixed):
            pts[:, fixed] = p_body @ np.swapaxes(rot, 1, 2) + trans[:, None]
            if want_d:
                drot = d_tf_ground_body[:, b, :, :3, :3]                     # (F, C, 3, 3)
                dtrans = d_tf_ground_body[:, b, :, :3, 3]                    # (F, C, 3)
                # one matrix product for all frames and coordinates: (F C 3, 3) @ (3, P_b)
                dp = (drot.reshape(-1, 3) @ p_body.T).reshape(drot.shape[:3] + (len(fixed),))
                d_pts[:, fixed] = np.moveaxis(dp, 3, 1) + dtrans[:, None]
        for i in moving:                                                     # few moving points
            loc, dloc = _moving_local(path.points[i], model, q_used, jac if want_d else None)
            pts[:, i] = np.einsum("fij,fj->fi", rot, loc) + trans
            if want_d:
                drot = d_tf_ground_body[:, b, :, :3, :3]
                d_pts[:, i] = (np.einsum("fcij,fj->fci", drot, loc) + d_tf_ground_body[:, b, :, :3, 3]
                               + np.einsum("fij,fcj->fci", rot, dloc))
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


def _point_set_active(ps: _PointSet, q_used: np.ndarray) -> np.ndarray:
    """(F, M*K) bool: the real points of a `_PointSet`'s grid, conditional ones inside their range."""
    act = np.zeros((q_used.shape[0], ps.shape[0] * ps.shape[1]), dtype=bool)
    act[:, ps.flat] = True
    if len(ps.cond):
        x = q_used[:, ps.cond_coord]
        act[:, ps.flat[ps.cond]] = (x >= ps.cond_lo) & (x <= ps.cond_hi)
    return act


def _polyline_kernel():
    """The compiled polyline kernel of a `_PointSet` (`_polyline_loop`: numba, module level,
    cached on disk; numba compiles a dispatcher once, thread-safely).

    ``kernel(tf, bodies, loc, moving, moving_loc, act, slot_point, n_slots, pair_of, twist,
    t_pair, t_twist, t_path, t_coord, path_index, length, g_moving, dldq, points, mask, order)``:
    per frame, the ground position ``R p_body + t`` of every point (``moving_loc`` (F, n_moving,
    3) replaces ``loc`` at the indices ``moving``), then per path the active points in path
    order: length = sum of segment lengths, g = unit vector of the segment arriving at a point
    minus the one leaving it, the moment [(p - t_body) x g, g] summed per (body, path) pair, and
    ``twist[t_twist] . moment[t_pair]`` added to ``dldq[:, t_path, t_coord]`` term by term (in
    the terms' order). Path m of the set is row ``path_index[m]`` of ``length``,
    ``dldq``, ``points`` (NaN on entry), ``mask`` (False), ``order`` (-1; the active points'
    slots in path order); ``g_moving`` (F, n_moving, 3) receives g of the moving points.
    """
    return _polyline_loop


@njit(cache=True, nogil=True)
def _polyline_loop(tf, bodies, loc, moving, moving_loc, act, slot_point, n_slots, pair_of, twist, t_pair, t_twist,
                   t_path, t_coord, path_index, length, g_moving, dldq, points, mask, order):  # pragma: no cover
    n_frames, n_points, n_paths = tf.shape[0], loc.shape[0], path_index.shape[0]
    pos = np.empty((n_points, 3))
    arm = np.empty((n_points, 3))
    g = np.empty((n_points, 3))
    moment = np.empty((pair_of[n_points - 1] + 1 if n_points else 0, 6))
    here = loc.copy()
    for f in range(n_frames):
        for i in range(moving.shape[0]):
            for a in range(3):
                here[moving[i], a] = moving_loc[f, i, a]
        for n in range(n_points):
            b = bodies[n]
            for a in range(3):
                arm[n, a] = tf[f, b, a, 0] * here[n, 0] + tf[f, b, a, 1] * here[n, 1] + tf[f, b, a, 2] * here[n, 2]
                pos[n, a] = arm[n, a] + tf[f, b, a, 3]
                arm[n, a] = pos[n, a] - tf[f, b, a, 3]
        g[:] = 0.0
        for m in range(n_paths):
            row = path_index[m]
            prev, total, count = -1, 0.0, 0
            for k in range(n_slots):
                s = m * n_slots + k
                n = slot_point[s]
                if n == n_points or not act[f, s]:
                    continue
                mask[f, row, k] = True
                order[f, row, count] = k
                count += 1
                for a in range(3):
                    points[f, row, k, a] = pos[n, a]
                if prev >= 0:
                    d0, d1, d2 = pos[n, 0] - pos[prev, 0], pos[n, 1] - pos[prev, 1], pos[n, 2] - pos[prev, 2]
                    seg = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                    total += seg
                    if seg > 0:
                        d0, d1, d2 = d0 / seg, d1 / seg, d2 / seg
                    else:
                        d0, d1, d2 = 0.0, 0.0, 0.0
                    g[prev, 0] -= d0
                    g[prev, 1] -= d1
                    g[prev, 2] -= d2
                    g[n, 0], g[n, 1], g[n, 2] = d0, d1, d2
                prev = n
            length[f, row] = total
        moment[:] = 0.0
        for n in range(n_points):
            j = pair_of[n]
            moment[j, 0] += arm[n, 1] * g[n, 2] - arm[n, 2] * g[n, 1]
            moment[j, 1] += arm[n, 2] * g[n, 0] - arm[n, 0] * g[n, 2]
            moment[j, 2] += arm[n, 0] * g[n, 1] - arm[n, 1] * g[n, 0]
            moment[j, 3] += g[n, 0]
            moment[j, 4] += g[n, 1]
            moment[j, 5] += g[n, 2]
        for t in range(t_pair.shape[0]):
            j, u = t_pair[t], t_twist[t]
            acc = 0.0
            for a in range(6):
                acc += twist[f, u, a] * moment[j, a]
            dldq[f, t_path[t], t_coord[t]] += acc
        for i in range(moving.shape[0]):
            for a in range(3):
                g_moving[f, i, a] = g[moving[i], a]
