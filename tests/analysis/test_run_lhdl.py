"""`analysis.run` on the LHDL hip (tests/data/lhdl_hip.toml, data in ../shared): fibre moment
arms are smooth derivatives (h = 1e-4 rad agrees with a 2-degree difference quotient), fibre
ends ride their bones, and the fibre band brackets plausible values around the action line."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from analysis.run import run
from analysis.spec import load_spec

TOML = Path(__file__).resolve().parents[1] / "data" / "lhdl_hip.toml"


@pytest.fixture(scope="module")
def sweep(lhdl_dir):
    """iliacus and psoas over a 1-degree hip-flexion sweep 10..30 degrees (other coordinates 0)."""
    from motion import Motion

    spec = load_spec(TOML)
    q = np.deg2rad(np.arange(10.0, 31.0, 1.0))
    mot = Motion.from_array(spec.model, np.arange(len(q)) * 0.01, {"hip_flexion_r": q})
    return run(spec, mot, muscles=["iliacus_r", "psoas_r"], fibres=60)


@pytest.mark.parametrize("muscle", ["iliacus_r", "psoas_r"])
def test_fd_moment_arms_agree_with_a_2_degree_quotient(sweep, muscle):
    m = sweep.muscle(muscle)
    k = m.coordinates.index("hip_flexion_r")
    L = m.fibre_lengths
    r_quot = -(L[2:] - L[:-2]) / np.deg2rad(2.0)         # central quotient over 2 degrees
    r_fd = m.fibre_moment_arms[1:-1, :, k]                # h = 1e-4 rad, the whole chain
    # 5 %: a 2-degree quotient differs from the derivative by (1 deg)^2 / 6 * r'' / r, well
    # under 1 % for a smooth chain; a jump (a flip of a discrete choice) would be far larger
    ok = np.abs(r_fd - r_quot) <= 0.05 * np.abs(r_quot)
    assert ok.mean() >= 0.95, f"{muscle}: only {ok.mean():.1%} of fibre-frames agree"


def test_fibre_ends_ride_their_bones_and_moment_arms_are_plausible(sweep):
    from motion.osim.kinematics import body_poses

    m = sweep.muscle("iliacus_r")
    assert set(m.coordinates) == {"hip_flexion_r", "hip_adduction_r", "hip_rotation_r"}
    # in the frame of the femur the insertion ends do not move (rigid attachment zone)
    from motion import Motion

    model = load_spec(TOML).model
    poses = body_poses(model, Motion.from_array(model, sweep.time, sweep.q))
    tf = np.asarray(poses.tf_ground_body)[:, model.body_index("femur_r")]
    inv = np.linalg.inv(tf)
    ends = m.fibre_points[:, :, -1]
    local = np.einsum("fij,fnj->fni", inv[:, :3, :3], ends) + inv[:, None, :3, 3]
    assert np.abs(local - local[0]).max() < 1e-9
    # iliacus flexion moment arm, Modenese & Kohout 2020 Table 2: 1.3-4.6 cm over the fibres;
    # the fibre median lies within 1 cm of the action line's
    r = m.fibre_moment_arms[:, :, m.coordinates.index("hip_flexion_r")]
    assert (np.median(r, axis=1) > 0.01).all() and (np.median(r, axis=1) < 0.05).all()
    line = m.action_line_moment_arms[:, 0, m.coordinates.index("hip_flexion_r")]
    assert np.abs(np.median(r, axis=1) - line).max() < 0.01


def test_moment_arms_do_not_depend_on_the_step(sweep):
    """h = 1e-4 rad (default) vs 1e-5 rad: truncation error ~h^2 L'''/6 and round-off
    ~eps L / h are both far below 1 micrometre, so the two must agree to 1e-6 m."""
    from motion import Motion

    spec = load_spec(TOML)
    mot = Motion.from_array(spec.model, sweep.time, sweep.q)
    fine = run(spec, mot, muscles=["iliacus_r"], fibres=60, step={"rotational": 1e-5})
    np.testing.assert_allclose(fine.muscle("iliacus_r").fibre_moment_arms,
                               sweep.muscle("iliacus_r").fibre_moment_arms, atol=1e-6)


def test_psoas_with_the_iliacus_area_origin_notes_its_dead_end(sweep):
    """The TOML gives the psoas the iliacus-area origin (Modenese & Kohout 2020): a patch on its
    side, with its lumbar part beyond (fibres.slicing.harmonic_sections.dead_end_levels). The run
    notes the dead end and the empty volume it leaves; its fibres do not turn back into it
    (141 degrees before the dead end was bounded)."""
    m = sweep.muscle("psoas_r")
    assert any("lies beyond the origin patch" in n for n in m.notes)
    assert any("fibre quality below the usual limits" in n and "volume" in n for n in m.notes)
    p = m.fibre_points[0]
    seg = np.diff(p, axis=1)
    cos = np.einsum("npk,npk->np", seg[:, 1:], seg[:, :-1]) / (
        np.linalg.norm(seg[:, 1:], axis=2) * np.linalg.norm(seg[:, :-1], axis=2))
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 45.0
