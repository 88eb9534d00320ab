"""Reading .osim files: what OpenSim 4.6 reports about the same models (metadata.json)."""
from __future__ import annotations

import numpy as np
import pytest

from motion.osim.functions import LinearFunction, SimmSpline
from motion.osim.model import euler_xyz_matrix
from motion.osim.reader import load_model

from reference import CASES, ReferenceCase, case_id

MODELS = sorted({c for c in CASES}, key=lambda c: c[0])


@pytest.mark.parametrize("case", MODELS, ids=[case_id(c) for c in MODELS])
def test_model_matches_opensim_metadata(opensim_dir, case):
    rc = ReferenceCase(opensim_dir, *case)
    model = load_model(rc.model_file)
    meta = rc.metadata
    counts = meta["counts"]
    assert len(model.bodies) - 1 == counts["bodies"]          # OpenSim does not count the ground
    assert len(model.joints) == counts["joints"]
    assert len(model.paths) == counts["path_forces"]
    assert len(model.couplers) + len(model.welds) == counts["constraints"]
    # coordinate order, motion types, flags and defaults exactly as OpenSim 4.6 has them
    assert list(model.coordinate_names) == list(meta["coordinates"])
    for c in model.coordinates:
        ref = meta["coordinates"][c.name]
        assert c.motion_type == ref["motion_type"], c.name
        assert (c.locked, c.clamped) == (ref["locked"], ref["clamped"]), c.name
        assert c.default_value == ref["default"], c.name
        assert model.dependent_coordinates[model.coordinate_index(c.name)] == ref["dependent"]
    assert set(model.path_names) == set(meta["paths"])
    for p in model.paths:
        assert p.force_type == meta["paths"][p.name]["type"]
        assert [w.wrap_object for w in p.wraps] == [w[0] for w in meta["paths"][p.name]["wrap_objects"]]


def test_arm26_details(opensim_dir):
    model = load_model(opensim_dir / "Arm26" / "arm26.osim")
    assert model.version == 40000
    assert model.body_names == ("ground", "base", "r_humerus", "r_ulna_radius_hand")
    hum = model.bodies[model.body_index("r_humerus")]
    assert [g.mesh_file for g in hum.geometry] == ["arm_r_humerus.vtp"]
    tri = model.wrap_object("TRI")
    assert (tri.kind, tri.body, tri.quadrant, tri.radius, tri.length) == ("cylinder", "r_humerus", "all", 0.016, 0.05)
    hh = model.wrap_object("BIClonghh")
    assert hh.kind == "ellipsoid" and hh.quadrant == "-y"
    np.testing.assert_array_equal(hh.dimensions, [0.025, 0.02, 0.02])
    np.testing.assert_allclose(hh.tf_body_wrap[:3, :3], euler_xyz_matrix(hh.xyz_body_rotation))
    bic = model.path("BIClong")
    assert bic.wraps[0].range == (2, 3) and bic.wraps[0].method == "hybrid"
    elbow = model.joints[2]
    assert elbow.kind == "CustomJoint" and elbow.coordinates == ("r_elbow_flex",)
    # the file's axis (0.0494, 0.0366, 0.9981) is normalised, as SimTK's UnitVec3 does
    np.testing.assert_allclose(np.linalg.norm(elbow.axes[0].axis), 1.0, atol=1e-15)
    assert isinstance(elbow.axes[0].function, LinearFunction)


def test_gait2392_points_and_splines(opensim_dir):
    model = load_model(opensim_dir / "Gait2392_Simbody" / "gait2392_thelen2003muscle.osim")
    kinds = [p.kind for path in model.paths for p in path.points]
    # README: 26 ConditionalPathPoints and 8 MovingPathPoints
    assert kinds.count("conditional") == 26 and kinds.count("moving") == 8
    knee = next(j for j in model.joints if j.name == "knee_r")
    assert isinstance(knee.axes[3].function, SimmSpline)
    assert model.coordinates[model.coordinate_index("knee_angle_r")].motion_type == "rotational"


def test_lhdl_3x_model(lhdl_dir):
    model = load_model(lhdl_dir / "model" / "LHDL_hip_r.osim")     # Version 30000, Latin-1 bytes
    assert model.version == 30000
    assert model.bodies[0].name == "ground"
    assert len(model.coordinates) == 9 and len(model.paths) == 8
    assert all(len(p.points) >= 2 for p in model.paths)


def test_3x_joint_frames_are_rounded_like_opensim(opensim_dir):
    # OpenSim 4.6 converts a 3.x/2.x joint's orientation through a 6-digit text stream:
    # -1.5707963267948966 in the file becomes -1.5708 (checked with OpenSim itself)
    model = load_model(opensim_dir / "MomentArmTests" / "P2PBallJointMomentArmTest.osim")
    ball = next(j for j in model.joints if j.kind == "BallJoint")
    np.testing.assert_allclose(ball.tf_parent_jointframe[:3, :3], euler_xyz_matrix([0.0, -1.5708, 0.0]), atol=1e-15)


def test_model_is_frozen(opensim_dir):
    model = load_model(opensim_dir / "Arm26" / "arm26.osim")
    with pytest.raises(Exception):
        model.name = "x"
    with pytest.raises(ValueError):
        model.joints[1].tf_parent_jointframe[0, 0] = 2.0
    assert model.coordinate_index("r_elbow_flex") == 1
    with pytest.raises(KeyError):
        model.coordinate_index("nope")


def test_muscle_parameters_of_a_latin1_file_declared_utf8(tmp_path):
    """The LHDL hip model declares UTF-8 but holds a Latin-1 byte ("Universit\xe9"): the model
    loaded, but `muscle_parameters` parsed the file strictly, got nothing, and every LHDL
    normalized_length was NaN (no l_opt) without a word."""
    from pathlib import Path

    from motion.osim.muscle_parameters import muscle_parameters

    src = Path(__file__).resolve().parents[2] / "models" / "arm_example.osim"
    data = src.read_bytes()
    assert data.lstrip().startswith(b"<?xml") and b"UTF-8" in data.split(b"?>", 1)[0]
    head, rest = data.split(b"?>", 1)
    latin1 = tmp_path / "arm_latin1.osim"
    latin1.write_bytes(head + b"?>\n<!-- Universit\xe9 Libre de Bruxelles -->" + rest)
    model, reference = load_model(latin1), load_model(src)
    got, expected = muscle_parameters(model, "BIClong"), muscle_parameters(reference, "BIClong")
    assert expected.optimal_fiber_length == pytest.approx(0.254)     # models/arm_example.osim
    assert got == expected
