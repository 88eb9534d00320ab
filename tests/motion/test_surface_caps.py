"""`motion.surface.caps`: which bone a belly's cap lies over, the tilt of the end frames, and the
derived bone's depth between a generated belly's rings (`motion.surface.thickness`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from motion.osim.builder import ModelBuilder
from motion.osim.kinematics import body_poses, motion_from_array
from motion.osim.reader import load_model
from motion.surface.caps import TILT_LINEAR, TILT_MAX, cap_bodies, saturated_tilt, tilt_frames
from motion.surface.curves import rotation_minimizing_frames
from motion.surface.thickness import local_half_thickness

GAIT2392 = Path(__file__).resolve().parents[2].parent / "shared" / "opensim" / "Gait2392_Simbody" / \
    "gait2392_thelen2003muscle.osim"


def knee_model(tmp_path, top, slack):
    """Thigh (fixed) and shank on a pin at the origin; a straight path from y = ``top`` (thigh) to
    y = -0.3 (shank), 0.07 m behind the knee: the knee projects onto the path at arc ``top``."""
    mb = (ModelBuilder("knee").add_body("thigh").add_weld_joint("fix", "ground", "thigh")
          .add_body("shank").add_pin_joint("knee", "thigh", "shank", "q", range=(-3.0, 3.0)))
    mb.add_muscle("m", [("thigh", (-0.07, top, 0.0)), ("shank", (-0.07, -0.3, 0.0))],
                  optimal_fiber_length=0.1, tendon_slack_length=slack, max_isometric_force=500.0)
    model = load_model(mb.write(tmp_path / "knee.osim"))
    tf = np.asarray(body_poses(model, motion_from_array(model, np.zeros((1, 1)))).tf_ground_body)[0]
    line = np.array([[-0.07, top, 0.0], [-0.07, -0.3, 0.0]])
    return model, tf, line


# belly span [l_ts / 2, L - l_ts / 2] with L = top + 0.3; the knee projects at arc ``top``
@pytest.mark.parametrize("top, slack, expect", [(0.25, 0.3, ("thigh", "shank")),   # caps at 0.15, 0.40
                                                (0.6, 0.7, ("thigh", "thigh")),    # caps at 0.35, 0.55
                                                (0.1, 0.1, ("thigh", "shank")),    # caps at 0.05, 0.35
                                                (0.1, 0.3, ("shank", "shank"))])   # caps at 0.15, 0.25
def test_caps_lie_over_the_body_on_their_side_of_the_joint(tmp_path, top, slack, expect):
    model, tf, line = knee_model(tmp_path, top, slack)
    assert tuple(model.bodies[b].name for b in cap_bodies(model, "m", line, tf, slack)) == expect


@pytest.mark.skipif(not GAIT2392.exists(), reason="Gait2392 model not available")
def test_gait2392_caps():
    """Anatomy: a gastrocnemius' belly lies over the tibia (its tendons cross the knee above and
    the ankle below), a rectus femoris' and a semimembranosus' over the femur, an iliacus' across
    the hip (origin on the pelvis, insertion cap on the femur)."""
    from motion.osim.muscle_parameters import muscle_parameters
    from motion.surface.current_lines import current_polylines

    model = load_model(GAIT2392)
    rest = motion_from_array(model, np.array([[c.default_value for c in model.coordinates]]))
    tf = np.asarray(body_poses(model, rest).tf_ground_body)
    want = {"med_gas_r": ("tibia_r", "tibia_r"), "rect_fem_r": ("femur_r", "femur_r"),
            "semimem_r": ("femur_r", "femur_r"), "iliacus_r": ("pelvis", "femur_r")}
    lines = current_polylines(model, rest, list(want), None, tf)
    for name, bodies in want.items():
        c = lines[name][0][0]
        slack = muscle_parameters(model, name).tendon_slack_length
        got = cap_bodies(model, name, c[np.isfinite(c).all(axis=1)], tf[0], slack)
        assert tuple(model.bodies[b].name for b in got) == bodies, name


def test_tilt_puts_the_end_tangent_on_the_target_and_keeps_frames_orthonormal():
    rng = np.random.default_rng(3)
    curve = np.cumsum(rng.normal(size=(4, 12, 3)) * 0.01 + [0.0, 0.0, 0.02], axis=1)
    frames = rotation_minimizing_frames(curve, np.tile([1.0, 0.0, 0.0], (4, 1)))
    target = frames[:, 0, :, 2] + 0.1 * rng.normal(size=(4, 3))
    target /= np.linalg.norm(target, axis=1, keepdims=True)
    angle = np.arccos(np.sum(frames[:, 0, :, 2] * target, axis=1))
    assert angle.max() < TILT_LINEAR                         # the linear range: exactly on target
    weight = np.linspace(1.0, 0.0, 12)
    out = tilt_frames(frames, target, weight)
    np.testing.assert_allclose(out[:, 0, :, 2], target, atol=1e-12)
    np.testing.assert_allclose(out[:, -1], frames[:, -1], atol=1e-12)       # weight 0: unchanged
    eye = np.einsum("fnji,fnjk->fnik", out, out)
    np.testing.assert_allclose(eye, np.broadcast_to(np.eye(3), eye.shape), atol=1e-12)


def test_saturated_tilt_is_c1_and_bounded():
    a = np.linspace(0.0, 3.0, 30001)
    f = saturated_tilt(a)
    np.testing.assert_array_equal(f[a <= TILT_LINEAR], a[a <= TILT_LINEAR])
    assert f.max() < TILT_MAX and np.all(np.diff(f) > 0)
    slope = np.diff(f) / np.diff(a)
    assert np.abs(np.diff(slope)).max() < 1e-3                 # no kink (C1) at TILT_LINEAR


def test_half_thickness_between_the_rings_of_a_coarse_surface():
    """A tube of radius 10 mm with 11 rings along 0.2 m, its line sampled at 201 stations (1 mm):
    points on the tube between two rings have the tube's half-thickness, not 0."""
    from meshes import capped_tube

    verts, _ = capped_tube(np.zeros(3), np.array([0.0, 0.0, 0.2]), 0.01, n_around=16, n_rings=11)
    probe = np.array([[0.0095, 0.0, z] for z in np.linspace(0.013, 0.187, 30)])     # between rings
    h = local_half_thickness(np.vstack([verts, probe]), len(verts), [np.array([[0, 0, 0], [0, 0, 0.2]])],
                             n_samples=201)
    np.testing.assert_allclose(h[len(verts):], 0.01, rtol=1e-6)


@pytest.mark.parametrize("share", [0.0, 0.25, 0.5, 1.0])
def test_belly_span_puts_its_share_of_the_tendon_at_the_origin(share):
    """`belly_span`: the belly is L - l_ts long (or the floor's length) and starts share x
    (L - belly) along the path; at 1/2 it is the centred rule, in the same arithmetic."""
    from motion.osim.muscle_parameters import BELLY_MIN_FRACTION, belly_span

    length = np.array([0.30, 0.25, 0.205, 0.18])           # l_ts 0.2: long, long, on the floor, short
    start, stop, short = belly_span(length, 0.2, share)
    belly = stop - start
    np.testing.assert_allclose(belly[:2], length[:2] - 0.2, rtol=1e-12)
    assert (belly[2:] >= BELLY_MIN_FRACTION * length[2:] - 1e-15).all()
    np.testing.assert_allclose(start, share * (length - belly), rtol=1e-12, atol=1e-15)
    assert list(short) == [False, False, True, True]
    if share == 0.5:
        t = 0.5 * (length - belly)
        assert (start == t).all() and (stop == length - t).all()
