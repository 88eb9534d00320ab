"""`fibres study` / `analysis.study`: the study file, tables equal to single `fibres run`s, resume
(skip, rerun on a changed input), failure isolation, the Dask LocalCluster and a lost worker.

Small on purpose: the bundled arm (two of its muscles, 6 fibres x 4 segments) over 3-row pieces of
its motion, two subjects; the process-pool engine everywhere, Dask where installed."""
from __future__ import annotations

import filecmp
import os
import shutil
import signal
import threading
import time
from pathlib import Path

import pytest

from analysis.errors import InputError
from analysis.study_file import load_study, run_arguments

ROOT = Path(__file__).resolve().parents[2]
ARM = ROOT / "models" / "arm_example.toml"
MOTION = ROOT / "models" / "elbow_flexion.mot"
TABLES = ("fibre_lengths", "fibre_moment_arms", "action_lines", "action_line_moment_arms", "summary",
          "fibre_quality")


def _sub_motion(dst: Path, rows) -> Path:
    lines = MOTION.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if ln.strip() == "endheader")
    data = lines[end + 2:]
    head = [f"nRows={len(rows)}" if ln.startswith("nRows=") else ln for ln in lines[:end + 1]]
    dst.write_text("\n".join(head + [lines[end + 1]] + [data[r] for r in rows]) + "\n")
    return dst


def _write_study(folder: Path) -> Path:
    (folder / "A").mkdir(parents=True, exist_ok=True)
    (folder / "B").mkdir(exist_ok=True)
    for k, name in enumerate(("early", "mid", "late")):
        _sub_motion(folder / "A" / f"{name}.mot", range(8 * k, 8 * k + 3))
    _sub_motion(folder / "B" / "walk1.mot", range(0, 6, 2))
    _sub_motion(folder / "B" / "walk2.mot", range(10, 16, 2))
    study = folder / "study.toml"
    study.write_text(f"""
[options]
fibres = 6
resolution = 4
muscle = ["biceps", "brachialis"]
plots = false
no-scene = true
no-sto = true

[subjects.A]
model = "{ARM}"
trials = ["A/*.mot", {{ motion = "A/late.mot", options = {{ frames = "1:3", fibres = 7 }} }}]

[subjects.B]
model = "{ARM}"
trials = ["B/*.mot"]
options = {{ fibres = 5 }}
""")
    return study


def _single_run(trial, out: Path) -> Path:
    """`fibres run` of one trial, in this process, with the trial's options."""
    from analysis.cli import main

    argv = ["run", str(trial.spec), "--motion", str(trial.motion), "--out", str(out), "--quiet",
            "--fibres", str(trial.options["fibres"]), "--resolution", "4", "--muscle", "biceps",
            "--muscle", "brachialis", "--no-plots", "--no-scene", "--no-sto"]
    assert main(argv) == 0
    return out


def _differing(a: Path, b: Path) -> list:
    return [t for t in TABLES if not filecmp.cmp(a / f"{t}.csv", b / f"{t}.csv", shallow=False)]


@pytest.fixture(scope="module")
def pool_study(tmp_path_factory):
    """The study run once by the command line with the process pool, subject B with a broken
    motion: (study file, output folder, exit status, stdout, stderr)."""
    import contextlib
    import io

    from analysis.cli import main

    base = tmp_path_factory.mktemp("study")
    study_file = _write_study(base / "in")
    (base / "in" / "B" / "broken.mot").write_text("not a motion\n1 2 3\n")
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["study", str(study_file), "--out", str(base / "out"), "--engine", "processes",
                     "--workers", "2"])
    return study_file, base / "out", code, out.getvalue(), err.getvalue()


def _good_trials(study_file):
    return [t for t in load_study(study_file).trials if t.trial != "broken"]


