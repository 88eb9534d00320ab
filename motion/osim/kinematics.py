"""Forward kinematics of an OpenSim model, vectorised over frames, with exact derivatives.

Coordinates (`coordinate_values`) are set as OpenSim's AnalyzeTool does: the motion's values,
then "assembly": locked coordinates keep their default value; in models with constraints,
clamped coordinates are clamped to their range; every CoordinateCouplerConstraint sets its
dependent coordinate to ``scale_factor * f(q_independent)``. The Jacobian ``dq_dqk`` (F, C, C)
gives column k = dq/dq_k: for a coordinate that is not a coupler's dependent, the total
derivative along the couplers (chain rule); for a dependent coordinate the partial one (e_k).

Body poses (`body_poses`, `body_pose_derivatives`) compose the joints root to leaf:
``tf_ground_child = tf_ground_parent @ tf_parent_F @ tf_F_M(q) @ inv(tf_child_M)`` with
``tf_F_M = [R1 R2 R3 | sum_i f_i(q) a_i]`` (OpenSim's SpatialTransform / SimTK FunctionBased
mobilizer: rotations about axes in successively rotated frames, translations in F).
Derivatives are forward-mode (analytic product rule), not finite differences.

WeldConstraints (closed loops) are assembled as OpenSim does: the free coordinates move as
little as possible from the motion's values so that the welded frames coincide
(`_assemble_welds`). The derivatives are then taken along the couplers only, with the weld-solved
coordinates held (the references' ``neg_dLdq_fd`` convention).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .model import Model

__all__ = ["BodyPoses", "body_poses", "body_pose_derivatives", "coordinate_values", "motion_coordinates",
           "motion_from_array"]


@dataclass(frozen=True, eq=False)
class BodyPoses:
    """Every body's frame in ground, per frame.

    Attributes
    ----------
    tf_ground_body : (F, B, 4, 4) float
        p_ground = tf_ground_body[f, b] @ p_body (homogeneous).
    body_names : (B,) tuple of str
        Ground first, model order.
    time : (F,) float
    q : (F, C) float
        The coordinate values used (after locking, clamping and couplers).
    """

    tf_ground_body: np.ndarray
    body_names: tuple
    time: np.ndarray
    q: np.ndarray

    def __post_init__(self):
        for key in ("tf_ground_body", "time", "q"):
            arr = np.array(getattr(self, key), dtype=float, copy=True)
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)
        if self.tf_ground_body.shape[1:] != (len(self.body_names), 4, 4):
            raise ValueError(f"tf_ground_body must be (F, {len(self.body_names)}, 4, 4)")

    def __getitem__(self, body: str) -> np.ndarray:
        """(F, 4, 4) transforms of the body called ``body``."""
        return self.tf_ground_body[:, self.body_names.index(body)]

    def __array__(self, dtype=None, copy=None):
        return np.asarray(self.tf_ground_body, dtype=dtype)


@dataclass(frozen=True)
class _SimpleMotion:
    time: np.ndarray
    q: np.ndarray
    coordinate_names: tuple


def motion_from_array(model: Model, q, time=None):
    """A motion-like object (``time``, ``q``, ``coordinate_names``) from (F, C) values in model order."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.shape[1] != len(model.coordinates):
        raise ValueError(f"q must be (F, {len(model.coordinates)}), got {q.shape}")
    t = np.arange(len(q), dtype=float) if time is None else np.asarray(time, dtype=float)
    return _SimpleMotion(t, q, model.coordinate_names)


def motion_coordinates(model: Model, motion) -> tuple:
    """(time (F,), q (F, C) in model order) from a Motion-like object or an (F, C) array."""
    if hasattr(motion, "q"):
        q = np.asarray(motion.q, dtype=float)
        names = tuple(getattr(motion, "coordinate_names", model.coordinate_names))
        time = np.asarray(getattr(motion, "time", np.arange(len(q))), dtype=float)
    else:
        q = np.atleast_2d(np.asarray(motion, dtype=float))
        names = model.coordinate_names
        time = np.arange(len(q), dtype=float)
    if q.ndim != 2 or q.shape[1] != len(names):
        raise ValueError(f"motion q must be (F, {len(names)}), got {q.shape}")
    if names != model.coordinate_names:
        missing = [n for n in model.coordinate_names if n not in names]
        if missing:
            raise InputError(f"the motion lacks coordinates {missing[:5]} of model {model.name!r}",
                             where="motion", fix="give a value for every model coordinate (motion.load_motion fills defaults)")
        q = q[:, [names.index(n) for n in model.coordinate_names]]
    return time, q


