"""`fibres run` bad input through `analysis.cli.main`: exit status 2, one line on stderr naming the
file/element and the fix, no traceback, no output file. Ctrl-C: status 130, nothing written."""
from __future__ import annotations

import importlib
import os
import shutil
from pathlib import Path

import pytest

from analysis import cli

run_module = importlib.import_module("analysis.run")  # the module (analysis.run is the function)

MODELS = Path(__file__).resolve().parents[2] / "models"


@pytest.fixture()
def example(tmp_path):
    """A private copy of the bundled example (repository files, not shared data)."""
    if not (MODELS / "arm_example.toml").is_file():
        pytest.skip("the bundled example model is not in this checkout")
    dst = tmp_path / "models"
    shutil.copytree(MODELS, dst, ignore=shutil.ignore_patterns("*.py", "*.log", "__pycache__"))
    return dst


def _fails(capsys, argv, *must):
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for text in must:
        assert text in lines[0], lines[0]
    return lines[0]


def _no_output(out: Path):
    assert not out.exists() or list(out.iterdir()) == []


@pytest.mark.parametrize("old,new,key", [
    ('action_lines = ["BRA"]', 'action_lines = ["BRA", "NOPE"]', "muscles.brachialis.action_lines[1]"),
    ('mesh = "meshes/biceps.ply"', 'mesh = "meshes/gone.ply"', "muscles.biceps.mesh"),
    ('template = "pennate"', 'template = "spiral"', "muscles.brachialis.template"),
    ('origin = { body = "humerus", file = "biceps_origin.csv" }',
     'origin = { body = "scapula", file = "biceps_origin.csv" }', "muscles.biceps.origin.body"),
    ('units = "m"', 'units = "m"\ncolour = "red"', "colour"),
])
def test_toml_mistakes_exit_2_with_one_line(example, tmp_path, capsys, old, new, key):
    toml = example / "arm_example.toml"
    text = toml.read_text()
    assert old in text
    toml.write_text(text.replace(old, new, 1))
    out = tmp_path / "out"
    _fails(capsys, ["run", str(toml), "--out", str(out), "--quiet"], str(toml), key)
    _no_output(out)


def test_misspelt_action_line_gets_the_close_names(example, tmp_path, capsys):
    """Rajagopal has 80 muscles: the first 12 in alphabetical order (addbrev_l ...) do not help
    with 'vaslat'; the close names do. Here 'TRIlon' -> TRIlong (the example's paths)."""
    toml = example / "arm_example.toml"
    toml.write_text(toml.read_text().replace('action_lines = ["TRIlong", "TRIlat"]',
                                             'action_lines = ["TRIlon", "TRIlat"]', 1))
    line = _fails(capsys, ["run", str(toml), "--out", str(tmp_path / "out"), "--quiet"],
                  "muscles.triceps.action_lines[0]", "'TRIlon'")
    assert "Did you mean TRIlong" in line and "BICshort" not in line


def test_motion_with_coordinates_the_model_lacks(example, tmp_path, capsys):
    mot = tmp_path / "knee.mot"
    mot.write_text("knee\nversion=1\nnRows=2\nnColumns=2\ninDegrees=yes\nendheader\n"
                   "time\tknee_angle\n0\t0\n0.1\t10\n")
    out = tmp_path / "out"
    _fails(capsys, ["run", str(example / "arm_example.toml"), "--motion", str(mot), "--out", str(out),
                    "--quiet"], str(mot))
    _no_output(out)


def test_motion_error_comes_before_the_start_line(example, tmp_path, capsys):
    """Not quiet: a broken motion file is the one line printed (no "fibres: 3 muscle(s) ..." start
    line before it), exit 2, no output folder."""
    mot = tmp_path / "bad.mot"
    mot.write_text("bad\nversion=1\nnRows=2\nnColumns=2\ninDegrees=yes\nendheader\n"
                   "time\telbow_flexion\n0\t0\n0.1\tten\n")
    out = tmp_path / "out"
    line = _fails(capsys, ["run", str(example / "arm_example.toml"), "--motion", str(mot), "--out", str(out)],
                  str(mot))
    assert line.startswith("fibres run: error"), line
    assert not out.exists()


def test_motion_is_read_with_the_muscles_spanned_coordinates(example, tmp_path, capsys, monkeypatch):
    """The motion is read with the coordinates the chosen muscles' paths span (the example's
    elbow paths: elbow_flexion), so that a missing one is warned about apart from the others."""
    import motion

    seen = []
    load = motion.load_motion
    monkeypatch.setattr(motion, "load_motion", lambda path, model, **kw: (seen.append(kw), load(path, model, **kw))[1])
    _fails(capsys, ["run", str(example / "arm_example.toml"), "--muscle", "brachialis", "--frames", "500:600",
                    "--out", str(tmp_path / "out")], "out of range")
    assert seen == [{"spanned": ("elbow_flexion",)}]