# ------------------------------------------------------------------------------ the study file
def test_study_file_trials_names_and_options(tmp_path):
    s = load_study(_write_study(tmp_path))
    assert s.subjects == ("A", "B")
    assert [t.label for t in s.trials] == ["A/early", "A/late", "A/mid", "B/walk1", "B/walk2"]
    a, b = s.trials[0], s.trials[-1]
    assert a.options["fibres"] == 6
    assert a.options["no_plots"] is True and a.options["sto"] is False and a.options["no_scene"] is True
    assert a.options["muscle"] == ["biceps", "brachialis"]
    assert b.options["fibres"] == 5 and b.options["resolution"] == 4   # subject over study options
    assert b.folder == "B/walk2" and b.motion == (tmp_path / "B" / "walk2.mot").resolve()
    late = s.trials[1]                      # named by the glob, then by a table of its own
    assert late.label == "A/late" and late.options["frames"] == "1:3" and late.options["fibres"] == 7
    assert late.options["resolution"] == 4 and "frames" not in s.trials[0].options
    assert run_arguments(late, tmp_path).frames.start == 1 and run_arguments(late, tmp_path).frames.stop == 3


@pytest.mark.parametrize("text, where", [
    ('[options]\nfibers = 5\n[subjects.A]\nmodel = "{arm}"\ntrials = ["A/*.mot"]', "options.fibers"),
    ('[options]\nfibres = "many"\n[subjects.A]\nmodel = "{arm}"\ntrials = ["A/*.mot"]', "options.fibres"),
    ('[options]\nfibres = 200000\n[subjects.A]\nmodel = "{arm}"\ntrials = ["A/*.mot"]', "options.fibres"),
    ('[options]\nslicing = "cubes"\n[subjects.A]\nmodel = "{arm}"\ntrials = ["A/*.mot"]', "options.slicing"),
    ('[options]\nno-plots = 1\n[subjects.A]\nmodel = "{arm}"\ntrials = ["A/*.mot"]', "options.no-plots"),
    ('[options]\nframes = "a:b"\n[subjects.A]\nmodel = "{arm}"\ntrials = ["A/*.mot"]', "options.frames"),
    ('[options]\nmotion = "x.mot"\n[subjects.A]\nmodel = "{arm}"\ntrials = ["A/*.mot"]', "options.motion"),
    ('[subjects.A]\nmodel = "nope.toml"\ntrials = ["A/*.mot"]', "subjects.A.model"),
    ('[subjects.A]\nmodel = "{arm}"\ntrials = ["A/*.sto"]', "subjects.A.trials"),
    ('[subjects.A]\nmodel = "{arm}"\ntrials = ["A/missing.mot"]', "subjects.A.trials"),
    ('[subjects.A]\nmodel = "{arm}"\ntrials = ["A/early.mot", "B/early.mot"]', "subjects.A.trials"),
    ('[subjects.A]\nmodel = "{arm}"\ntrial = ["A/*.mot"]', "subjects.A.trial"),
    ('[subjects."study.json"]\nmodel = "{arm}"\ntrials = ["A/*.mot"]', "subjects.study.json"),
    ('[options]\nfibres = 5\n', "subjects"),
    ('[subjects.A]\nmodel = "{arm}"\ntrials = [{{ options = {{ fibres = 5 }} }}]', "subjects.A.trials[0].motion"),
    ('[subjects.A]\nmodel = "{arm}"\ntrials = ["A/*.mot", {{ motion = "A/early.mot", option = {{}} }}]',
     "subjects.A.trials[1].option"),
    ('[subjects.A]\nmodel = "{arm}"\ntrials = ["A/*.mot", {{ motion = "A/early.mot", options = {{ frames = "9:2" }} }}]',
     "subjects.A.trials[1].options.frames"),
    ('[subjects.A]\nmodel = "{arm}"\ntrials = [{{ motion = "A/nope*.mot" }}]', "subjects.A.trials[0]"),
    ('[subjects.A]\nmodel = "{arm}"\ntrials = [3]', "subjects.A.trials[0]"),
])
def test_study_file_errors_are_one_line_naming_the_key(tmp_path, text, where):
    _write_study(tmp_path)
    _sub_motion(tmp_path / "B" / "early.mot", range(3))
    bad = tmp_path / "bad.toml"
    bad.write_text(text.format(arm=ARM))
    with pytest.raises(InputError) as err:
        load_study(bad)
    msg = str(err.value)
    assert "\n" not in msg and str(bad) in msg and where in msg


