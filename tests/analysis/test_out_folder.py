"""Issue 16, the output folder is owned by the run: refused folders, the lock against concurrent
runs, the manifest and the removal of an earlier run's files, stale staging, and Ctrl-C (exit 130,
previous outputs intact) also when a library swallows the KeyboardInterrupt and with --jobs 2."""
from __future__ import annotations

import importlib
import json
import os
import shutil
import signal
import time
from pathlib import Path

import pytest

from analysis import cli
from analysis.out_folder import JOURNAL_NAME, LOCK_NAME, OutFolderLock, refusal

run_module = importlib.import_module("analysis.run")
out_folder = importlib.import_module("analysis.out_folder")
MODELS = Path(__file__).resolve().parents[2] / "models"
SMALL = ["--fibres", "8", "--resolution", "6", "--quiet"]


@pytest.fixture()
def example(tmp_path):
    if not (MODELS / "arm_example.toml").is_file():
        pytest.skip("the bundled example model is not in this checkout")
    dst = tmp_path / "models"
    shutil.copytree(MODELS, dst, ignore=shutil.ignore_patterns("*.py", "*.log", "__pycache__"))
    return dst


def _run(example, out, *extra):
    return cli.main(["run", str(example / "arm_example.toml"), "--out", str(out), *SMALL, *extra])