def test_frames_out_of_range(example, tmp_path, capsys):
    out = tmp_path / "out"
    line = _fails(capsys, ["run", str(example / "arm_example.toml"), "--frames", "500:600", "--out", str(out),
                           "--quiet"], "--frames", "out of range")
    assert "elbow_flexion.mot" in line
    _no_output(out)


def test_output_folder_is_a_file(example, tmp_path, capsys):
    out = tmp_path / "out"
    out.write_text("not a folder")
    _fails(capsys, ["run", str(example / "arm_example.toml"), "--out", str(out), "--quiet"], str(out),
           "is a file")
    assert out.read_text() == "not a folder"


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="needs POSIX permissions, not root")
def test_output_folder_read_only(example, tmp_path, capsys):
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o500)
    try:
        _fails(capsys, ["run", str(example / "arm_example.toml"), "--out", str(out), "--quiet"], str(out),
               "not writable")
        assert list(out.iterdir()) == []
    finally:
        out.chmod(0o700)


def test_output_folder_not_writable_as_root_too(example, tmp_path, capsys, monkeypatch):
    """Root ignores permission bits, so the check itself is exercised through os.access."""
    out = tmp_path / "ro"
    out.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **k: False if Path(p) == out else real(p, mode, **k))
    _fails(capsys, ["run", str(example / "arm_example.toml"), "--out", str(out), "--quiet"], str(out),
           "not writable")
    assert list(out.iterdir()) == []


def test_ctrl_c_in_the_middle_leaves_nothing(example, tmp_path, capsys, monkeypatch):
    import motion

    if not hasattr(motion, "action_lines"):
        pytest.skip("motion.wrapping.action_lines is not in this checkout yet")
    out = tmp_path / "out"

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    # the per-muscle stage (wrap -> fibres -> lengths) is interrupted after the action lines
    monkeypatch.setattr(run_module, "run_muscle", interrupted)
    code = cli.main(["run", str(example / "arm_example.toml"), "--out", str(out), "--quiet", "--frames", "0:2"])
    assert code == 130
    assert "interrupted" in capsys.readouterr().err
    assert not out.exists()                 # the folder was created for this run: removed again
    # a rerun works and writes the whole set
    monkeypatch.undo()
    code = cli.main(["run", str(example / "arm_example.toml"), "--out", str(out), "--quiet", "--frames", "0:2",
                     "--fibres", "8", "--resolution", "6", "--muscle", "brachialis"])
    assert code == 0, capsys.readouterr().err
    names = {p.name for p in out.iterdir()}
    assert {"fibre_lengths.csv", "fibre_moment_arms.csv", "action_lines.csv", "action_line_moment_arms.csv",
            "summary.csv", "run.json", "plots", "fibres"} <= names
    assert not [n for n in names if n.startswith(".")]


def test_full_example_run_writes_the_contract(example, tmp_path, capsys):
    """`fibres run` on the bundled example: every table has the INTERFACE columns, one row per
    (frame, fibre[, coordinate]); summary medians equal the fibre table's medians."""
    import pandas as pd

    out = tmp_path / "out"
    code = cli.main(["run", str(example / "arm_example.toml"), "--out", str(out), "--quiet", "--frames", "0:27:13",
                     "--fibres", "12", "--resolution", "8", "--sto"])
    assert code == 0, capsys.readouterr().err
    fl = pd.read_csv(out / "fibre_lengths.csv")
    assert list(fl.columns) == ["frame", "time", "muscle", "fibre", "length", "normalized_length"]
    assert len(fl) == 3 * 3 * 12 and set(fl.frame) == {0, 1, 2}
    # the example's muscles have OpenSim parameters: l / l_opt is finite, and the plots show it
    assert fl.normalized_length.notna().all() and (fl.normalized_length > 0).all()
    fr = pd.read_csv(out / "fibre_moment_arms.csv")
    assert list(fr.columns) == ["frame", "time", "muscle", "fibre", "coordinate", "moment_arm"]
    assert set(fr.coordinate) == {"elbow_flexion"} and len(fr) == len(fl)
    s = pd.read_csv(out / "summary.csv")
    row = s[(s.frame == 1) & (s.muscle == "biceps") & (s.quantity == "length")].iloc[0]
    assert row["median"] == pytest.approx(fl[(fl.frame == 1) & (fl.muscle == "biceps")].length.median(), rel=1e-9)
    record = __import__("json").loads((out / "run.json").read_text())
    assert set(record["inputs"]) >= {"spec", "model", "motion", "mesh:biceps"}
    assert {"wrap", "decompose_rest", "moment_arms"} <= set(record["timings_s"])
    assert (out / "fibres" / "biceps.pvd").is_file() and (out / "plots" / "biceps_lengths.png").is_file()
    assert (out / "plots" / "biceps_normalized_lengths.png").is_file()
    norm = s[(s.frame == 1) & (s.muscle == "biceps") & (s.quantity == "normalized_length")].iloc[0]
    fb = fl[(fl.frame == 1) & (fl.muscle == "biceps")]
    assert norm["median"] == pytest.approx(fb.normalized_length.median(), rel=1e-9)
    assert (out / "MuscleAnalysis_Length.sto").is_file()