# ------------------------------------------------------------------------- running and resuming
def test_a_broken_motion_is_reported_and_the_others_finish(pool_study):
    study_file, out, code, printed, err = pool_study
    assert code == 2
    rows = {tuple(ln.split()[:2]): ln.split()[2] for ln in printed.splitlines()[1:7]}
    assert rows == {("A", "early"): "ok", ("A", "late"): "ok", ("A", "mid"): "ok", ("B", "walk1"): "ok",
                    ("B", "walk2"): "ok", ("B", "broken"): "failed"}
    line = next(ln for ln in printed.splitlines() if ln.split()[:2] == ["B", "broken"])
    assert "broken.mot" in line                       # the one-line error names the file
    assert "fibres study: [" in err and "B/broken: failed" in err
    assert "local process pool, 2 workers" in err
    assert not (out / "B" / "broken").exists()        # nothing half-written
    assert not (out / "study.parquet" / "fibre_lengths" / "subject=B" / "trial=broken").exists()


def test_trials_equal_single_runs_and_fill_the_dataset(pool_study, tmp_path):
    import pandas as pd

    study_file, out, *_ = pool_study
    for trial in [t for t in _good_trials(study_file) if t.label in ("A/mid", "B/walk2")]:
        single = _single_run(trial, tmp_path / trial.folder)
        assert _differing(out / trial.folder, single) == [], trial.label
        # every file `fibres run` writes, and nothing else
        assert sorted(p.name for p in (out / trial.folder).iterdir()) == \
            sorted(p.name for p in single.iterdir())
    data = pd.read_parquet(out / "study.parquet" / "fibre_lengths")
    assert set(zip(data.subject.astype(str), data.trial.astype(str))) == {
        ("A", "early"), ("A", "mid"), ("A", "late"), ("B", "walk1"), ("B", "walk2")}
    # the trial with its own frames (rows 1 and 2 of its motion: frames 0 and 1 of the rows
    # used) and fibres
    late = data[(data.subject == "A") & (data.trial == "late")]
    rows = (study_file.parent / "A" / "late.mot").read_text().split("endheader")[1].splitlines()[2:]
    times = [float(r.split()[0]) for r in rows if r.strip()]
    assert sorted(late.frame.unique()) == [0, 1] and late.fibre.nunique() == 7
    assert sorted(late.time.unique()) == pytest.approx(times[1:3])
    early = data[(data.subject == "A") & (data.trial == "early")]
    assert sorted(early.frame.unique()) == [0, 1, 2] and early.fibre.nunique() == 6
    one = data[(data.subject == "B") & (data.trial == "walk2")].drop(columns=["subject", "trial"])
    own = pd.read_parquet(out / "B" / "walk2" / "fibre_lengths.parquet")
    pd.testing.assert_frame_equal(one.reset_index(drop=True), own)


def test_rerun_skips_and_a_changed_motion_reruns_only_its_trial(pool_study):
    from analysis.study import study

    study_file, out, *_ = pool_study
    (study_file.parent / "B" / "broken.mot").unlink()   # the failed trial leaves the study
    t0 = time.perf_counter()
    again = study(study_file, out, engine="processes", workers=2)
    assert time.perf_counter() - t0 < 5.0
    assert {t.status for t in again.trials} == {"skipped"} and len(again.trials) == 5
    motion = study_file.parent / "A" / "mid.mot"
    os.utime(motion)                                  # touched, same bytes: still up to date
    assert {t.status for t in study(study_file, out, engine="processes").trials} == {"skipped"}
    before = (out / "A" / "mid" / "fibre_lengths.csv").read_bytes()
    motion.write_text(motion.read_text().replace("\t40.0000000000", "\t41.0000000000"))
    third = study(study_file, out, engine="processes", workers=1)
    assert {f"{t.subject}/{t.trial}": t.status for t in third.trials} == {
        "A/early": "skipped", "A/mid": "ok", "A/late": "skipped", "B/walk1": "skipped", "B/walk2": "skipped"}
    assert (out / "A" / "mid" / "fibre_lengths.csv").read_bytes() != before
    assert (out / "study.parquet" / "fibre_lengths" / "subject=A" / "trial=mid" / "part-0.parquet").read_bytes() \
        == (out / "A" / "mid" / "fibre_lengths.parquet").read_bytes()


