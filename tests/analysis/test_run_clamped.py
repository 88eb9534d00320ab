"""Fibre moment arms where a clamped coordinate leaves its range (Rajagopal's walk dips to -1 deg
of knee flexion, range 0..140 deg): the pose is clamped, and the fibres' moment arm must be the
one at the clamped pose, as the action line's, not 0 (both central-difference poses clamped to
the same one) nor half of it (at the bound, one of them clamped).

Model (`motion.osim.builder` plus one CoordinateCouplerConstraint, so that posing clamps, as in
OpenSim's assembly): thigh fixed, shank on a pin (axis z) at the origin, ``knee`` clamped to
[0, 1]; a massless ``pat`` body on a pin ``beta`` coupled to the knee (beta = knee). A straight
muscle from p1 = (X0, A) on the thigh to p2 = Rz(q) (X0, -B) on the shank: with
dL/dq = (p1 x p2)_z / L its moment arm is r(q) = (A p2x - X0 p2y) / L(q), and r(0) = X0 exactly
(L(0) = A + B). A generated belly's median fibre tracks its line within max(5 %, 1 mm) (README,
"Generated muscles have tendons"); the median of 30 fibres sits up to ~0.6 mm off the line.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from analysis.run import run

X0, A, B = -0.04, 0.25, 0.3
HI = 1.0


def _r_line(q):
    c, s = np.cos(q), np.sin(q)
    p2x, p2y = c * X0 + s * B, s * X0 - c * B
    return (A * p2x - X0 * p2y) / np.hypot(p2x - X0, p2y - A)


def build(tmp_path, q, slack=0.3):
    from motion import write_sto
    from motion.osim.builder import ModelBuilder

    mb = (ModelBuilder("clamped").add_body("thigh").add_weld_joint("fix", "ground", "thigh")
          .add_body("shank").add_pin_joint("knee", "thigh", "shank", "knee", range=(0.0, HI), clamped=True)
          .add_body("pat", mass=0.01).add_pin_joint("patj", "thigh", "pat", "beta", range=(-3.0, 3.0)))
    mb.add_muscle("gas", [("thigh", (X0, A, 0.0)), ("shank", (X0, -B, 0.0))],
                  optimal_fiber_length=0.1, tendon_slack_length=slack, max_isometric_force=800.0)
    doc = mb.to_element()
    cs = ET.SubElement(ET.SubElement(doc.find("Model"), "ConstraintSet", name="constraintset"), "objects")
    cc = ET.SubElement(cs, "CoordinateCouplerConstraint", name="beta_con")
    ET.SubElement(ET.SubElement(cc, "coupled_coordinates_function"), "LinearFunction").append(
        _text("coefficients", "1 0"))
    cc.append(_text("independent_coordinate_names", "knee"))
    cc.append(_text("dependent_coordinate_name", "beta"))
    cc.append(_text("scale_factor", "1"))
    (tmp_path / "knee.osim").write_text(ET.tostring(doc, encoding="unicode"))
    write_sto(tmp_path / "walk.mot", np.arange(len(q)) * 0.01, {"knee": np.asarray(q), "beta": np.asarray(q)})
    (tmp_path / "gas.toml").write_text('model = "knee.osim"\nmotion = "walk.mot"\n'
                                       '[muscles.gas]\naction_lines = ["gas"]\nfibres = 30\nresolution = 16\n')
    return tmp_path / "gas.toml"


def _text(tag, text):
    el = ET.Element(tag)
    el.text = text
    return el


def test_fibre_moment_arms_at_clamped_poses_are_those_of_the_clamped_pose(tmp_path):
    q = np.array([0.3, 0.1, -0.02, -0.05, 0.0, 0.2, HI, HI + 0.1])
    res = run(build(tmp_path, q), quiet=True)
    m = res.muscles[0]
    knee = m.coordinates.index("knee")
    median = np.median(m.fibre_moment_arms[:, :, knee], axis=1)
    expected = _r_line(np.clip(q, 0.0, HI))
    assert abs(expected[2] - X0) < 1e-15          # the clamped pose's arm is X0 (docstring)
    # the action line (exact derivative) at the clamped pose
    np.testing.assert_allclose(m.action_line_moment_arms[:, 0, knee], expected, atol=1e-9)
    # the fibres' median: within max(5 %, 1 mm) of it in every frame, inside, below and at the bounds
    np.testing.assert_allclose(median, expected, atol=1e-3)


def test_path_functions_of_a_clamped_coordinate_fit_inside_its_range(tmp_path):
    """`fibres export-osim`'s fit samples +-10 deg around the frames; a frame at -0.05 rad would
    put samples down to -0.22 rad, where the pose is clamped to 0 and the length flat: a kink at
    the bound that no polynomial fits. Inside the range the fitted function must give the fibre
    lengths of a separate run at new poses (the fit's tolerance 0.1 mm, with a margin of 2 for
    poses that are neither training nor validation samples)."""
    from analysis.fibre_paths import _evaluate_each, fit_fibre_paths
    from analysis.spec import load_spec

    spec = load_spec(build(tmp_path, [-0.05, 0.0, 0.05, 0.1, 0.15]))
    fit = fit_fibre_paths(spec, run(spec, quiet=True))["gas"]
    q_new = np.array([0.0, 0.01, 0.03, 0.07, 0.12, 0.2])
    (tmp_path / "new").mkdir()
    fresh = run(build(tmp_path / "new", q_new), quiet=True).muscles[0].fibre_lengths
    got, _ = _evaluate_each(fit, 1, q_new[:, None], fit.gates)
    assert np.abs(got - fresh).max() < 2e-4


def test_path_fit_does_not_repeat_the_runs_warnings_per_chunk_of_samples(tmp_path):
    """A path shorter than its tendon slack length (0.55 m < 0.56 m) warns in the motion's run; the
    fit's runs on sampled poses (chunks of `CHUNK`) said it again per chunk, each worded with its
    own frame count: ~20 lines on stderr for a Rajagopal export. They say nothing now."""
    import warnings

    from analysis.errors import FibreWarning
    from analysis.fibre_paths import fit_fibre_paths
    from analysis.spec import load_spec

    spec = load_spec(build(tmp_path, [0.0, 0.05, 0.1], slack=0.56))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        result = run(spec, quiet=True)
    assert any(issubclass(w.category, FibreWarning) and "tendon slack" in str(w.message) for w in seen)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        fit_fibre_paths(spec, result)
    assert not [w for w in seen if issubclass(w.category, FibreWarning)]