def test_jobs_and_transport_options(example, tmp_path):
    """--jobs 2 (muscles in threads) gives the same numbers as one job; the per-frame
    'decompose' transport runs and gives finite moment arms."""
    import numpy as np

    from analysis import run

    toml = example / "arm_example.toml"
    kw = dict(frames="0:27:13", fibres=8, resolution=6, muscles=["biceps", "brachialis"])
    one, two = run(toml, jobs=1, **kw), run(toml, jobs=2, **kw)
    for a, b in zip(one.muscles, two.muscles):
        np.testing.assert_array_equal(a.fibre_lengths, b.fibre_lengths)
        np.testing.assert_array_equal(a.fibre_moment_arms, b.fibre_moment_arms)
    dec = run(toml, transport="decompose", **kw)
    assert dec.settings["transport"] == "decompose"
    assert np.isfinite(dec.muscle("biceps").fibre_moment_arms).all()


def test_unknown_muscle_option(example, tmp_path, capsys):
    out = tmp_path / "out"
    _fails(capsys, ["run", str(example / "arm_example.toml"), "--muscle", "deltoid", "--out", str(out), "--quiet"],
           "--muscle", "deltoid", "biceps")
    _no_output(out)


def test_muscle_option_given_an_action_line_names_its_muscle(example, tmp_path, capsys):
    """An OpenSim muscle name (the example's biceps surface is driven by BIClong and BICshort) is
    the likely mistake of a user who knows the model: the fix names the fibre-model muscle."""
    out = tmp_path / "out"
    line = _fails(capsys, ["run", str(example / "arm_example.toml"), "--muscle", "BICshort", "--out", str(out),
                           "--quiet"], "--muscle", "'BICshort'")
    assert "action line of biceps" in line and "--muscle biceps" in line
    _no_output(out)


def test_muscle_without_mesh_gets_a_generated_surface(example):
    """No `mesh`: a belly is generated around the fibre part of the action line (tendons of the
    model's tendon slack length join it to the attachments), so at the rest pose (frame 0) the
    median fibre length is L_path - tendon_slack_length within 5 %, and l / l_opt uses the
    model's optimal fibre length."""
    import numpy as np

    from analysis import run
    from motion.osim.muscle_parameters import muscle_parameters

    toml = example / "arm_example.toml"
    toml.write_text(toml.read_text().replace('mesh = "meshes/brachialis.ply"\n', "", 1))
    res = run(toml, frames="0:27:13", muscles=["brachialis"], fibres=12, resolution=8, template="parallel")
    m = res.muscle("brachialis")
    assert np.isfinite(m.fibre_moment_arms).all()
    from motion import load_model

    p = muscle_parameters(load_model(example / "arm_example.osim"), m.action_lines[0])
    belly = m.action_line_lengths[0, 0] - p.tendon_slack_length
    assert np.median(m.fibre_lengths[0]) == pytest.approx(belly, rel=0.05)
    np.testing.assert_allclose(m.normalized_lengths, m.fibre_lengths / p.optimal_fiber_length, rtol=1e-12)


def test_bones_are_handed_to_the_wrapping(example, tmp_path):
    """`bones` (the example's humerus and forearm meshes, ground at rest = body frames) reach
    motion.wrap_surfaces; the run completes and run.json lists and hashes them."""
    import json

    import numpy as np

    toml = example / "arm_example.toml"
    text = toml.read_text().replace(
        'mesh = "meshes/brachialis.ply"',
        'mesh = "meshes/brachialis.ply"\nbones = [{ body = "humerus", mesh = "meshes/humerus.stl" }, '
        '{ body = "forearm", mesh = "meshes/forearm.stl" }]', 1)
    toml.write_text(text)
    out = tmp_path / "out"
    code = cli.main(["run", str(toml), "--out", str(out), "--quiet", "--frames", "0:27:13", "--fibres", "8",
                     "--resolution", "6", "--muscle", "brachialis", "--no-plots"])
    assert code == 0
    record = json.loads((out / "run.json").read_text())
    assert record["inputs"]["bone:brachialis:1"]["path"].endswith("forearm.stl")
    assert len(record["inputs"]["bone:brachialis:0"]["sha256"]) == 64
    import pandas as pd

    assert np.isfinite(pd.read_csv(out / "fibre_moment_arms.csv").moment_arm).all()