def _coupler_order(model: Model) -> list:
    """Couplers ordered so that a coupler whose independent is another's dependent comes after it."""
    pending = list(model.couplers)
    deps = {c.dependent for c in pending}
    done, out = set(), []
    while pending:
        rest = [c for c in pending if any(i in deps and i not in done for i in c.independent)]
        ready = [c for c in pending if c not in rest]
        if not ready:
            raise InputError("coordinate couplers form a cycle", file=model.file, where="ConstraintSet",
                             fix="make the coupler chain acyclic")
        out += ready
        done |= {c.dependent for c in ready}
        pending = rest
    return out


def clipped_coordinates(model: Model) -> list:
    """``[(index, lo, hi)]`` of the clamped coordinates that posing clips to their range: in
    models with constraints (couplers or welds), where OpenSim's assembly enforces the clamp;
    elsewhere a clamped coordinate keeps the motion's value, as OpenSim's posing does."""
    if not (model.couplers or model.welds):
        return []
    return [(i, c.range[0], c.range[1]) for i, c in enumerate(model.coordinates) if c.clamped]


def coordinate_values(model: Model, q) -> tuple:
    """Assembled coordinates and their Jacobian w.r.t. each coordinate.

    Parameters
    ----------
    q : (F, C) float
        Coordinate values in model order (e.g. a motion's).

    Returns
    -------
    q_used : (F, C) float
        After locking (default value), clamping (models with constraints) and couplers.
    dq_dqk : (F, C, C) float
        dq_used[:, i] / dq_k in [:, i, k] (see module docstring).
    """
    q = np.array(np.atleast_2d(q), dtype=float)
    n_frames, n_coords = q.shape
    for i, c in enumerate(model.coordinates):
        if c.locked:
            q[:, i] = c.default_value
    for i, lo, hi in clipped_coordinates(model):
        q[:, i] = np.clip(q[:, i], lo, hi)
    jac = np.broadcast_to(np.eye(n_coords), (n_frames, n_coords, n_coords)).copy()
    for cp in _coupler_order(model):
        d = model.coordinate_index(cp.dependent)
        k = model.coordinate_index(cp.independent[0])
        x = q[:, k]
        q[:, d] = cp.scale_factor * cp.function.value(x)
        slope = cp.scale_factor * cp.function.derivative(x)
        # row d = slope * row k (chain rule through k's own coupler, if any); partial stays e_d
        jac[:, d, :] = slope[:, None] * jac[:, k, :]
        jac[:, d, d] = 1.0
    return q, jac


def _axis_cross(axis: np.ndarray) -> tuple:
    """([axis]x, [axis]x^2) (3, 3) of a unit axis (Rodrigues' formula's two matrices)."""
    kx = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return kx, kx @ kx


def _axis_angle_matrices(axis: np.ndarray, angle: np.ndarray, cross: tuple | None = None) -> tuple:
    """Rotation about a unit ``axis`` by ``angle`` (F,) and its derivative dR/dangle (F, 3, 3);
    ``cross``: `_axis_cross` of the axis, if already made."""
    kx, kk = _axis_cross(axis) if cross is None else cross
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    rot = np.eye(3) + s * kx + (1.0 - c) * kk
    drot = c * kx + s * kk
    return rot, drot


def _joint_statics(model: Model, joint) -> tuple:
    """What a joint's transform takes from the model alone (kept with it, `Model.cached`):
    inv(tf_child_jointframe), per rotation axis its (R, dR) (1, 3, 3) if it has no coordinate
    (else its `_axis_cross`), per translation axis its value if constant (else None), and for a joint
    without coordinates its whole tf_F_M (4, 4)."""
    def make():
        rots = []
        for ax in joint.axes[:3]:
            if ax.coordinates:
                rots.append(_axis_cross(ax.axis))
            else:              # constant: one frame, broadcast
                rots.append(_axis_angle_matrices(ax.axis, np.full(1, float(ax.function.value(0.0)))))
        shifts = [None if ax.coordinates else float(ax.function.value(0.0)) for ax in joint.axes[3:]]
        inv_child = np.linalg.inv(joint.tf_child_jointframe)
        fixed = None
        if not joint.coordinates:
            fixed = _joint_transform(joint, np.zeros((1, len(model.coordinates))), model._coord_index,
                                     (inv_child, rots, shifts, None))[0][0]
            fixed.setflags(write=False)
        return inv_child, rots, shifts, fixed
    return model.cached(("joint statics", joint.name), make)


