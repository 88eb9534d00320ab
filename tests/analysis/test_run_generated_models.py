"""Generated (meshless, tendon-aware) muscles of real OpenSim models against their action lines
(issue 12); the whole models are measured by ``bench/generated_moment_arms.py``.

- Gait2392 walking, the four right quadriceps (the rectus femoris and vasti insert on patellar
  MovingPathPoints): in every frame where the line's moment arm exceeds 5 mm, the median fibre
  moment arm is the action line's (exact, `motion.wrapping.action_lines`) within max(5 %, 1 mm);
- Arm26 elbow flexion sweep, biceps and brachialis: the same;
- both: the median fibre length is the rigid-tendon belly length L_path - tendon_slack_length
  within 5 % in every frame (parallel template), and normalized_length = l / optimal_fiber_length;
- a path shorter than its tendon slack length: a warning note, and the belly stays positive.
"""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("motion.surface.tendons", reason="issue 12 not in this checkout")

from analysis.run import run  # noqa: E402

OPENSIM = Path(__file__).resolve().parents[2].parent / "shared" / "opensim"
GAIT = (OPENSIM / "Gait2392_Simbody" / "gait2392_thelen2003muscle.osim",
        OPENSIM / "Gait2392_Simbody" / "subject01_walk1_ik.mot")
ARM = (OPENSIM / "Arm26" / "arm26.osim", OPENSIM / "Arm26" / "arm26_elbow_flexion_sweep.mot")

pytestmark = pytest.mark.shared


def _toml(tmp_path, model, motion, muscles, fibres=24, resolution=12):
    body = [f'model = "{model}"', f'motion = "{motion}"', "[defaults]", 'template = "parallel"',
            f"fibres = {fibres}", f"resolution = {resolution}"]
    for name in muscles:
        body += [f"[muscles.{name}]", f'action_lines = ["{name}"]']
    path = tmp_path / "generated.toml"
    path.write_text("\n".join(body) + "\n")
    return path


def _check(res, model):
    from motion.osim.muscle_parameters import muscle_parameters

    for m in res.muscles:
        p = muscle_parameters(model, m.name)
        r_line = m.action_line_moment_arms[:, 0]
        med = np.median(m.fibre_moment_arms, axis=1)
        sel = np.abs(r_line) > 5e-3
        excess = np.abs(med - r_line) - np.maximum(0.05 * np.abs(r_line), 1e-3)
        assert sel.any()
        assert excess[sel].max() <= 0, (m.name, 1e3 * excess[sel].max())
        belly = m.action_line_lengths[:, 0] - p.tendon_slack_length
        np.testing.assert_allclose(np.median(m.fibre_lengths, axis=1), belly, rtol=0.05, err_msg=m.name)
        np.testing.assert_allclose(m.normalized_lengths, m.fibre_lengths / p.optimal_fiber_length, rtol=1e-12)


@pytest.mark.slow
def test_gait2392_quadriceps_on_patellar_moving_points(tmp_path):
    if not GAIT[0].is_file():
        pytest.skip("needs ../shared/opensim/Gait2392_Simbody")
    from motion import load_model

    muscles = ["rect_fem_r", "vas_med_r", "vas_int_r", "vas_lat_r"]
    res = run(_toml(tmp_path, *GAIT, muscles), frames="0:211:15")
    assert all(m.coordinates for m in res.muscles)
    _check(res, load_model(GAIT[0]))


def test_arm26_elbow_flexors(tmp_path):
    if not ARM[0].is_file():
        pytest.skip("needs ../shared/opensim/Arm26")
    from motion import load_model

    res = run(_toml(tmp_path, *ARM, ["BIClong", "BICshort", "BRA"]), frames="0:101:4")
    _check(res, load_model(ARM[0]))


