"""OpenSim's ``computeMomentArm`` convention, where it differs from r = -dL/dq.

`motion.wrapping.action_lines` returns r = -dL/dq (the project's contract, INTERFACE.md). OpenSim's
``Muscle::computeMomentArm`` (MomentArmSolver) instead returns the generalized force of a unit
path tension in the mobilizer's *generalized speeds* u. For most joints u = qdot and the two
agree. They differ in three places:

1. BallJoint, FreeJoint and EllipsoidJoint rotations: SimTK's Ball/Free/Ellipsoid mobilizers use the
   angular velocity of M in F, expressed in F, as u; with ``w = E(q) qdot`` (E's columns are
   the rotation axes carried by the preceding rotations, ``[a1, R1 a2, R1 R2 a3]``) the
   generalized force is ``E(q)^-T (-dL/dq)``. `opensim_moment_arms` reproduces this exactly
   (to 1e-16 on the P2PBallJoint reference and on a live OpenSim EllipsoidJoint). GimbalJoint
   and CustomJoint use u = qdot.
2. Wrapped paths: OpenSim's MomentArmSolver treats the wrap tangent points as fixed in the
   wrap object's body for the instant (0.05-4 mm off -dL/dq on Arm26). That is an
   approximation of -dL/dq, not another convention; it is not imitated here. Over wrap objects
   in series OpenSim's length keeps the first wrapping pass' tangent points
   (``ActionLines.drawn_lengths``), and there the two differ by more (Rajagopal 2023's
   gastrocnemii at the knee: -dL/dq 5.7 against computeMomentArm 22.6 mm).
3. Dependent coordinates of couplers: OpenSim's value is the projection of the unit-tension
   force onto a constrained mobility and is not a derivative of the length (the references
   show 1e4 or NaN); not imitated.
"""
from __future__ import annotations

import numpy as np

from .action_lines import ActionLines
from ..osim.kinematics import _axis_angle_matrices
from ..osim.model import Model

__all__ = ["opensim_moment_arms", "EULER_SPEED_JOINTS"]

EULER_SPEED_JOINTS = ("BallJoint", "FreeJoint", "EllipsoidJoint")


def _euler_rate_matrix(joint, q: np.ndarray, cidx: dict) -> np.ndarray:
    """E (F, 3, 3): angular velocity of M in F (in F) = E @ (rates of the three rotation coordinates)."""
    n_frames = q.shape[0]
    cols = []
    carried = np.broadcast_to(np.eye(3), (n_frames, 3, 3))
    for ax in joint.axes[:3]:
        cols.append(carried @ ax.axis)
        angle = q[:, cidx[ax.coordinates[0]]] if ax.coordinates else np.full(n_frames, float(ax.function.value(0.0)))
        carried = carried @ _axis_angle_matrices(ax.axis, angle)[0]
    return np.stack(cols, axis=-1)


def opensim_moment_arms(model: Model, lines: ActionLines) -> np.ndarray:
    """Moment arms as OpenSim's ``computeMomentArm`` reports them for independent coordinates.

    Parameters
    ----------
    model : Model
    lines : ActionLines
        From `motion.wrapping.action_lines` (its ``q`` are the coordinates used).

    Returns
    -------
    (F, M, C) float
        ``lines.moment_arms`` with the rotational coordinates of Ball, Free and Ellipsoid joints
        mapped to OpenSim's angular-velocity mobilities (see the module docstring); NaN at
        an Euler-angle singularity (middle angle +-pi/2).
    """
    out = np.array(lines.moment_arms, dtype=float, copy=True)
    cidx = model._coord_index
    for joint in model.joints:
        if joint.kind not in EULER_SPEED_JOINTS:
            continue
        rot_coords = [ax.coordinates[0] for ax in joint.axes[:3]]
        cols = [lines.coordinate_names.index(c) for c in rot_coords]
        e = _euler_rate_matrix(joint, lines.q, cidx)                         # (F, 3, 3)
        with np.errstate(all="ignore"):
            singular = np.abs(np.linalg.det(e)) < 1e-12
            inv_t = np.swapaxes(np.linalg.inv(np.where(singular[:, None, None], np.eye(3), e)), 1, 2)
        mapped = np.einsum("fij,fmj->fmi", inv_t, out[:, :, cols])
        mapped[singular] = np.nan
        out[:, :, cols] = np.where(lines.spanned[None][:, :, cols], mapped, 0.0)
    return out
