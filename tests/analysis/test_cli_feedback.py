"""Feedback of the command line away from a terminal: one progress line per muscle, warnings as
one line without Python source lines, no empty output folder after a failed run, the bundled
example found as package data."""
from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from analysis import cli, cli_run
from analysis.progress import progress

ROOT = Path(__file__).resolve().parents[2]


def test_progress_lines_per_muscle_when_not_a_terminal(capsys, monkeypatch):
    monkeypatch.delenv("FIBRES_PROGRESS", raising=False)
    for _ in progress(["a", "b", "c"], desc="plots", unit="muscle"):
        pass
    err = capsys.readouterr().err.splitlines()      # pytest's stderr is not a terminal
    assert len(err) == 3 and err[0].startswith("fibres: plots: 1/3 muscles (") and "3/3" in err[2]
    bar = progress(total=2, desc="wrap + fibres", unit="muscle")
    bar.update(1)
    assert "wrap + fibres: 1/2 muscles" in capsys.readouterr().err
    for _ in progress(range(50), desc="frames", unit="frame"):   # per-frame counters stay silent
        pass
    assert capsys.readouterr().err == ""
    for _ in progress(["a"], desc="plots", unit="muscle", quiet=True):
        pass
    assert capsys.readouterr().err == ""


def test_warnings_are_one_line_without_source(capsys, monkeypatch):
    class Loud:
        @staticmethod
        def execute(args):
            warnings.warn("first   problem\nsecond line", UserWarning)
            warnings.warn("first   problem\nsecond line", UserWarning)   # once only
            return 0

    parser = cli.build_parser()
    args = parser.parse_args(["lines", "m.osim", "x.mot"])
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    monkeypatch.setattr(parser, "parse_args", lambda argv=None: args)
    args._module = Loud
    saved = warnings.showwarning
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert cli.main([]) == 0
    err = capsys.readouterr().err
    assert err == "fibres lines: warning: first problem second line\n"
    assert warnings.showwarning is saved            # restored after the command


def test_failed_run_leaves_no_empty_output_folder(tmp_path, capsys):
    out = tmp_path / "new-out"
    code = cli.main(["run", str(ROOT / "models" / "arm_example.toml"), "--out", str(out), "--quiet",
                     "--frames", "500:600"])
    assert code == 2 and "frame" in capsys.readouterr().err
    assert not out.exists()
    # a folder that existed before is left as it was
    out.mkdir()
    (out / "keep.txt").write_text("x")
    assert cli.main(["run", str(ROOT / "models" / "arm_example.toml"), "--out", str(out), "--quiet",
                     "--frames", "500:600"]) == 2
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


def test_default_spec_falls_back_to_the_package_data(tmp_path, monkeypatch):
    """An installed (non-editable) package has no models/ beside it: the example is found in
    analysis/example/, where pyproject.toml installs it."""
    import analysis

    fake = tmp_path / "site" / "analysis"
    (fake / "example").mkdir(parents=True)
    (fake / "example" / "arm_example.toml").write_text("")
    monkeypatch.setattr(analysis, "__file__", str(fake / "__init__.py"))
    assert cli_run.default_spec() == fake / "example" / "arm_example.toml"
    (fake / "example" / "arm_example.toml").unlink()
    with pytest.raises(Exception, match="bundled example"):
        cli_run.default_spec()
    text = (ROOT / "pyproject.toml").read_text()
    assert '"analysis.example" = "models"' in text


def test_start_notice(capsys):
    from analysis.progress import start_notice

    assert start_notice("working", compiling=False) is True
    assert capsys.readouterr().err == "fibres: working\n"
    assert start_notice("working", quiet=True) is False and capsys.readouterr().err == ""


def test_first_run_says_it_compiles(capsys, tmp_path):
    """An empty numba cache cost the bundled example 38 s of silence after its first line."""
    from analysis.progress import kernels_cached, start_notice

    index = tmp_path / "k.nbi"
    assert kernels_cached([index]) is False
    index.write_bytes(b"")
    assert kernels_cached([index]) is True
    start_notice("working", compiling=True)
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "fibres: working" and "compiling" in err[1] and len(err) == 2


def test_run_prints_the_action_lines_stage(tmp_path, capsys):
    from analysis import run

    run(ROOT / "models" / "arm_example.toml", frames="0:3", fibres=8, resolution=6, quiet=False,
        muscles=["brachialis"])
    err = capsys.readouterr().err
    assert "fibres: action lines: 1 paths, 3 frames (" in err, err
    from analysis.progress import kernels_cached

    assert kernels_cached() is True           # the run compiled the action lines' kernel and cached it
    run(ROOT / "models" / "arm_example.toml", frames="0:3", fibres=8, resolution=6, quiet=True,
        muscles=["brachialis"])
    assert capsys.readouterr().err == ""