def _joint_transform(joint, q: np.ndarray, cidx: dict, statics: tuple) -> tuple:
    """tf_F_M (F, 4, 4) and its partials w.r.t. the joint's coordinates (F, n, 4, 4);
    ``statics`` from `_joint_statics`."""
    n_frames = q.shape[0]
    _, const_rots, shifts, fixed = statics
    n = len(joint.coordinates)
    if fixed is not None:                 # no coordinate: the same transform every frame
        return np.broadcast_to(fixed, (n_frames, 4, 4)), np.zeros((n_frames, 0, 4, 4))
    local = {name: i for i, name in enumerate(joint.coordinates)}
    tf = np.broadcast_to(np.eye(4), (n_frames, 4, 4)).copy()
    dtf = np.zeros((n_frames, n, 4, 4))
    rots, drots, owners = [], [], []
    for ax, const in zip(joint.axes[:3], const_rots):
        if ax.coordinates:
            x = q[:, cidx[ax.coordinates[0]]]
            val, dval = ax.function.value(x), ax.function.derivative(x)
            owners.append((local[ax.coordinates[0]], dval))
            r, dr = _axis_angle_matrices(ax.axis, val, const)
        else:
            owners.append(None)
            r, dr = const
        rots.append(r)
        drots.append(dr)
    tf[:, :3, :3] = rots[0] @ rots[1] @ rots[2]
    for i, owner in enumerate(owners):
        if owner is None:
            continue
        mats = [rots[0], rots[1], rots[2]]
        mats[i] = drots[i]
        dtf[:, owner[0], :3, :3] += owner[1][:, None, None] * (mats[0] @ mats[1] @ mats[2])
    if joint.radii is not None:     # EllipsoidJoint: origin of M on the ellipsoid at radii * z_M
        tf[:, :3, 3] += joint.radii * tf[:, :3, 2]
        dtf[:, :, :3, 3] += joint.radii * dtf[:, :, :3, 2]
    for ax, shift in zip(joint.axes[3:], shifts):
        if shift is None:
            x = q[:, cidx[ax.coordinates[0]]]
            tf[:, :3, 3] += ax.function.value(x)[:, None] * ax.axis
            dtf[:, local[ax.coordinates[0]], :3, 3] += ax.function.derivative(x)[:, None] * ax.axis
        else:
            tf[:, :3, 3] += shift * ax.axis
    return tf, dtf


def _weld_residual(model: Model, tf: np.ndarray, dtf: np.ndarray) -> tuple:
    """Residuals (F, 6W) of the WeldConstraints and their Jacobian (F, 6W, C).

    Per weld: position error of frame 2 relative to frame 1 in ground (3) and the orientation
    error vee(skew(R1^T R2)) (3), both zero when the two frames coincide.
    """
    res, jac = [], []
    for w in model.welds:
        b1, b2 = model.body_index(w.body_1), model.body_index(w.body_2)
        g1 = tf[:, b1] @ w.tf_body1_frame
        g2 = tf[:, b2] @ w.tf_body2_frame
        dg1 = dtf[:, b1] @ w.tf_body1_frame
        dg2 = dtf[:, b2] @ w.tf_body2_frame
        res.append(g2[:, :3, 3] - g1[:, :3, 3])
        jac.append(np.swapaxes(dg2[..., :3, 3] - dg1[..., :3, 3], 1, 2))
        rel = np.swapaxes(g1[:, :3, :3], 1, 2) @ g2[:, :3, :3]
        drel = (np.swapaxes(dg1[..., :3, :3], -1, -2) @ g2[:, None, :3, :3]
                + np.swapaxes(g1[:, None, :3, :3], -1, -2) @ dg2[..., :3, :3])
        def vee(m):
            return 0.5 * np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0],
                                   m[..., 1, 0] - m[..., 0, 1]], axis=-1)
        res.append(vee(rel))
        jac.append(np.swapaxes(vee(drel), 1, 2))
    return np.concatenate(res, axis=1), np.concatenate(jac, axis=1)


