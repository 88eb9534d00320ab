"""`fibres lines`: --frames, the long tables, end-to-end against OpenSim 4.6, and every bad input."""
from __future__ import annotations

import argparse
import re

import numpy as np
import pandas as pd
import pytest

from analysis.cli import main
from analysis.errors import InputError
from analysis.frames_option import parse_frames, resolve_frames
from analysis.lines_tables import action_lines_table, body_poses_table, moment_arms_table

# ------------------------------------------------------------------ --frames


@pytest.mark.parametrize("text, n, expected", [
    ("0:10:2", 20, [0, 2, 4, 6, 8]),
    ("::5", 12, [0, 5, 10]),
    ("7:", 10, [7, 8, 9]),
    (":3", 10, [0, 1, 2]),
    ("4", 10, [4]),
    ("0:10", 10, list(range(10))),
    (":", 3, [0, 1, 2]),
])
def test_frames_select_python_slices(text, n, expected):
    got = resolve_frames(parse_frames(text), n)
    np.testing.assert_array_equal(got, expected)
    # the same rows as Python's own slice of range(n)
    parts = (text.split(":") + ["", ""])[:3] if ":" in text else [text, str(int(text) + 1), ""]
    ref = list(range(n))[slice(*[int(p) if p else None for p in parts])]
    assert list(got) == ref


@pytest.mark.parametrize("text", ["", "a:b", "1:2:3:4", "5:2", "0:10:0", "-1:", "1.5:", ":"*4])
def test_frames_bad_syntax_is_a_usage_error(text):
    with pytest.raises(argparse.ArgumentTypeError, match="--frames"):
        parse_frames(text)


@pytest.mark.parametrize("text, word", [("10:", "START 10"), ("0:11", "STOP 11"), ("10", "START 10")])
def test_frames_out_of_range_names_valid_range(text, word):
    with pytest.raises(InputError) as info:
        resolve_frames(parse_frames(text), 10, source="walk.mot")
    message = str(info.value)
    assert message.startswith("walk.mot: --frames")
    assert word in message and "0 to 9" in message and "1 to 10" in message
    assert "\n" not in message


def test_frames_none_is_all():
    np.testing.assert_array_equal(resolve_frames(None, 4), [0, 1, 2, 3])


# ------------------------------------------------------------------ long tables


def test_body_poses_table_layout():
    rng = np.random.default_rng(0)
    tf = rng.normal(size=(3, 2, 4, 4))
    table = body_poses_table([0.0, 0.1, 0.2], tf, ["ground", "femur"])
    assert list(table.columns) == ["frame", "time", "body", "tx", "ty", "tz",
                                   "r00", "r01", "r02", "r10", "r11", "r12", "r20", "r21", "r22"]
    assert len(table) == 6
    row = table.iloc[3]  # frame 1, femur
    assert (row.frame, row.time, row.body) == (1, 0.1, "femur")
    np.testing.assert_array_equal(row[["tx", "ty", "tz"]].to_numpy(float), tf[1, 1, :3, 3])
    np.testing.assert_array_equal(row[[f"r{i}{j}" for i in range(3) for j in range(3)]]
                                  .to_numpy(float), tf[1, 1, :3, :3].reshape(-1))


def test_action_lines_table_layout():
    lengths = np.arange(6.0).reshape(2, 3)
    table = action_lines_table([0.0, 1.0], lengths, ["a", "b", "c"], frames=[5, 6])
    assert list(table.columns) == ["frame", "time", "muscle", "length"]
    assert table.frame.tolist() == [5, 5, 5, 6, 6, 6]
    assert table.muscle.tolist() == ["a", "b", "c"] * 2
    np.testing.assert_array_equal(table.length, lengths.reshape(-1))
    with_lines = action_lines_table([0.0, 1.0], lengths, ["m", "m", "n"],
                                    action_lines=["a", "b", "c"])
    assert list(with_lines.columns) == ["frame", "time", "muscle", "action_line", "length"]


def test_moment_arms_table_keeps_only_spanned_pairs():
    arms = np.arange(2 * 2 * 3, dtype=float).reshape(2, 2, 3)
    spanned = np.array([[True, False, True], [False, True, False]])
    table = moment_arms_table([0.0, 1.0], arms, spanned, ["a", "b"], ["q0", "q1", "q2"])
    assert list(table.columns) == ["frame", "time", "muscle", "coordinate", "moment_arm"]
    assert len(table) == 2 * 3
    assert list(zip(table.muscle, table.coordinate))[:3] == [("a", "q0"), ("a", "q2"), ("b", "q1")]
    expected = [arms[f, m, c] for f in range(2) for m, c in [(0, 0), (0, 2), (1, 1)]]
    np.testing.assert_array_equal(table.moment_arm, expected)


