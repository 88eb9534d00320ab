"""Paths over two wrap objects in series (Rajagopal's gastrocnemii: GasMed_at_shank_r, then
GasMed_at_condyles_r), where OpenSim 4.6 has two moment arms.

OpenSim repeats its wrapping passes until the length changes by less than 0.5 mm, but its length
reads each tangent point's position as first cached in the state (the first pass), while later
passes move the points and the arcs: the length is up to 8.8 mm shorter than the path OpenSim
draws, and its -dL/dq (the action lines' contract, `motion.wrapping.wrapped_rows`) differs from
OpenSim's own `computeMomentArm` (a unit tension along the current path) by about 11 mm at the knee.
The belly follows the drawn path (`motion.wrapping.batch.WrappedPath.drawn`), so its fibres'
knee moment arms are computeMomentArm's; the action lines keep OpenSim's length, carry the drawn
one (``ActionLines.drawn_lengths``) and warn, and the run says why fibres leave the line.

Oracle: OpenSim 4.6's `computeMomentArm` and -dL/dq by central differences, both in
``../shared/opensim/reference/RajagopalLaiUhlrich2023`` (every 4th row of the walk).
"""
from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from motion.osim.kinematics import body_pose_derivatives
from motion.osim.reader import ModelFileWarning, load_model
from motion.wrapping.action_lines import action_lines
from motion.surface.current_lines import current_polylines
from motion.wrapping.batch import wrap_path
from motion.wrapping.path_points import path_points

MODEL = "RajagopalLaiUhlrich2023/RajagopalLaiUhlrich2023.osim"
MOTION = "RajagopalLaiUhlrich2023/walk_from_gait2392.mot"
REFERENCE = "reference/RajagopalLaiUhlrich2023/walk_from_gait2392/moment_arms.csv"
ROWS = slice(0, 84, 4)          # reference frames 0..20 (motion rows 0, 4, .., 80)


@pytest.fixture(scope="module")
def rajagopal(opensim_dir):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_model(opensim_dir / MODEL)


def _wrapped(model, q, name):
    tf, dtf, q_used, jac = body_pose_derivatives(model, q, derivatives=True)
    path = model.path(name)
    pp = path_points(path, model, q_used, tf, jac=jac, d_tf_ground_body=dtf)
    return wrap_path(path, model, pp.points, pp.active, pp.d_points, tf, dtf), tf


def _walk_q(model, opensim_dir):
    from motion.osim.motion_file import load_motion

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mot = load_motion(opensim_dir / MOTION, model)
    return np.asarray(mot.q)[ROWS]


def test_drawn_path_is_the_current_polyline_and_longer_than_opensims_length(rajagopal, opensim_dir):
    q = _walk_q(rajagopal, opensim_dir)
    wrapped, tf = _wrapped(rajagopal, q, "gasmed_r")
    # the polyline the belly follows has the drawn path's length (arcs sampled by 24 chords on a
    # cylinder of radius ~ 2-3 cm: chord error < 0.1 mm)
    poly = current_polylines(rajagopal, q, ["gasmed_r"], None, tf, q)["gasmed_r"]
    seg = np.linalg.norm(np.diff(poly[0], axis=1), axis=-1)
    np.testing.assert_allclose(np.nansum(seg, axis=1), wrapped.drawn_length, atol=1e-4)
    gap = wrapped.drawn_length - wrapped.length
    assert gap.min() > -1e-9 and gap.max() > 5e-3       # up to 8.8 mm in this walk
    # the action lines carry the drawn length beside OpenSim's and say where they differ
    with pytest.warns(ModelFileWarning, match=r"gasmed_r \(up to [0-9.]+ mm.*first wrapping pass"):
        lines = action_lines(rajagopal, q, muscles=["gasmed_r", "vaslat_r", "bflh_r"])
    np.testing.assert_allclose(lines.length("gasmed_r"), wrapped.length, atol=1e-12)
    np.testing.assert_allclose(lines.drawn_lengths[:, 0], wrapped.drawn_length, atol=1e-12)
    np.testing.assert_array_equal(lines.drawn_lengths[:, 1:], lines.lengths[:, 1:])   # one wrap / none
    np.testing.assert_array_equal(lines.mixes_passes(), [True, False, False])
    # one wrap object: one pass, the drawn path is OpenSim's (vaslat_r over KnExtVL_at_fem_r)
    single, _ = _wrapped(rajagopal, q, "vaslat_r")
    np.testing.assert_array_equal(single.drawn, single.points)
    np.testing.assert_allclose(single.drawn_length, single.length, atol=1e-12)


@pytest.mark.slow
def test_fibres_follow_opensims_compute_moment_arm_and_the_run_says_why(rajagopal, opensim_dir, tmp_path):
    from analysis.errors import FibreWarning
    from analysis.run import run

    (tmp_path / "gas.toml").write_text(
        f'model = "{(opensim_dir / MODEL).as_posix()}"\nmotion = "{(opensim_dir / MOTION).as_posix()}"\n'
        '[muscles.gasmed_r]\naction_lines = ["gasmed_r"]\nfibres = 30\nresolution = 16\n')
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = run(tmp_path / "gas.toml", frames=ROWS, quiet=True, keep_points=False)
    m = res.muscles[0]
    knee = m.coordinates.index("knee_angle_r")
    fibre = np.median(m.fibre_moment_arms[:, :, knee], axis=1)
    line = m.action_line_moment_arms[:, 0, knee]
    ref = pd.read_csv(opensim_dir / REFERENCE)
    ref = ref[(ref.muscle == "gasmed_r") & (ref.coordinate == "knee_angle_r")].sort_values("frame")
    ref = ref[ref.frame < len(fibre)]
    # the action line is OpenSim's -dL/dq (the parity tests' tolerance)
    np.testing.assert_allclose(line, ref.neg_dLdq_fd, atol=1e-5)
    # the fibres: computeMomentArm within 2 mm (a generated belly's median fibre tracks its path
    # within max(5 %, 1 mm), README; 22 mm here), while OpenSim's -dL/dq is ~11 mm away
    np.testing.assert_allclose(fibre, ref.moment_arm, atol=2e-3)
    assert np.median(np.abs(ref.moment_arm - ref.neg_dLdq_fd)) > 5e-3
    said = [str(w.message) for w in seen if issubclass(w.category, FibreWarning)]
    assert any("knee_angle_r" in s and "computeMomentArm" in s for s in said)
    assert not any("check the mesh" in s for s in said)
    assert any(issubclass(w.category, ModelFileWarning) and "first wrapping pass" in str(w.message) for w in seen)
    # the 3D scene recomputes the lines on its own frames: the run has said it, the scene does not
    from analysis.scene import write_scene
    from analysis.spec import load_spec

    with warnings.catch_warnings(record=True) as again:
        warnings.simplefilter("always")
        write_scene(tmp_path / "scene", res, load_spec(tmp_path / "gas.toml"))
    assert not [w for w in again if "first wrapping pass" in str(w.message)]