def _files(out: Path) -> dict:
    return {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


def _manifest_matches(out: Path):
    record = json.loads((out / "run.json").read_text())
    assert sorted(record["files"]) == sorted(_files(out)), "the folder holds exactly the manifest"
    return record


# ----------------------------------------------------------------- refused folders
def test_refused_folders(tmp_path, monkeypatch):
    assert "root" in refusal("/")
    monkeypatch.setenv("HOME", str(tmp_path))
    assert "home" in refusal(tmp_path)
    (tmp_path / "repo" / ".git").mkdir(parents=True)
    assert "git" in refusal(tmp_path / "repo")
    (tmp_path / "proj" / "fibres").mkdir(parents=True)
    (tmp_path / "proj" / "fibres" / "__init__.py").write_text("")
    assert "fibres/" in refusal(tmp_path / "proj")
    assert "package" in refusal(tmp_path / "proj" / "fibres")
    (tmp_path / "py").mkdir()
    (tmp_path / "py" / "pyproject.toml").write_text("")
    assert "pyproject.toml" in refusal(tmp_path / "py")
    assert refusal(tmp_path / "new") is None and refusal(tmp_path / "repo" / "out") is None


def test_root_home_and_project_are_refused_unless_forced(example, tmp_path, capsys, monkeypatch):
    for out in ("/", str(Path.home())):
        assert _run(example, out) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--force" in err[0], err
    project = tmp_path / "project"
    (project / "fibres").mkdir(parents=True)
    (project / "fibres" / "__init__.py").write_text("")
    assert _run(example, project, "--frames", "0:2") == 2
    assert "holds the Python package fibres/" in capsys.readouterr().err
    assert sorted(p.name for p in project.iterdir()) == ["fibres"]
    assert _run(example, project, "--frames", "0:2", "--no-plots", "--force") == 0
    assert (project / "run.json").is_file() and (project / "fibres" / "__init__.py").read_text() == ""


def test_fibres_lines_refuses_them_too(example, tmp_path, capsys):
    project = tmp_path / "project"
    (project / ".git").mkdir(parents=True)
    code = cli.main(["lines", str(example / "arm_example.osim"), str(example / "elbow_flexion.mot"),
                     "--out", str(project), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "git repository" in err[0] and "--force" in err[0]
    assert [p.name for p in project.iterdir()] == [".git"]
    assert cli.main(["lines", str(example / "arm_example.osim"), str(example / "elbow_flexion.mot"),
                     "--out", str(project), "--quiet", "--force"]) == 0
    assert (project / "action_lines.csv").is_file() and not (project / LOCK_NAME).exists()


# ----------------------------------------------------------------- one run at a time
def test_second_run_into_a_busy_folder_refuses_at_once(example, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.setattr(run_module, "run_muscle", lambda *a, **k: pytest.fail("work started"))
    with OutFolderLock(out):              # the first run, still working
        t0 = time.perf_counter()
        code = _run(example, out)
        elapsed = time.perf_counter() - t0
        err = capsys.readouterr().err.strip().splitlines()
        assert (out / LOCK_NAME).is_file()
    assert code == 2 and len(err) == 1
    assert f"another fibres run (process {os.getpid()}) is writing into this folder" in err[0]
    assert elapsed < 2.0, elapsed         # before loading the model
    assert list(out.iterdir()) == []      # the holder removed its lock; nothing else was written


def test_lock_is_exclusive_and_released(tmp_path):
    from analysis.errors import InputError

    with OutFolderLock(tmp_path):
        with pytest.raises(InputError, match="another fibres run"):
            OutFolderLock(tmp_path).acquire()
    with OutFolderLock(tmp_path):          # free again
        pass
    assert not (tmp_path / LOCK_NAME).exists()


# ----------------------------------------------------------------- manifest, reruns, debris
def test_smaller_rerun_leaves_nothing_of_the_old_run(example, tmp_path, capsys):
    out = tmp_path / "out"
    assert _run(example, out, "--frames", "0:27:13", "--sto") == 0
    first = _manifest_matches(out)
    assert "fibres/triceps_0002.vtp" in first["files"] and "plots/biceps_lengths.png" in first["files"]
    (out / "notes.txt").write_text("mine")                       # the user's own file
    (out / "plots" / "my_figure.png").write_bytes(b"mine")
    assert _run(example, out, "--frames", "0:2", "--muscle", "brachialis", "--no-sto") == 0
    second = json.loads((out / "run.json").read_text())
    left = set(_files(out)) - {"notes.txt", "plots/my_figure.png"}
    assert left == set(second["files"])                           # no file of the old run survives
    assert not (out / "fibres" / "biceps.pvd").exists() and not (out / "MuscleAnalysis_Length.sto").exists()
    assert (out / "notes.txt").read_text() == "mine" and (out / "plots" / "my_figure.png").exists()
    pvd = (out / "fibres" / "brachialis.pvd").read_text()
    assert pvd.count("<DataSet") == 2                             # the .pvd matches the tables
    assert not [p for p in out.rglob(".*")]                       # no lock, journal or staging


def test_debris_of_killed_runs_is_cleaned(example, tmp_path):
    out = tmp_path / "out"
    assert _run(example, out, "--frames", "0:27:13") == 0
    # a SIGKILL'd run: its staging folder, a temporary file, its lock, and a publishing journal
    # that lists a file it had already moved into place
    (out / ".fibres-run-dead1234" / "plots").mkdir(parents=True)
    (out / ".fibres-run-dead1234" / "plots" / "x.png").write_bytes(b"half")
    (out / ".summary.csv.abcd1234.part").write_text("half")
    (out / LOCK_NAME).write_text("99999\n")
    (out / "fibres" / "biceps_0099.vtp").write_text("from the killed run")
    (out / JOURNAL_NAME).write_text(json.dumps({"files": ["fibres/biceps_0099.vtp", "../outside.txt"]}))
    (tmp_path / "outside.txt").write_text("not ours")
    assert _run(example, out, "--frames", "0:2") == 0
    _manifest_matches(out)
    assert not [p for p in out.rglob(".*")]
    assert (tmp_path / "outside.txt").read_text() == "not ours"   # never outside --out


# ----------------------------------------------------------------- Ctrl-C
def _swallowing(real, *, in_thread=False):
    """A stage during which Ctrl-C arrives and a third-party ``except BaseException`` swallows
    it (the run used to finish with exit 0)."""
    def stage(ctx, mspec):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.5)                     # the handler raises here (main thread)
        except BaseException:                   # noqa: BLE001 - the third party's bug
            pass
        return real(ctx, mspec)
    return stage


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_swallowed_ctrl_c_still_exits_130_and_keeps_the_previous_outputs(example, tmp_path, capsys,
                                                                         monkeypatch, jobs):
    out = tmp_path / "out"
    assert _run(example, out, "--frames", "0:27:13") == 0
    before = _files(out)
    monkeypatch.setattr(run_module, "run_muscle", _swallowing(run_module.run_muscle))
    code = _run(example, out, "--frames", "0:2", "--jobs", jobs)
    err = capsys.readouterr().err
    assert code == 130, err
    assert "Traceback" not in err and err.strip().splitlines()[-1].endswith("no partial output was left.")
    assert _files(out) == before                                   # previous outputs intact


def test_ctrl_c_while_publishing_completes_the_new_set_then_exits_130(example, tmp_path, capsys,
                                                                       monkeypatch):
    out = tmp_path / "out"
    assert _run(example, out, "--frames", "0:27:13") == 0
    calls = []
    real_replace = os.replace

    def replace(src, dst):                     # (os.replace also renames files inside staging)
        if ".fibres-run-" in str(src) and ".fibres-run-" not in str(dst):
            calls.append(dst)                  # moving a finished file into place
        if len(calls) == 3 and not calls[-1] is None:
            calls.append(None)
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.2)                    # held back: publishing goes on
        return real_replace(src, dst)

    monkeypatch.setattr(out_folder.os, "replace", replace)
    code = _run(example, out, "--frames", "0:2", "--muscle", "biceps")
    assert code == 130, capsys.readouterr().err
    record = _manifest_matches(out)                                # all of the new run, none of the old
    assert record["frames"]["count"] == 2 and list(record["muscles"]) == ["biceps"]
    assert not (out / JOURNAL_NAME).exists()


# ----------------------------------------------------------------- Ctrl-C of the real process
@pytest.mark.skipif(os.name != "posix", reason="sends SIGINT to a child process")
@pytest.mark.parametrize("delay", [0.15, 1.5])
def test_ctrl_c_early_in_the_process_exits_130_without_traceback(example, tmp_path, delay):
    """SIGINT while the packages load (0.15 s: it used to print a traceback from inside an
    import, or "module 'motion' has no attribute 'errors'") and while the inputs load (1.5 s)."""
    import subprocess
    import sys

    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(MODELS.parent))
    proc = subprocess.Popen([sys.executable, "-m", "analysis.cli", "run", str(example / "arm_example.toml"),
                             "--out", str(out), "--quiet"], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    time.sleep(delay)
    assert proc.poll() is None, "the run ended before its signal"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    text = err.decode()
    assert proc.returncode == 130, text
    assert "Traceback" not in text and len(text.strip().splitlines()) == 1, text
    assert not out.exists() or [p.name for p in out.iterdir()] == []


# ----------------------------------------------------------------- plots in worker processes
def test_plots_drawn_in_worker_processes_equal_the_ones_drawn_here(example, tmp_path, monkeypatch):
    """From `cli_run.PARALLEL_PLOTS_FROM` muscles on, the plots are drawn by spawned worker
    processes while the tables are written: the same PNG files, pixel for pixel (the same
    matplotlib Agg renderer and inputs), as when this process draws them, and both runs' folders
    hold exactly their manifests."""
    import numpy as np
    from matplotlib import image

    cli_run = importlib.import_module("analysis.cli_run")
    here, workers = tmp_path / "here", tmp_path / "workers"
    monkeypatch.setattr(cli_run, "PARALLEL_PLOTS_FROM", float("inf"))
    assert _run(example, here, "--frames", "0:27:13", "--no-sto", "--no-scene") == 0
    monkeypatch.setattr(cli_run, "PARALLEL_PLOTS_FROM", 1)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)       # two workers even on a one-core runner
    import concurrent.futures

    pools = []

    class CountedPool(concurrent.futures.ProcessPoolExecutor):
        def __init__(self, *a, **k):
            pools.append(k.get("max_workers"))
            super().__init__(*a, **k)

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", CountedPool)
    assert _run(example, workers, "--frames", "0:27:13", "--no-sto", "--no-scene") == 0
    assert pools == [2]                                     # the plots went to two workers
    token = cli_run.PLOTS_IN_THIS_PROCESS.set(True)          # as a study's trial sets it
    try:
        assert _run(example, tmp_path / "trial", "--frames", "0:27:13", "--no-sto", "--no-scene") == 0
    finally:
        cli_run.PLOTS_IN_THIS_PROCESS.reset(token)
    assert pools == [2]                                     # no pool inside a trial
    _manifest_matches(here)
    _manifest_matches(workers)
    pngs = sorted(p.relative_to(here) for p in (here / "plots").glob("*.png"))
    assert len(pngs) >= 3 * 3           # three muscles, three plots each
    assert pngs == sorted(p.relative_to(workers) for p in (workers / "plots").glob("*.png"))
    for rel in pngs:
        np.testing.assert_array_equal(image.imread(here / rel), image.imread(workers / rel), err_msg=str(rel))
