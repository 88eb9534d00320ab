"""Attachment ``frame``: landmarks copied from the .osim (each path point in its own body's frame)
work as written with ``frame = "body"``; every landmark mistake is one error naming the muscle, the
end, the units and the likely fix."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import analysis
from analysis.errors import InputError
from analysis.spec import load_spec

ROOT = Path(__file__).resolve().parents[2]
GAIT = ROOT.parent / "shared" / "opensim" / "Gait2392_Simbody"


def _cluster(p, units=1.0):
    """A path point and two neighbours 4 mm away (an attachment area around it)."""
    p = np.asarray(p, dtype=float)
    pts = np.array([p, p + [0.004, 0, 0], p + [0, 0, 0.004]]) * units
    return "[" + ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]" for row in pts) + "]"


def _gait_toml(tmp_path, model, muscles):
    lines = [f'model = "{GAIT / "gait2392_thelen2003muscle.osim"}"',
             f'motion = "{GAIT / "subject01_walk1_ik.mot"}"', "[defaults]", "fibres = 8", "resolution = 8"]
    for name in muscles:
        path = model.path(name)
        first, last = path.points[0], path.points[-1]
        lines += [f"[muscles.{name}]", f'action_lines = ["{name}"]', 'template = "parallel"',
                  f'origin = {{ body = "{first.body}", frame = "body", points = {_cluster(first.location)} }}',
                  f'insertion = {{ body = "{last.body}", frame = "body", points = {_cluster(last.location)} }}']
    toml = tmp_path / "gait_fibres.toml"
    toml.write_text("\n".join(lines) + "\n")
    return toml


@pytest.mark.shared
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_gait2392_landmarks_in_their_own_bodies_frames_run(tmp_path):
    """add_long_r (pelvis -> femur_r) and bifemsh_r (femur_r -> tibia_r) with landmarks taken from
    the .osim path points: the fibres run over walking, and at every frame their length is within
    15 % of the belly's, L - tendon_slack_length (a generated surface around that very line)."""
    if not GAIT.is_dir():
        pytest.skip("../shared/opensim/Gait2392_Simbody is absent")
    import motion

    model = motion.load_model(GAIT / "gait2392_thelen2003muscle.osim")
    toml = _gait_toml(tmp_path, model, ["add_long_r", "bifemsh_r"])
    spec = load_spec(toml)
    assert all(m.origin.in_body_frame and m.insertion.in_body_frame for m in spec.muscles)
    from motion.osim.muscle_parameters import muscle_parameters

    res = analysis.run(spec, frames="0:211:50", keep_points=False)
    for m in res.muscles:
        # a generated surface is the belly, L - tendon_slack_length (tendons join it to the ends)
        belly = m.action_line_lengths[:, 0] - muscle_parameters(model, m.name).tendon_slack_length
        ratio = np.median(m.fibre_lengths, axis=1) / belly
        assert np.all(np.isfinite(m.fibre_lengths)) and np.all(np.abs(ratio - 1) < 0.15), (m.name, ratio)


ARM_OSIM = ROOT / "models" / "arm_example.osim"


def _arm_toml(tmp_path, origin, insertion, units="m"):
    toml = tmp_path / "arm.toml"
    toml.write_text(f'model = "{ARM_OSIM}"\nmotion = "{ROOT / "models" / "elbow_flexion.mot"}"\nunits = "{units}"\n'
                    "[defaults]\nfibres = 6\nresolution = 6\n"
                    '[muscles.bra]\naction_lines = ["BRA"]\ntemplate = "parallel"\n'
                    f'mesh = "{ROOT / "models" / "meshes" / "brachialis.ply"}"\n'
                    f"origin = {origin}\ninsertion = {insertion}\n")
    return toml


def _arm_points(end):
    import motion

    path = motion.load_model(ARM_OSIM).path("BRA")
    return path.points[0 if end == "origin" else -1]


def _run_error(toml):
    with pytest.raises(InputError) as exc:
        analysis.run(toml, frames="0:2")
    return str(exc.value)


def test_arm_landmarks_in_body_frames_work(tmp_path):
    o, i = _arm_points("origin"), _arm_points("insertion")
    toml = _arm_toml(tmp_path, f'{{ body = "{o.body}", frame = "body", points = {_cluster(o.location)} }}',
                     f'{{ body = "{i.body}", frame = "{i.body}", points = {_cluster(i.location)} }}')
    res = analysis.run(toml, frames="0:27:13", keep_points=False)
    assert np.all(np.isfinite(res.muscles[0].fibre_lengths))


def test_error_body_frame_points_read_in_the_muscle_frame(tmp_path):
    """Forearm path points (forearm frame, 0.29 m below the humerus) written without frame="body"."""
    o, i = _arm_points("origin"), _arm_points("insertion")
    msg = _run_error(_arm_toml(tmp_path, f'{{ body = "{o.body}", frame = "body", points = {_cluster(o.location)} }}',
                               f'{{ body = "{i.body}", points = {_cluster(i.location)} }}'))
    assert "muscle 'bra': insertion" in msg and 'units "m"' in msg
    assert "frame = \"body\"" in msg and "forearm" in msg and "mm from the muscle surface" in msg


def test_error_body_frame_on_muscle_frame_points(tmp_path):
    """Points in ground (the muscle's frame) marked frame = "body"."""
    import motion

    model = motion.load_model(ARM_OSIM)
    tf = motion.body_poses(model, np.zeros((1, 1))).tf_ground_body[0, model.body_index("forearm")]
    i = _arm_points("insertion")
    ground = tf[:3, :3] @ i.location + tf[:3, 3]
    o = _arm_points("origin")
    msg = _run_error(_arm_toml(tmp_path, f'{{ body = "{o.body}", frame = "body", points = {_cluster(o.location)} }}',
                               f'{{ body = "{i.body}", frame = "body", points = {_cluster(ground)} }}'))
    assert "muscle 'bra': insertion" in msg and "remove frame = \"body\"" in msg


def test_error_millimetres_read_as_metres(tmp_path):
    o, i = _arm_points("origin"), _arm_points("insertion")
    msg = _run_error(_arm_toml(
        tmp_path, f'{{ body = "{o.body}", frame = "body", points = {_cluster(o.location, 1000.0)} }}',
        f'{{ body = "{i.body}", frame = "body", points = {_cluster(i.location)} }}'))
    assert "muscle 'bra': origin" in msg and 'units "m"' in msg and 'units = "mm"' in msg


def test_error_unknown_attachment_frame(tmp_path):
    o, i = _arm_points("origin"), _arm_points("insertion")
    with pytest.raises(InputError) as exc:
        load_spec(_arm_toml(tmp_path, f'{{ body = "{o.body}", frame = "humerus_body", points = [[0, 0, 0]] }}',
                            f'{{ body = "{i.body}", points = [[0, 0, 0]] }}'))
    msg = str(exc.value)
    assert "muscles.bra.origin.frame" in msg and "frame = \"body\"" in msg