def _assemble_welds(model: Model, q: np.ndarray, *, iterations: int = 50, tol: float = 1e-12) -> np.ndarray:
    """Coordinates that satisfy the WeldConstraints, as OpenSim's assembly finds them.

    OpenSim (Model::assemble, SimTK::Assembler) meets the constraints exactly; coordinates
    that are ``free_to_satisfy_constraints`` have no goal, the other unlocked, non-coupled
    ones stay as close as possible to their set values. Gauss-Newton, all frames at once:
    first on the free coordinates alone (minimum-norm steps ``-J^+ r``); if that cannot close
    the loops, on all unlocked coordinates with the minimum-change step
    ``dq = -e + J^+ (J e - r)`` (e = distance from the set values).
    """
    movable = ~model.coupled_coordinates & np.array([not c.locked for c in model.coordinates])
    free = movable & np.array([c.free_to_satisfy_constraints for c in model.coordinates])
    q_goal = np.array(q, dtype=float)
    for unknown in ([free] if free.any() else []) + [movable]:
        q_now = q_goal.copy()
        for _ in range(iterations):
            tf, dtf, _, _ = _poses(model, q_now, derivatives=True)
            r, jac = _weld_residual(model, tf, dtf)
            if np.max(np.abs(r)) < tol:
                return q_now
            jf = jac[:, :, unknown]
            e = (q_now - q_goal)[:, unknown]
            if unknown is free:
                e = np.zeros_like(e)
            rhs = np.einsum("frc,fc->fr", jf, e) - r
            q_now[:, unknown] += -e + np.einsum("fcr,fr->fc", np.linalg.pinv(jf, rcond=1e-10), rhs)
    raise InputError("the WeldConstraints cannot be satisfied (assembly did not converge)",
                     file=model.file, where="ConstraintSet",
                     fix="check the constraint frames and the motion's coordinate values")


def body_pose_derivatives(model: Model, motion, *, derivatives: bool = True) -> tuple:
    """Body transforms in ground and their derivatives w.r.t. every coordinate.

    Parameters
    ----------
    motion : Motion-like (``q`` (F, C), ``coordinate_names``) or (F, C) array in model order.
    derivatives : bool, keyword-only
        If False, ``d_tf_ground_body`` is None (faster).

    Returns
    -------
    tf_ground_body : (F, B, 4, 4) float
    d_tf_ground_body : (F, B, C, 4, 4) float or None
        d tf_ground_body / d q_k along the couplers (see `coordinate_values`).
    q_used : (F, C) float
    dq_dqk : (F, C, C) float
    """
    return _poses(model, _assembled_q(model, motion), derivatives=derivatives)


def _assembled_q(model: Model, motion) -> np.ndarray:
    """(F, C) coordinate values of a motion, weld constraints assembled."""
    _, q = motion_coordinates(model, motion)
    if model.welds:
        q = _assemble_welds(model, coordinate_values(model, q)[0])
    return q


def _pose_start(model: Model, q: np.ndarray):
    """q_used, dq_dqk, F, C, B, the coordinate index, and tf (F, B, 4, 4) with ground set."""
    q_used, jac = coordinate_values(model, q)
    n_frames, n_coords = q_used.shape
    n_bodies = len(model.bodies)
    tf = np.zeros((n_frames, n_bodies, 4, 4))
    tf[:, 0] = np.eye(4)
    return q_used, jac, n_frames, n_coords, n_bodies, model._coord_index, tf


def _joint_steps(model: Model, q_used, cidx, tf):
    """Walk the joints root to leaf, filling ``tf[:, child]`` (ground <- body) for each; yields
    ``(joint, parent index, child index, X_FM (F, 4, 4), dX_FM/dq, inv(X_BM), tf_ground_parent
    @ X_PF)`` for the caller's derivatives."""
    for joint in model.joints:
        p = model.body_index(joint.parent)
        b = model.body_index(joint.child)
        statics = _joint_statics(model, joint)
        tf_fm, dtf_fm = _joint_transform(joint, q_used, cidx, statics)
        left = tf[:, p] @ joint.tf_parent_jointframe           # (F, 4, 4) ground <- F
        tf[:, b] = left @ tf_fm @ statics[0]
        yield joint, p, b, tf_fm, dtf_fm, statics[0], left


def _poses(model: Model, q: np.ndarray, *, derivatives: bool) -> tuple:
    q_used, jac, n_frames, n_coords, n_bodies, cidx, tf = _pose_start(model, q)
    dtf = np.zeros((n_frames, n_bodies, n_coords, 4, 4)) if derivatives else None
    # columns k where d tf_ground_body / dq_k may be nonzero (the others stay exactly 0)
    support = np.zeros((n_bodies, n_coords), dtype=bool)
    for joint, p, b, tf_fm, dtf_fm, inv_child, left in _joint_steps(model, q_used, cidx, tf):
        if derivatives:
            # parent's motion carried along: d(parent) @ (X_PF X_FM X_MB)
            rest = joint.tf_parent_jointframe @ tf_fm @ inv_child           # (F, 4, 4)
            keep = np.flatnonzero(support[p])
            dtf[:, b, keep] = dtf[:, p, keep] @ rest[:, None]
            support[b] = support[p]
            if joint.coordinates:
                cols = [cidx[c] for c in joint.coordinates]
                ks = np.flatnonzero(np.any(jac[:, cols, :] != 0.0, axis=(0, 1)))
                support[b, ks] = True
                # total derivative: sum_c dX_FM/dq_c * dq_c/dq_k
                dfm_total = np.einsum("fcij,fck->fkij", dtf_fm, jac[:, cols][:, :, ks])
                dtf[:, b, ks] += left[:, None] @ dfm_total @ inv_child
    return tf, dtf, q_used, jac


