"""Forward kinematics: OpenSim 4.6 body transforms, assembly rules, exact derivatives."""
from __future__ import annotations

import numpy as np
import pytest

from motion.osim.kinematics import body_pose_derivatives, body_poses, coordinate_values, motion_from_array
from motion.osim.reader import load_model

from reference import CASES, ReferenceCase, case_id


@pytest.mark.parametrize("case", CASES, ids=[case_id(c) for c in CASES])
def test_body_transforms_match_opensim(opensim_dir, case):
    rc = ReferenceCase(opensim_dir, *case)
    model = load_model(rc.model_file)
    q = rc.q_used(model)
    poses = body_poses(model, motion_from_array(model, q, rc.time))
    ref = rc.body_transforms(model)
    # acceptance: body origins within 1e-9 m, rotation matrix entries within 1e-9
    # (the CoupledCoordinates model's reference is itself assembled to ~1e-11 only)
    assert np.abs(poses.tf_ground_body[..., :3, 3] - ref[..., :3, 3]).max() < 1e-9
    assert np.abs(poses.tf_ground_body[..., :3, :3] - ref[..., :3, :3]).max() < 1e-9
    assert poses.body_names == model.body_names
    np.testing.assert_array_equal(poses.time, rc.time)


# testMomentArmsConstraintA/B are left out: where knee_angle_r sits 5e-10 inside its clamped range
# OpenSim's assembler moves it by 1e-5 / 3e-5 (its tolerance at a bound; metadata.json
# "max_abs_change_by_assembly"), while we keep the motion's value, which satisfies every constraint.
@pytest.mark.parametrize("case", [c for c in CASES if "Constraint" not in c[0]],
                         ids=[case_id(c) for c in CASES if "Constraint" not in c[0]])
def test_assembly_from_motion_values(opensim_dir, case):
    """Posing from the motion's own values (missing -> default) reproduces OpenSim's assembly:
    couplers, locks, the WeldConstraint loop of CoupledCoordinatesMPPs (foot_x, foot_y free)."""
    rc = ReferenceCase(opensim_dir, *case)
    model = load_model(rc.model_file)
    tab = rc.coordinates.pivot(index="frame", columns="coordinate", values="motion_value")
    q = tab[list(model.coordinate_names)].to_numpy(dtype=float).copy()
    defaults = np.array([c.default_value for c in model.coordinates])
    q = np.where(np.isnan(q), defaults, q)
    poses = body_poses(model, q)
    # OpenSim's assembler satisfies constraints to its own tolerance (~1e-11 for the weld loop,
    # 1.5e-9 for the PathOnConstrainedBody spline couplers); ours solves them to rounding
    np.testing.assert_allclose(poses.q, rc.q_used(model), rtol=0, atol=5e-9)


def test_derivatives_match_finite_differences(opensim_dir):
    model = load_model(opensim_dir / "MomentArmTests" / "testMomentArmsConstraintA.osim")
    rng = np.random.default_rng(3)
    q = np.array([c.default_value for c in model.coordinates]) + rng.uniform(-0.3, 0.3, (4, len(model.coordinates)))
    # stay inside the ranges: clamped coordinates do not move outside them (derivative 0 there)
    lo, hi = np.array([c.range for c in model.coordinates]).T
    q = np.clip(q, lo + 2e-6, hi - 2e-6)
    tf, dtf, _, _ = body_pose_derivatives(model, q)
    h = 1e-6
    for k in np.flatnonzero(model.independent_coordinates)[::3]:
        qp, qm = q.copy(), q.copy()
        qp[:, k] += h
        qm[:, k] -= h
        fd = (body_pose_derivatives(model, qp, derivatives=False)[0]
              - body_pose_derivatives(model, qm, derivatives=False)[0]) / (2 * h)
        # central differences: O(h^2) ~ 1e-12 truncation + 1e-16/h rounding ~ 1e-10
        np.testing.assert_allclose(dtf[:, :, k], fd, rtol=0, atol=2e-9, err_msg=model.coordinate_names[k])


def test_couplers_locks_and_clamps():
    from motion.osim.functions import LinearFunction
    from motion.osim.model import Body, Coordinate, CouplerConstraint, Joint, Model
    from motion.osim.joints import joint_axes

    class _Node:  # joint_axes only needs .error for bad input
        def error(self, *a, **k):
            raise AssertionError(a)

    eye = np.eye(4)
    joints = [Joint("j1", "PinJoint", "ground", "a", eye, eye, ("q1",), joint_axes("PinJoint", ("q1",), _Node())),
              Joint("j2", "PinJoint", "a", "b", eye, eye, ("q2",), joint_axes("PinJoint", ("q2",), _Node())),
              Joint("j3", "SliderJoint", "b", "c", eye, eye, ("q3",), joint_axes("SliderJoint", ("q3",), _Node()))]
    coords = [Coordinate("q1", "rotational", 0.0, [-0.5, 0.5], True, False, "j1"),
              Coordinate("q2", "rotational", 0.0, [-9, 9], False, False, "j2"),
              Coordinate("q3", "translational", 0.25, [-1, 1], False, True, "j3")]
    model = Model("t", "t.osim", 40000, [Body("ground"), Body("a"), Body("b"), Body("c")], joints, coords,
                  couplers=[CouplerConstraint("c", ("q1",), "q2", LinearFunction(2.0, 0.1), 3.0)])
    q_used, jac = coordinate_values(model, np.array([[0.9, 7.0, -0.4]]))
    # q1 clamped to its range (model has a constraint), q2 = 3 (2 q1 + 0.1), q3 locked at 0.25
    np.testing.assert_allclose(q_used, [[0.5, 3.0 * 1.1, 0.25]])
    # dq2/dq1 = 3 * 2; partial of the dependent is its own unit vector
    np.testing.assert_allclose(jac[0], [[1, 0, 0], [6, 1, 0], [0, 0, 1]])
    tf = body_poses(model, q_used).tf_ground_body[0]
    angle = 0.5 + 3.3                    # two pins about z in series
    np.testing.assert_allclose(tf[2, :2, :2], [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]],
                               atol=1e-15)
    np.testing.assert_allclose(tf[3, :3, 3], tf[2, :3, :3] @ [0.25, 0, 0], atol=1e-15)


def test_motion_columns_are_matched_by_name(opensim_dir):
    model = load_model(opensim_dir / "Arm26" / "arm26.osim")

    class Mot:
        time = np.array([0.0, 0.1])
        q = np.array([[0.3, 0.1], [0.4, 0.2]])          # elbow first, shoulder second
        coordinate_names = ("r_elbow_flex", "r_shoulder_elev")

    a = body_poses(model, Mot()).tf_ground_body
    b = body_poses(model, np.array([[0.1, 0.3], [0.2, 0.4]])).tf_ground_body
    np.testing.assert_array_equal(a, b)