def test_path_shorter_than_its_tendon_slack_length_warns_and_keeps_a_belly(tmp_path):
    from motion import write_sto
    from motion.osim.builder import ModelBuilder

    mb = (ModelBuilder("short").add_body("a").add_weld_joint("fix", "ground", "a")
          .add_body("b").add_pin_joint("pin", "a", "b", "q", range=(-3.0, 3.0)))
    # path 0.25 m long at q = 0, shortening as q grows; tendon slack length 0.24 m
    mb.add_muscle("m", [("a", (0.03, 0.1, 0.0)), ("b", (0.03, -0.15, 0.0))], tendon_slack_length=0.24,
                  optimal_fiber_length=0.05)
    mb.write(tmp_path / "short.osim")
    q = np.deg2rad(np.arange(0, 91, 15.0))
    write_sto(tmp_path / "sweep.mot", np.arange(len(q)) * 0.01, {"q": q})
    (tmp_path / "m.toml").write_text(textwrap.dedent("""
        model = "short.osim"
        motion = "sweep.mot"
        [muscles.m]
        action_lines = ["m"]
        fibres = 12
        resolution = 8
        """))
    with pytest.warns(UserWarning, match="shorter than its tendon slack length"):
        res = run(tmp_path / "m.toml")
    m = res.muscle("m")
    assert any("shorter than its tendon slack length" in n and n.startswith("warning:") for n in m.notes)
    assert (m.fibre_lengths > 0).all() and np.isfinite(m.fibre_moment_arms).all()
    # it counts the motion's frames (not the moment arms' perturbed poses): those where the path
    # is shorter than l_ts + 2 f L (f = BELLY_MIN_FRACTION = 2 %)
    length = m.action_line_lengths[:, 0]
    short = int((length - 0.24 < 2 * 0.02 * length).sum())
    assert 0 < short < len(q)
    (note,) = [n for n in m.notes if "shorter than its tendon slack length" in n]
    assert f"in {short} of {len(q)} frames)" in note, note
    # the belly never drops below 2 % of the path (motion.osim.muscle_parameters.BELLY_MIN_FRACTION)
    assert (np.median(m.fibre_lengths, axis=1) > 0.015 * m.action_line_lengths[:, 0]).all()


def _straight_model(tmp_path, share=None, mesh=False):
    """A 0.30 m straight path (l_ts 0.20 m: a 0.10 m belly) over a pin at its origin, and the
    fibre model of it; ``share``: its ``origin_tendon_share``."""
    from motion import write_sto
    from motion.osim.builder import ModelBuilder

    mb = (ModelBuilder("straight").add_body("a").add_weld_joint("fix", "ground", "a")
          .add_body("b").add_pin_joint("pin", "a", "b", "q", range=(-1.0, 1.0)))
    mb.add_muscle("m", [("a", (0.02, 0.0, 0.0)), ("b", (0.02, -0.30, 0.0))], tendon_slack_length=0.20,
                  optimal_fiber_length=0.08)
    mb.write(tmp_path / "straight.osim")
    write_sto(tmp_path / "sweep.mot", np.arange(3) * 0.01, {"q": np.deg2rad([0.0, 5.0, 10.0])})
    extra = "" if share is None else f"origin_tendon_share = {share}\n"
    (tmp_path / "m.toml").write_text('model = "straight.osim"\nmotion = "sweep.mot"\n[muscles.m]\n'
                                     'action_lines = ["m"]\nfibres = 12\nresolution = 8\n' + extra)
    return tmp_path / "m.toml"


@pytest.mark.parametrize("share", [0.1, 0.5, 0.9])
def test_origin_tendon_share_places_the_belly_and_keeps_its_length(tmp_path, share):
    """The belly starts share x l_ts along the path from the origin (here at q = 0 the path is
    the straight segment from (0.02, 0, 0) down to (0.02, -0.30, 0)) and is L - l_ts long
    whatever the share (rigid tendon)."""
    res = run(_straight_model(tmp_path, share), keep_points=True)
    m = res.muscle("m")
    ends = m.fibre_points[0]                                  # frame 0: (N, P, 3)
    depth = -ends[..., 1]                                     # arc length from the origin
    assert np.median(depth[:, 0]) == pytest.approx(share * 0.20, abs=2e-3)
    assert np.median(depth[:, -1]) == pytest.approx(share * 0.20 + 0.10, abs=2e-3)
    np.testing.assert_allclose(np.median(m.fibre_lengths, axis=1),
                               m.action_line_lengths[:, 0] - 0.20, rtol=0.01)


@pytest.mark.parametrize("value, mesh, message", [
    ("1.5", False, "expected a number from 0 to 1"), ("true", False, "expected a number from 0 to 1"),
    ("0.2", True, "only a generated surface"),
])
def test_origin_tendon_share_errors_name_the_key(tmp_path, value, mesh, message):
    from analysis.errors import InputError
    from analysis.spec import load_spec

    toml = _straight_model(tmp_path, value)
    if mesh:
        import trimesh

        trimesh.creation.icosphere(radius=0.01).export(tmp_path / "ball.stl")
        toml.write_text(toml.read_text().replace("[muscles.m]\n", '[muscles.m]\nmesh = "ball.stl"\n'))
    with pytest.raises(InputError) as err:
        load_spec(toml)
    assert "muscles.m.origin_tendon_share" in str(err.value) and message in str(err.value)