def _pose_twists(model: Model, motion) -> tuple:
    """Body transforms and body twists (instead of `body_pose_derivatives`' (F, B, C, 4, 4)).

    The twist of body b about coordinate k is [omega, v] (ground frame) with
    ``d R_gb / dq_k = [omega]x R_gb`` and ``v = d t_gb / dq_k`` (total derivative along the
    couplers, as `body_pose_derivatives`). Root to leaf, with ``L = tf_ground_parent @ X_PF``:
    ``omega_b = omega_p + R_L vee(dR_FM R_FM^T)``, ``v_b = v_p + omega_p x (t_b - t_p)
    + R_L (dR_FM c + dt_FM)`` (c: translation of inv(X_BM)); (Featherstone, Rigid Body Dynamics
    Algorithms, 2008, ch. 4: velocity propagation along a kinematic tree).

    Returns
    -------
    tf_ground_body : (F, B, 4, 4) float
    twist : (F, B, C, 6) float
    q_used : (F, C) float
    dq_dqk : (F, C, C) float
    """
    q_used, jac, n_frames, n_coords, n_bodies, cidx, tf = _pose_start(model, _assembled_q(model, motion))
    twist = np.zeros((n_bodies, n_coords, n_frames, 6))       # (B, C, F, 6) while building
    support = np.zeros((n_bodies, n_coords), dtype=bool)      # columns that may be nonzero
    for joint, p, b, tf_fm, dtf_fm, inv_child, left in _joint_steps(model, q_used, cidx, tf):
        keep = np.flatnonzero(support[p])
        if len(keep):
            w = twist[p, keep, :, :3]                                              # (K, F, 3)
            d = tf[:, b, :3, 3] - tf[:, p, :3, 3]                                  # t_b - t_p
            twist[b, keep, :, :3] = w
            twist[b, keep, :, 3:] = twist[p, keep, :, 3:] + np.stack(
                [w[..., 1] * d[:, 2] - w[..., 2] * d[:, 1], w[..., 2] * d[:, 0] - w[..., 0] * d[:, 2],
                 w[..., 0] * d[:, 1] - w[..., 1] * d[:, 0]], axis=-1)              # omega x d
        support[b] = support[p]
        if joint.coordinates:
            cols = [cidx[c] for c in joint.coordinates]
            ks = np.flatnonzero(np.any(jac[:, cols, :] != 0.0, axis=(0, 1)))
            support[b, ks] = True
            dfm = np.einsum("fcij,fck->kfij", dtf_fm, jac[:, cols][:, :, ks])           # (K, F, 4, 4)
            w = dfm[..., :3, :3] @ np.swapaxes(tf_fm[:, :3, :3], -1, -2)
            w = 0.5 * np.stack([w[..., 2, 1] - w[..., 1, 2], w[..., 0, 2] - w[..., 2, 0],
                                w[..., 1, 0] - w[..., 0, 1]], axis=-1)                   # in F
            v = dfm[..., :3, :3] @ inv_child[:3, 3] + dfm[..., :3, 3]
            rot = left[:, :3, :3]
            twist[b, ks, :, :3] += (rot @ w[..., None])[..., 0]
            twist[b, ks, :, 3:] += (rot @ v[..., None])[..., 0]
    twist = np.moveaxis(twist, 2, 0)
    return tf, twist, q_used, jac


def body_poses(model: Model, motion) -> BodyPoses:
    """Transforms of every body in ground for every frame of ``motion``.

    Parameters
    ----------
    model : Model
    motion : Motion-like (``time`` (F,), ``q`` (F, C), ``coordinate_names``) or (F, C) array.

    Returns
    -------
    BodyPoses
        ``tf_ground_body`` (F, B, 4, 4), ``body_names`` (B,), ``time``, ``q`` used.
    """
    time, _ = motion_coordinates(model, motion)
    tf, _, q_used, _ = body_pose_derivatives(model, motion, derivatives=False)
    return BodyPoses(tf, model.body_names, time, q_used)