# ---------------------------------------------------------------------------------------- Dask
def test_dask_local_cluster_survives_a_killed_worker_with_the_same_tables(pool_study, tmp_path):
    """The default engine (a LocalCluster of 2 worker processes); one worker is killed (SIGKILL)
    while a trial is being written: the study completes with the tables of the process pool."""
    pytest.importorskip("distributed")
    import psutil

    from analysis.study import study

    study_file, pool_out, *_ = pool_study
    text = study_file.read_text()          # subject A only (3 trials), to keep the test short
    only_a = study_file.with_name("study_a.toml")
    only_a.write_text(text[:text.index("[subjects.B]")])
    box, lines = {}, []
    runner = threading.Thread(target=lambda: box.setdefault(
        "report", study(only_a, tmp_path / "out", workers=2, quiet=False, log=lines.append)))
    runner.start()
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline and not any(
            p.name.startswith(".fibres-run-") for p in (tmp_path / "out").glob("*/*/*")):
        time.sleep(0.02)
    workers = [p for p in psutil.Process().children(recursive=True)
               if "spawn_main" in " ".join(p.cmdline()) and "resource_tracker" not in " ".join(p.cmdline())]
    assert workers, "no worker process found"
    os.kill(workers[0].pid, signal.SIGKILL)
    runner.join(timeout=180)
    report = box["report"]
    assert report.engine == "dask" and not report.failed, report.table()
    assert any("LocalCluster, 2 workers; dashboard:" in ln for ln in lines)
    assert len(report.trials) == 3
    for trial in load_study(only_a).trials:
        assert _differing(tmp_path / "out" / trial.folder, pool_out / trial.folder) == [], trial.label
        assert not [p for p in (tmp_path / "out" / trial.folder).iterdir() if p.name.startswith(".")]
    shutil.rmtree(tmp_path / "out")


def test_without_dask_the_pool_is_used_and_said(monkeypatch):
    import importlib

    study_module = importlib.import_module("analysis.study")
    from analysis.errors import MissingDependencyError

    monkeypatch.setattr(study_module, "dask_available", lambda: False)
    said = []
    assert study_module._choose_engine(None, None, said.append) == "processes"
    assert "Dask is not installed" in said[0] and "musclefibres[dask]" in said[0]
    with pytest.raises(MissingDependencyError, match=r"musclefibres\[dask\]"):
        study_module._choose_engine(None, "tcp://127.0.0.1:8786", said.append)
    with pytest.raises(InputError, match="--engine"):
        study_module._choose_engine("threads", None, said.append)


@pytest.mark.parametrize("option", [["--scheduler", "tcp://127.0.0.1:8786"], ["--engine", "dask"]])
def test_cli_without_dask_asked_for_dask_is_one_line_exit_2(tmp_path, monkeypatch, capsys, option):
    """A Dask option without Dask installed is the user's setup, not an internal failure: exit 2
    (docs/INTERFACE.md, "Errors"), one line naming the extra, before any trial runs."""
    import importlib

    from analysis.cli import main

    study_module = importlib.import_module("analysis.study")
    monkeypatch.setattr(study_module, "dask_available", lambda: False)
    study = _write_study(tmp_path)
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--quiet"] + option) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error" in ln]
    assert len(err) == 1 and "internal" not in err[0] and "musclefibres[dask]" in err[0], err
    assert not (tmp_path / "out" / "study.json").exists()