def test_tables_check_shapes():
    with pytest.raises(ValueError, match=r"\(F, M\)"):
        action_lines_table([0.0], np.zeros((2, 1)), ["a"])
    with pytest.raises(ValueError, match=r"\(F, B, 4, 4\)"):
        body_poses_table([0.0], np.zeros((1, 2, 3, 4)), ["a", "b"])
    with pytest.raises(ValueError, match="spanned"):
        moment_arms_table([0.0], np.zeros((1, 1, 2)), np.zeros((2, 1), bool), ["a"], ["x", "y"])


# ------------------------------------------------------------------ end to end (shared data)

POSE = ["tx", "ty", "tz"] + [f"r{i}{j}" for i in range(3) for j in range(3)]


def _run(argv, capsys):
    code = main(["lines", *map(str, argv)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _merge(ours, ref, keys, value, ref_value=None):
    """Our table and the reference joined on time (rounded) and names; one row per reference row."""
    ours = ours.assign(t=ours.time.round(9))
    ref = ref.assign(t=ref.time.round(9))
    merged = ref.merge(ours, on=["t", *keys], suffixes=("_ref", ""), how="left", validate="1:1")
    assert merged[value].notna().all(), "a reference row has no counterpart in our output"
    return merged


@pytest.fixture(scope="module")
def gait_out(tmp_path_factory, opensim_dir):
    out = tmp_path_factory.mktemp("gait")
    folder = opensim_dir / "Gait2392_Simbody"
    code = main(["lines", str(folder / "gait2392_thelen2003muscle.osim"),
                 str(folder / "subject01_walk1_ik.mot"), "--out", str(out), "--quiet"])
    assert code == 0
    return out


def test_writes_the_interface_columns(gait_out):
    assert sorted(p.name for p in gait_out.iterdir()) == sorted(
        ["body_poses.csv", "action_lines.csv", "action_line_moment_arms.csv"])
    poses = pd.read_csv(gait_out / "body_poses.csv")
    lines = pd.read_csv(gait_out / "action_lines.csv")
    arms = pd.read_csv(gait_out / "action_line_moment_arms.csv")
    assert list(poses.columns) == ["frame", "time", "body", *POSE]
    # the columns of `fibres run`'s files of the same names; each path is its own action line
    assert list(lines.columns) == ["frame", "time", "muscle", "action_line", "length"]
    assert list(arms.columns) == ["frame", "time", "muscle", "action_line", "coordinate", "moment_arm"]
    assert (lines.muscle == lines.action_line).all() and (arms.muscle == arms.action_line).all()
    assert poses.frame.min() == 0 and poses.frame.max() == 210  # 211 rows in the motion
    assert len(lines) == 211 * 92 and len(arms) == 211 * 262
    # >= 9 significant digits: the text of a length has at least 9 digits
    text = (gait_out / "action_lines.csv").read_text().splitlines()[1]
    assert len(re.sub(r"\D", "", text.split(",")[-1]).lstrip("0")) >= 9


def _reference_sets():
    """(model, motion, reference folder) of every OpenSim 4.6 reference set."""
    import json
    from pathlib import Path

    shared = Path(__file__).resolve().parents[2].parent / "shared"  # ../shared, as conftest
    sets = []
    for meta in sorted((shared / "opensim" / "reference").glob("*/*/metadata.json")):
        info = json.loads(meta.read_text())
        # metadata paths are relative to the repository root (../shared/...)
        model = shared.parent / info["model_file"].replace("../", "", 1)
        motion = shared.parent / info["motion_file"].replace("../", "", 1)
        sets.append(pytest.param(model, motion, meta.parent,
                                 id=f"{meta.parent.parent.name}/{meta.parent.name}"))
    return sets or [pytest.param(None, None, None, marks=pytest.mark.skip(
        reason="../shared data folder is absent"))]


@pytest.mark.parametrize("model, motion, ref_dir", _reference_sets())
def test_matches_opensim_reference(model, motion, ref_dir, tmp_path, capsys):
    """Every reference set through the command line, posed from the motion file as a user would.

    Tolerances: body frames 1e-9, lengths 1e-6 m, moment arms 1e-5 m of OpenSim's -dL/dq (central
    difference h = 1e-5: truncation ~h^2 L''' < 1e-9, round-off ~1e-11), plus what OpenSim's own
    assembler adds: in models with constraints it moves even the coordinates the motion gives by
    up to dq = max|value - motion_value| (3e-5 rad in testMomentArmsConstraintB), which moves a
    point 1 m from the joint by dq, a length by at most max|r| dq, a moment arm by ~|dr/dq| dq
    (|dr/dq| < 1 m here). Elsewhere dq = 0 and the plain tolerances apply.
    """
    code, _, err = _run([model, motion, "--out", tmp_path, "--quiet"], capsys)
    assert code == 0, err
    coords = pd.read_csv(ref_dir / "coordinates.csv")
    dq = float(np.nanmax(np.abs(coords.value - coords.motion_value)))
    ref_arms = pd.read_csv(ref_dir / "moment_arms.csv")
    r_max = float(np.max(np.abs(ref_arms.moment_arm)))

    poses = _merge(pd.read_csv(tmp_path / "body_poses.csv"),
                   pd.read_csv(ref_dir / "body_transforms.csv"), ["body"], "tx")
    for column in POSE:
        np.testing.assert_allclose(poses[column], poses[column + "_ref"], rtol=0,
                                   atol=1e-9 + 2 * dq, err_msg=column)
    lines = _merge(pd.read_csv(tmp_path / "action_lines.csv"),
                   pd.read_csv(ref_dir / "path_lengths.csv"), ["muscle"], "length")
    np.testing.assert_allclose(lines.length, lines.length_ref, rtol=0, atol=1e-6 + 2 * r_max * dq)
    ours = pd.read_csv(tmp_path / "action_line_moment_arms.csv")
    # the same (muscle, coordinate) pairs as OpenSim's reference tool, less the coupler-dependent
    # coordinates (INTERFACE.md: reported against the independent coordinate, total derivative)
    ref_arms = ref_arms[ref_arms.coord_status != "dependent"]
    assert set(zip(ours.muscle, ours.coordinate)) == set(zip(ref_arms.muscle, ref_arms.coordinate))
    arms = _merge(ours, ref_arms, ["muscle", "coordinate"], "moment_arm")
    np.testing.assert_allclose(arms.moment_arm, arms.neg_dLdq_fd, rtol=0, atol=1e-5 + 2 * dq)


def test_frames_and_muscle_options(opensim_dir, tmp_path, capsys):
    model = opensim_dir / "Arm26" / "arm26.osim"
    motion = opensim_dir / "Arm26" / "arm26_elbow_flexion_sweep.mot"
    code, out, err = _run([model, motion, "--out", tmp_path, "--frames", "10:50:5",
                           "--muscle", "BIClong", "--muscle", "TRIlat"], capsys)
    assert code == 0, err
    assert "2 paths" in out  # the summary line (not --quiet)
    lines = pd.read_csv(tmp_path / "action_lines.csv")
    assert lines.frame.tolist() == [f for f in range(8) for _ in range(2)]
    # motion rows 10, 15, ..., 45 of a sweep sampled every 0.01 s
    np.testing.assert_allclose(lines.time.unique(), np.arange(10, 50, 5) * 0.01, atol=1e-12)
    assert lines.muscle.tolist() == ["BIClong", "TRIlat"] * 8
    ref = pd.read_csv(opensim_dir / "reference" / "Arm26" / "elbow_flexion_sweep" /
                      "path_lengths.csv")
    merged = _merge(lines, ref[ref.muscle.isin(["BIClong", "TRIlat"])
                               & ref.time.round(9).isin(lines.time.round(9))], ["muscle"], "length")
    np.testing.assert_allclose(merged.length, merged.length_ref, rtol=0, atol=1e-6)


def test_frames_out_of_range_is_one_line(opensim_dir, tmp_path, capsys):
    out = tmp_path / "out"
    code, _, err = _run([opensim_dir / "Arm26" / "arm26.osim",
                         opensim_dir / "Arm26" / "arm26_elbow_flexion_sweep.mot", "--out", out,
                         "--frames", "200:"], capsys)
    assert code == 2
    assert err.count("\n") == 1 and "0 to 100" in err and "arm26_elbow_flexion_sweep.mot" in err
    assert not out.exists()


def test_unknown_muscle_is_one_line(opensim_dir, tmp_path, capsys):
    code, _, err = _run([opensim_dir / "Arm26" / "arm26.osim",
                         opensim_dir / "Arm26" / "arm26_elbow_flexion_sweep.mot", "--out", tmp_path,
                         "--muscle", "BIClonk"], capsys)
    assert code == 2
    assert err.count("\n") == 1 and "BIClonk" in err and "Did you mean BIClong" in err
    assert list(tmp_path.iterdir()) == []


def test_output_folder_is_a_file(opensim_dir, tmp_path, capsys):
    target = tmp_path / "taken"
    target.write_text("x")
    code, _, err = _run([opensim_dir / "Arm26" / "arm26.osim",
                         opensim_dir / "Arm26" / "arm26_elbow_flexion_sweep.mot", "--out", target],
                        capsys)
    assert code == 2 and err.count("\n") == 1 and "is a file" in err
    assert target.read_text() == "x"


# ------------------------------------------------------------------ every bad input: exit 2, one line


def _corrupt_model(text, case):
    if case == "truncated_xml":
        return text[: len(text) // 2]
    if case == "not_opensim":
        return '<?xml version="1.0"?>\n<html><body><p>hello</p></body></html>\n'
    if case == "unknown_joint":
        return re.sub(r"(</?)CustomJoint\b", r"\1FooJoint", text, count=2)
    if case == "missing_body":
        # the first path point of a muscle: attach it to a body that does not exist
        return text.replace("<socket_parent_frame>/bodyset/base</socket_parent_frame>",
                            "<socket_parent_frame>/bodyset/no_such_body</socket_parent_frame>", 1)
    if case == "negative_wrap_radius":
        start = text.index("<WrapCylinder")
        head, tail = text[:start], text[start:]
        return head + re.sub(r"<radius>\s*([0-9.eE+-]+)\s*</radius>", r"<radius>-\1</radius>",
                             tail, count=1)
    if case == "billion_laughs":
        entities = '<!ENTITY lol "lol">' + "".join(
            f'<!ENTITY lol{i} "{("&lol" + (str(i - 1) if i > 1 else "") + ";") * 10}">'
            for i in range(1, 10))
        return (f'<?xml version="1.0"?>\n<!DOCTYPE lolz [{entities}]>\n'
                '<OpenSimDocument Version="40000"><Model name="m">&lol9;</Model></OpenSimDocument>\n')
    raise AssertionError(case)


def _corrupt_motion(text, case):
    lines = text.splitlines()
    end = next(i for i, line in enumerate(lines) if line.strip() == "endheader")
    first = end + 2  # first data row (0-based)
    if case == "non_monotonic_time":
        lines[first + 3], lines[first + 4] = lines[first + 4], lines[first + 3]
        return "\n".join(lines) + "\n", first + 4 + 1
    if case == "nan":
        lines[first + 2] = re.sub(r"\S+$", "NaN", lines[first + 2])
        return "\n".join(lines) + "\n", first + 2 + 1
    if case == "text_in_number_column":
        lines[first + 1] = re.sub(r"\S+$", "abc", lines[first + 1])
        return "\n".join(lines) + "\n", first + 1 + 1
    if case == "ragged_row":
        lines[first + 5] = lines[first + 5].rsplit(None, 1)[0]
        return "\n".join(lines) + "\n", first + 5 + 1
    if case == "header_never_ends":
        del lines[end]
        return "\n".join(lines) + "\n", len(lines)
    if case == "no_coordinate_column":
        lines[end + 1] = "\t".join(["time"] + [f"col{k}" for k in range(len(lines[end + 1].split()) - 1)])
        return "\n".join(lines) + "\n", end + 2
    raise AssertionError(case)


MODEL_CASES = ["truncated_xml", "not_opensim", "unknown_joint", "missing_body",
               "negative_wrap_radius", "billion_laughs"]
MOTION_CASES = ["non_monotonic_time", "nan", "text_in_number_column", "ragged_row",
                "header_never_ends", "no_coordinate_column"]
FILE_CASES = ["empty", "missing", "binary"]

#: model-side checks that the reader does not make yet (strict: they must start failing to pass)
MODEL_XFAIL = {}


def _assert_one_line_error(code, err, path, out_dir, where=None):
    assert code == 2, err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert "Traceback" not in err
    assert path.name in err, err
    if where is not None:
        assert where in err, err
    # the message says what to do: more than "file: problem"
    assert len(err.split(path.name, 1)[1]) > 30, err
    assert not out_dir.exists() or list(out_dir.iterdir()) == []


@pytest.mark.parametrize("case", MODEL_CASES)
def test_bad_model_file(case, opensim_dir, tmp_path, capsys, request):
    if case in MODEL_XFAIL:
        request.applymarker(pytest.mark.xfail(strict=True, reason=MODEL_XFAIL[case]))
    bad = tmp_path / f"{case}.osim"
    bad.write_text(_corrupt_model((opensim_dir / "Arm26" / "arm26.osim").read_text(), case))
    out = tmp_path / "out"
    code, _, err = _run([bad, opensim_dir / "Arm26" / "arm26_elbow_flexion_sweep.mot",
                         "--out", out], capsys)
    _assert_one_line_error(code, err, bad, out)


@pytest.mark.parametrize("case", MOTION_CASES)
def test_bad_motion_file(case, opensim_dir, tmp_path, capsys):
    text = (opensim_dir / "Arm26" / "arm26_elbow_flexion_sweep.mot").read_text()
    content, line = _corrupt_motion(text, case)
    bad = tmp_path / f"{case}.mot"
    bad.write_text(content)
    out = tmp_path / "out"
    code, _, err = _run([opensim_dir / "Arm26" / "arm26.osim", bad, "--out", out], capsys)
    _assert_one_line_error(code, err, bad, out, where=f"line {line}")


@pytest.mark.parametrize("which", ["model", "motion"])
@pytest.mark.parametrize("case", FILE_CASES)
def test_empty_missing_binary_file(case, which, opensim_dir, tmp_path, capsys, request):
    if which == "model" and case in MODEL_XFAIL:
        request.applymarker(pytest.mark.xfail(strict=True, reason=MODEL_XFAIL[case]))
    model = opensim_dir / "Arm26" / "arm26.osim"
    motion = opensim_dir / "Arm26" / "arm26_elbow_flexion_sweep.mot"
    bad = tmp_path / ("bad.osim" if which == "model" else "bad.mot")
    if case == "empty":
        bad.write_bytes(b"")
    elif case == "binary":
        bad.write_bytes(bytes(range(256)) * 64)
    out = tmp_path / "out"
    argv = [bad, motion] if which == "model" else [model, bad]
    code, _, err = _run([*argv, "--out", out], capsys)
    _assert_one_line_error(code, err, bad, out)


# ------------------------------------------------------------------ LHDL hip vs live OpenSim


def test_lhdl_hip_flexion_matches_live_opensim(lhdl_dir, osim, tmp_path, capsys):
    model_file = lhdl_dir / "model" / "LHDL_hip_r.osim"
    motion_file = lhdl_dir / "model" / "motions" / "hip_flexion.mot"
    code, _, err = _run([model_file, motion_file, "--out", tmp_path, "--quiet"], capsys)
    assert code == 0, err
    warned = [line for line in err.splitlines() if "xRotation" in line]
    assert len(warned) == 1, err
    assert all(c in warned[0] for c in ("yRotation", "zRotation", "xTranslation", "zTranslation"))
    lines = pd.read_csv(tmp_path / "action_lines.csv")
    arms = pd.read_csv(tmp_path / "action_line_moment_arms.csv")

    # OpenSim 4.6 itself, posed as the AnalyzeTool does (setValue for every coordinate, then
    # assemble): motion columns in degrees for the rotational hip coordinates, pelvis defaults.
    osim.Logger.setLevelString("error")
    model = osim.Model(str(model_file))
    state = model.initSystem()
    coords = model.getCoordinateSet()
    storage = osim.Storage(str(motion_file))
    n_rows = storage.getSize()
    values = {}
    for name in ("hip_flexion_r", "hip_adduction_r", "hip_rotation_r"):
        column = osim.ArrayDouble()
        storage.getDataColumn(name, column)
        values[name] = np.radians([column.get(i) for i in range(n_rows)])
    muscles = [model.getMuscles().get(i) for i in range(model.getMuscles().getSize())]
    assert sorted(lines.muscle.unique()) == sorted(m.getName() for m in muscles)
    h = 1e-6
    for frame in range(0, n_rows, 5):
        for name in values:
            coords.get(name).setValue(state, float(values[name][frame]), False)
        model.assemble(state)
        model.realizePosition(state)
        ours_len = lines[lines.frame == frame].set_index("muscle").length
        ours_arm = arms[arms.frame == frame].set_index(["muscle", "coordinate"]).moment_arm
        for muscle in muscles:
            # No wrap objects in this model: lengths are closed-form, agree to round-off.
            assert ours_len[muscle.getName()] == pytest.approx(muscle.getLength(state), abs=1e-9)
            for name in values:
                coord = coords.get(name)
                q0 = coord.getValue(state)
                lengths = []
                for q in (q0 + h, q0 - h):
                    coord.setValue(state, q, False)
                    model.realizePosition(state)
                    lengths.append(muscle.getLength(state))
                coord.setValue(state, q0, False)
                model.realizePosition(state)
                neg_dldq = -(lengths[0] - lengths[1]) / (2 * h)
                # central difference h=1e-6: truncation ~h^2 L''' ~1e-13, round-off
                # ~eps L / h ~ 1e-10; OpenSim's computeMomentArm is exact here (no wrapping).
                ours = ours_arm[(muscle.getName(), name)]
                assert ours == pytest.approx(neg_dldq, abs=1e-7)
                assert ours == pytest.approx(muscle.computeMomentArm(state, coord), abs=1e-9)


def test_failure_while_writing_leaves_no_file(opensim_dir, tmp_path, capsys, monkeypatch):
    """The third table fails to write (disk full): none of the three files may be left."""
    real = pd.DataFrame.to_csv

    def failing(self, path, *args, **kwargs):
        if "action_line_moment_arms" in str(path):
            raise OSError(28, "No space left on device")
        return real(self, path, *args, **kwargs)

    monkeypatch.setattr(pd.DataFrame, "to_csv", failing)
    gait = opensim_dir / "Gait2392_Simbody"
    out = tmp_path / "out"
    code, _, err = _run([gait / "gait2392_thelen2003muscle.osim",
                         gait / "subject01_walk1_ik.mot", "--out", out,
                         "--frames", "0:3", "--quiet"], capsys)
    assert code == 1 and err.count("\n") == 1 and "No space left" in err
    assert not out.exists()  # created by this run, removed again (empty)
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "notes.txt").write_text("mine")
    code, _, _ = _run([gait / "gait2392_thelen2003muscle.osim",
                       gait / "subject01_walk1_ik.mot", "--out", kept,
                       "--frames", "0:3", "--quiet"], capsys)
    assert code == 1
    assert sorted(p.name for p in kept.iterdir()) == ["notes.txt"]


def test_first_run_says_it_compiles(tmp_path, capsys, monkeypatch):
    """An empty numba cache: the action lines' kernels compile for up to ~40 s; say so first."""
    from pathlib import Path

    from analysis import progress

    models = Path(__file__).resolve().parents[2] / "models"
    argv = ["lines", str(models / "arm_example.osim"), str(models / "elbow_flexion.mot"),
            "--frames", "0:2", "--out", str(tmp_path / "o")]
    monkeypatch.setattr(progress, "kernels_cached", lambda index_paths=None: False)
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert err.startswith("fibres lines: first run with this installation: compiling"), err
    monkeypatch.setattr(progress, "kernels_cached", lambda index_paths=None: True)
    assert main(argv) == 0 and "compiling" not in capsys.readouterr().err
    monkeypatch.setattr(progress, "kernels_cached", lambda index_paths=None: False)
    assert main([*argv, "--quiet"]) == 0 and capsys.readouterr().err == ""


def test_missing_spanned_coordinate_is_named_apart(lhdl_dir, tmp_path, capsys):
    """A LHDL hip motion without hip_flexion_r: glut_med1_r spans it, so a warning of its own says
    it stays at its default value; the pelvis coordinates nothing selected spans are listed apart."""
    mot = tmp_path / "hip.mot"
    mot.write_text("hip\nversion=1\ninDegrees=yes\nendheader\ntime\thip_adduction_r\thip_rotation_r\n"
                   "0\t0\t0\n0.1\t5\t0\n")
    code, _, err = _run([lhdl_dir / "model" / "LHDL_hip_r.osim", mot, "--muscle", "glut_med1_r",
                         "--out", tmp_path / "out", "--quiet"], capsys)
    assert code == 0, err
    warned = [line for line in err.splitlines() if "not in the file" in line]
    assert len(warned) == 2, err
    assert warned[0].endswith("paths span are not in the file, so they stay at their default "
                              "value in every frame: hip_flexion_r = 0 deg"), warned[0]
    assert "hip_flexion_r" not in warned[1] and "pelvis_tilt" in warned[1], warned[1]
    assert "no selected muscle path spans them" in warned[1]
