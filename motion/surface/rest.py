"""The rest pose of a muscle surface: from the mesh's own frame to ground, as body transforms.

A rest pose is a set of body transforms ``tf_ground_body`` (B, 4, 4) plus the coordinates
``q`` (C,) at which the action lines are evaluated, and the transform ``tf_ground_data`` that
takes the mesh/landmark coordinates to ground:

- ``frame = "ground"``: ``q`` = model defaults overridden by ``rest_pose``;
  ``tf_ground_body = body_poses(q)``; ``tf_ground_data = I``.
- ``frame = "<body>"``: as above, and ``tf_ground_data`` = that body's pose at ``q``.
- ``frame = "bodies"`` (NMSBuilder/LHDL): the data frame S is every body's frame. Such a pose
  need not be the model's default pose -- in the LHDL hip model it is not: at the default
  coordinates the pelvis frame is turned by the ground-pelvis joint's child orientation and the
  femur frame differs from the pelvis frame by about 18 degrees, because the hip joint's parent
  and child orientations differ. ``q`` is therefore solved (Levenberg-Marquardt on the
  independent coordinates, from the defaults/``rest_pose``) so that every body frame coincides
  with the first non-ground body's frame; ``tf_ground_data`` is that body's pose and every
  ``tf_ground_body`` is set to it exactly (so landmarks ride their bodies exactly), and the
  residual of the solve (rotation in rad + translation in m) is kept for reporting. More than
  1 mm / 1 mrad raises `InputError`: the model cannot reach a pose where all frames coincide.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["RestPose", "rest_pose", "rest_coordinates"]

#: Largest residual (rad + m) accepted for ``frame = "bodies"``.
BODIES_TOLERANCE = 1e-3


@dataclass(frozen=True, eq=False)
class RestPose:
    """A muscle's rest pose.

    Attributes
    ----------
    q : (C,) float
        Coordinates at which the rest action lines are evaluated.
    tf_ground_body : (B, 4, 4) float
        Rest pose of every body used to bind attachments and bones.
    tf_ground_data : (4, 4) float
        Mesh/landmark frame in ground.
    residual : float
        For ``frame = "bodies"``: how far the solved pose is from all frames coinciding.
    """

    q: np.ndarray
    tf_ground_body: np.ndarray
    tf_ground_data: np.ndarray
    residual: float = 0.0

    def __post_init__(self):
        for key in ("q", "tf_ground_body", "tf_ground_data"):
            arr = np.array(getattr(self, key), dtype=float, copy=True)
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)


def rest_coordinates(model, rest: dict, *, muscle: str = "?") -> np.ndarray:
    """(C,) default coordinate values overridden by ``rest`` (name -> SI value)."""
    q = np.array([c.default_value for c in model.coordinates], dtype=float)
    names = list(model.coordinate_names)
    for key, value in dict(rest).items():
        if key not in names:
            raise InputError(f"rest_pose names {key!r}, which is not a coordinate of the model",
                             file=getattr(model, "file", None), where=f"muscle {muscle!r}: rest_pose.{key}",
                             fix=f"use one of the model's coordinates: {', '.join(names[:12])}"
                                 + (" ..." if len(names) > 12 else ""))
        q[names.index(key)] = float(value)
    return q


def _poses(model, q: np.ndarray) -> np.ndarray:
    from ..osim.kinematics import body_poses, motion_from_array

    return np.asarray(body_poses(model, motion_from_array(model, np.atleast_2d(q))).tf_ground_body)


def _frames_mismatch(tf: np.ndarray) -> np.ndarray:
    """Residual of every body's frame against the first non-ground body's frame, (..., 12 (B-2))."""
    ref = tf[..., 1:2, :, :]
    rel = np.linalg.inv(ref) @ tf[..., 2:, :, :]
    rot = (rel[..., :3, :3] - np.eye(3)).reshape(rel.shape[:-2] + (9,))
    trans = rel[..., :3, 3]
    return np.concatenate([rot, trans], axis=-1).reshape(tf.shape[:-3] + (-1,))


def _solve_bodies_pose(model, q0: np.ndarray, muscle: str):
    from scipy.optimize import least_squares

    free = np.asarray(model.independent_coordinates, dtype=bool)
    if len(model.bodies) <= 2 or not free.any():
        tf = _poses(model, q0)[0]
        return q0, tf, float(np.abs(_frames_mismatch(tf)).max(initial=0.0))

    def residual(x):
        q = q0.copy()
        q[free] = x
        # a tiny pull towards the start pins the coordinates that do not change relative frames
        # (e.g. the pelvis's six ground coordinates) instead of letting them drift
        return np.concatenate([_frames_mismatch(_poses(model, q)[0]), 1e-6 * (x - q0[free])])

    sol = least_squares(residual, q0[free], method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    q = q0.copy()
    q[free] = sol.x
    tf = _poses(model, q)[0]
    res = float(np.abs(_frames_mismatch(tf)).max(initial=0.0))
    if res > BODIES_TOLERANCE:
        raise InputError(f"frame = \"bodies\" needs a pose in which every body frame coincides, but the closest "
                         f"pose the model reaches is {res:.3g} (rad + m) away",
                         file=getattr(model, "file", None), where=f"muscle {muscle!r}: frame",
                         fix="give the mesh in ground with frame = \"ground\" and its rest_pose, "
                             "or in one body's frame")
    return q, tf, res


def rest_pose(model, spec) -> RestPose:
    """The rest pose of ``spec`` (a `motion.surface.spec.MuscleSurfaceSpec`) on ``model``."""
    q = rest_coordinates(model, spec.rest_pose, muscle=spec.name)
    frame = spec.frame
    if frame == "bodies":
        q, tf, res = _solve_bodies_pose(model, q, spec.name)
        ref = tf[1] if len(tf) > 1 else tf[0]
        tf_all = np.broadcast_to(ref, tf.shape).copy()
        tf_all[0] = np.eye(4)  # ground stays ground; nothing rides on it in a scanner export
        return RestPose(q, tf_all, ref, res)
    tf = _poses(model, q)[0]
    if frame == "ground":
        return RestPose(q, tf, np.eye(4))
    names = list(model.body_names)
    if frame not in names:
        raise InputError(f"frame {frame!r} is not a body of the model",
                         file=getattr(model, "file", None), where=f"muscle {spec.name!r}: frame",
                         fix=f"use \"ground\", \"bodies\" or one of: {', '.join(names)}")
    return RestPose(q, tf, tf[names.index(frame)])
