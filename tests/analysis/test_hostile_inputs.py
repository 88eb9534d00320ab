"""Issue 16, hostile inputs through `fibres run` (`analysis.cli.main`): names from input files never
become paths, wrongly typed TOML values and damaged files are one-line errors (exit 2), caps and
the memory budget refuse with the reason, and nothing is ever written outside ``--out``."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from analysis import cli

MODELS = Path(__file__).resolve().parents[2] / "models"
SMALL = ["--frames", "0:27:13", "--fibres", "8", "--resolution", "6", "--quiet"]


@pytest.fixture()
def example(tmp_path):
    if not (MODELS / "arm_example.toml").is_file():
        pytest.skip("the bundled example model is not in this checkout")
    dst = tmp_path / "models"
    shutil.copytree(MODELS, dst, ignore=shutil.ignore_patterns("*.py", "*.log", "__pycache__"))
    return dst


def _tree(root: Path) -> set:
    return {p.relative_to(root).as_posix() for p in root.rglob("*")}


def _fails(capfd, argv, *must):
    code = cli.main(argv)
    err = capfd.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err          # capfd: also VTK's own C++ output would show here
    assert "Traceback" not in err
    for text in must:
        assert text in lines[0], lines[0]
    return lines[0]


def _edit(toml: Path, old: str, new: str):
    text = toml.read_text()
    assert old in text, old
    toml.write_text(text.replace(old, new, 1))


# ----------------------------------------------------------------- names never become paths
def test_muscle_name_with_parent_references_stays_inside_out(example, tmp_path, capfd):
    toml = example / "arm_example.toml"
    _edit(toml, "[muscles.biceps]", '[muscles."../../../pwned"]')
    before = _tree(tmp_path)
    out = tmp_path / "a" / "b" / "out"
    code = cli.main(["run", str(toml), "--out", str(out), "--sto", *SMALL])
    assert code == 0, capfd.readouterr().err
    outside = {p for p in _tree(tmp_path) - before if p not in ("a", "a/b") and not p.startswith("a/b/out")}
    assert outside == set()                                   # nothing beside or above --out
    assert not list(tmp_path.parent.glob("pwned*")) and not list(tmp_path.glob("**/pwned.pvd"))
    record = json.loads((out / "run.json").read_text())
    stem = record["file_names"]["muscles"]["../../../pwned"]
    assert stem == "pwned-55d4ac58"
    assert record["file_names"]["muscles"]["brachialis"] == "brachialis"
    assert (out / "fibres" / f"{stem}.pvd").is_file() and (out / "plots" / f"{stem}_lengths.png").is_file()
    assert sorted(record["files"]) == sorted(p for p in _tree(out) if (out / p).is_file())
    import pandas as pd

    assert "../../../pwned" in set(pd.read_csv(out / "fibre_lengths.csv").muscle)   # the name itself


def test_every_output_path_is_checked_against_the_staging_folder(tmp_path):
    from analysis.errors import InputError
    from analysis.output_files import confined_to, write_text

    (tmp_path / "stage").mkdir()
    with confined_to(tmp_path / "stage"):
        write_text("ok", tmp_path / "stage" / "a.txt")
        with pytest.raises(InputError, match="outside the output folder"):
            write_text("no", tmp_path / "stage" / ".." / "escaped.txt")
        with pytest.raises(InputError, match="same file"):
            write_text("twice", tmp_path / "stage" / "a.txt")
    assert not (tmp_path / "escaped.txt").exists()


def test_file_stems_are_safe_unique_and_keep_ordinary_names():
    from analysis.file_names import file_stems, is_safe_stem

    names = ["biceps", "Biceps", "../../../pwned", "a/b", "a_b", "CON", "", ".", "x" * 300, "é", "a b"]
    stems = file_stems(names)
    assert stems["biceps"] == "biceps" and stems["a_b"] == "a_b"
    assert all(is_safe_stem(s) for s in stems.values())
    assert len({s.lower() for s in stems.values()}) == len(names)       # unique, ignoring case
    assert file_stems(names) == stems                                    # deterministic


# ----------------------------------------------------------------- TOML values type-checked
@pytest.mark.parametrize("old,new,where", [
    ('units = "m"', "units = []", "units"),
    ("[defaults]\n", "[defaults]\nunits = {}\n", "defaults.units"),
    ('action_lines = ["BRA"]', "action_lines = [{}]", "muscles.brachialis.action_lines[0]"),
    ('origin = { body = "humerus", file = "biceps_origin.csv" }',
     'origin = { body = "humerus", file = "biceps_origin.csv", units = [] }', "muscles.biceps.origin.units"),
    ('origin = { body = "humerus", file = "biceps_origin.csv" }',
     'origin = { body = "humerus", points = [[0.0, 0.0, 0.0]], units = [] }', "muscles.biceps.origin.units"),
    ('mesh = "meshes/biceps.ply"', 'mesh = "meshes/bi\\u0000ceps.ply"', "muscles.biceps.mesh"),
    ('motion = "elbow_flexion.mot"', 'motion = "elbow\\u0000.mot"', "motion"),
    ("fibres = 100", "fibres = 1000000000", "defaults.fibres"),
    ("resolution = 19", "resolution = 16000", "defaults.resolution"),
    ("fibres = 100", 'fibres = "many"', "defaults.fibres"),
    ('template = "pennate"', "template = []", "muscles.brachialis.template"),
    ('template = "pennate"', 'template = "pennate"\ntemplate_params = { angle = "steep" }',
     "muscles.brachialis.template_params"),
    ('template = "pennate"', 'template = "pennate"\nvolume = inf', "muscles.brachialis.volume"),
    ("[muscles.biceps]", '[muscles."bi\\nceps"]', "muscles.bi"),
])
def test_wrongly_typed_toml_values_exit_2_in_one_line(example, tmp_path, capfd, old, new, where):
    toml = example / "arm_example.toml"
    _edit(toml, old, new)
    out = tmp_path / "out"
    _fails(capfd, ["run", str(toml), "--out", str(out), *SMALL], str(toml), where)
    assert not out.exists()


def test_caps_say_why(example, tmp_path, capfd):
    toml = str(example / "arm_example.toml")
    line = _fails(capfd, ["run", toml, "--out", str(tmp_path / "o"), "--quiet", "--resolution", "16000"],
                  "--resolution", "limit of 1000")
    assert "slice" in line
    line = _fails(capfd, ["run", toml, "--out", str(tmp_path / "o"), "--quiet", "--fibres", "1000000000"],
                  "--fibres", "limit of 100000")
    assert "GB" in line
    assert not (tmp_path / "o").exists()


def test_meshes_in_metres_declared_as_millimetres_are_refused_at_once(example, tmp_path, capfd):
    """units = "mm" on the example's metre meshes made a 0.3 mm biceps: the run took minutes,
    exited 0 and reported moment arms of -288 mm against the action lines' 25 mm."""
    toml = example / "arm_example.toml"
    _edit(toml, 'units = "m"', 'units = "mm"')
    out = tmp_path / "out"
    _fails(capfd, ["run", str(toml), "--out", str(out), *SMALL], "biceps.ply", "too small for a muscle",
           "units='m'")
    assert not out.exists()


# ----------------------------------------------------------------- damaged mesh files
def _corrupt_legacy_vtk(path: Path, src_ply: Path):
    """A binary legacy .vtk (5.1 layout) of a real mesh with its OFFSETS array corrupted (the file
    that made VTK's reader die with SIGSEGV / std::bad_alloc)."""
    import trimesh

    mesh = trimesh.load(str(src_ply), process=False)
    v, f = np.asarray(mesh.vertices, ">f4"), np.asarray(mesh.faces, ">i8")
    offsets = (3 * np.arange(len(f) + 1)).astype(">i8")
    offsets[len(offsets) // 2] = 2**40                                     # the corruption
    body = (b"# vtk DataFile Version 5.1\nvtk output\nBINARY\nDATASET POLYDATA\n"
            + f"POINTS {len(v)} float\n".encode() + v.tobytes() + b"\n"
            + f"POLYGONS {len(offsets)} {f.size}\nOFFSETS vtktypeint64\n".encode() + offsets.tobytes()
            + b"\nCONNECTIVITY vtktypeint64\n" + f.tobytes() + b"\n")
    path.write_bytes(body)


def test_corrupted_vtk_offsets_and_truncated_vtp_are_one_line_errors(example, tmp_path, capfd):
    toml = example / "arm_example.toml"
    _corrupt_legacy_vtk(example / "meshes" / "bad.vtk", example / "meshes" / "biceps.ply")
    _edit(toml, 'mesh = "meshes/biceps.ply"', 'mesh = "meshes/bad.vtk"')
    _fails(capfd, ["run", str(toml), "--out", str(tmp_path / "o1"), *SMALL], "bad.vtk", "OFFSETS")
    import pyvista as pv
    import trimesh

    mesh = trimesh.load(str(example / "meshes" / "biceps.ply"), process=False)
    pv.make_tri_mesh(mesh.vertices, mesh.faces).save(str(example / "meshes" / "full.vtp"))
    data = (example / "meshes" / "full.vtp").read_bytes()
    (example / "meshes" / "bad.vtp").write_bytes(data[: len(data) * 2 // 3])
    _edit(toml, 'mesh = "meshes/bad.vtk"', 'mesh = "meshes/bad.vtp"')
    _fails(capfd, ["run", str(toml), "--out", str(tmp_path / "o2"), *SMALL], "bad.vtp")
    assert not (tmp_path / "o1").exists() and not (tmp_path / "o2").exists()


def test_truncated_obj_is_a_one_line_error(example, tmp_path, capfd):
    toml = example / "arm_example.toml"
    (example / "meshes" / "bad.obj").write_text("v 1\n")
    _edit(toml, 'mesh = "meshes/biceps.ply"', 'mesh = "meshes/bad.obj"')
    _fails(capfd, ["run", str(toml), "--out", str(tmp_path / "o"), *SMALL], "bad.obj")


def test_unknown_in_degrees_in_the_motion_is_a_one_line_error(example, tmp_path, capfd):
    mot = example / "elbow_flexion.mot"
    mot.write_text(mot.read_text().replace("inDegrees=yes", "inDegrees=Yes please"))
    _fails(capfd, ["run", str(example / "arm_example.toml"), "--out", str(tmp_path / "o"), *SMALL],
           "elbow_flexion.mot", "line 5", "neither yes nor no")


# ----------------------------------------------------------------- memory budget
def test_max_memory_refuses_before_the_long_computation(example, tmp_path, capfd, monkeypatch):
    run_module = __import__("importlib").import_module("analysis.run")
    monkeypatch.setattr(run_module, "run_muscle", lambda *a, **k: pytest.fail("work started"))
    from analysis import budget

    # counting only the run's own needs (not what this test process holds), 50 MiB: the motion
    # and the action lines fit, the muscles do not
    # (27 frames x 3 poses x (1922 + 100 x 39) points x 24 bytes x 12 copies = 136 MB per muscle)
    monkeypatch.setattr(budget, "resident_bytes", lambda: 0)
    line = _fails(capfd, ["run", str(example / "arm_example.toml"), "--out", str(tmp_path / "o"),
                          "--quiet", "--max-memory", "50M"], "--max-memory", "needs about",
                  "27 frames x 100 fibres x 20 points x 3 poses", "budget of 50.0 MiB")
    assert "Use fewer frames" in line
    _fails(capfd, ["run", str(example / "arm_example.toml"), "--out", str(tmp_path / "o"), "--quiet",
                   "--max-memory", "lots"], "--max-memory", "cannot read the size")
    assert not (tmp_path / "o").exists()          # a failed run leaves no empty folder behind


@pytest.mark.slow
def test_a_million_frame_motion_is_refused_up_front(example, tmp_path, capfd, monkeypatch):
    """1,000,000 frames x 100 fibres x 20 points x 3 poses: refused by the estimate, with the
    numbers, before the action lines (it used to grow past 5 GB until MemoryError)."""
    run_module = __import__("importlib").import_module("analysis.run")
    monkeypatch.setattr(run_module, "run_muscle", lambda *a, **k: pytest.fail("work started"))
    n = 1_000_000
    mot = tmp_path / "long.mot"
    t = np.arange(n) * 1e-3
    with open(mot, "w") as fh:
        fh.write(f"long\nversion=1\nnRows={n}\nnColumns=2\ninDegrees=yes\nendheader\ntime\telbow_flexion\n")
        np.savetxt(fh, np.column_stack([t, 60 + 50 * np.sin(t)]), fmt="%.4f", delimiter="\t")
    line = _fails(capfd, ["run", str(example / "arm_example.toml"), "--motion", str(mot), "--out",
                          str(tmp_path / "o"), "--quiet", "--max-memory", "4G"],
                  "1000000 frames x 100 fibres x 20 points x 3 poses", "budget of 4.0 GiB")
    assert "needs about" in line


def test_estimate_is_recorded_and_within_a_factor_of_the_model(example):
    """The estimate of a small run is recorded; its wrapping term is the documented formula."""
    from analysis import budget, run

    res = run(example / "arm_example.toml", frames="0:27:13", fibres=8, resolution=6, muscles=["biceps"])
    est = res.settings["estimate"]
    v = 1922      # the example biceps.ply header: element vertex 1922
    work = 3 * 3 * (v + 8 * 13) * 3 * 8 * budget.WRAP_COPIES
    kept = 3 * 8 * 7 * 3 * 8 + 3 * 3 * 8 * 8          # the frames' points + every pose's lengths
    assert est["memory_bytes"] == max(work, 3 * 8 * 2 * budget.TABLE_BYTES_PER_ROW) + kept
    assert est["disk_bytes"] > 0 and est["max_memory_bytes"] == budget.default_budget()


def test_parse_size():
    from analysis.budget import parse_size

    assert parse_size("8G") == 8 * 2**30 and parse_size("500MB") == 500 * 10**6
    assert parse_size("1.5GiB") == int(1.5 * 2**30) and parse_size("4096") == 4096
    assert parse_size(None) is None
    for bad in ("0", "-1G", "8X", "", "G"):
        with pytest.raises(Exception, match="cannot read the size"):
            parse_size(bad)


# ----------------------------------------------------------------- --jobs in a fresh process
def test_jobs_in_a_fresh_process_compile_the_kernels_once(example, tmp_path):
    """`fibres` compiles its numba kernels lazily without a lock; three muscles in three threads
    of a fresh process raised "A jit decorator was called on an already jitted function" (exit 1)
    every time. `analysis.run` now warms them in one thread first."""
    import subprocess
    import sys

    out = tmp_path / "out"
    env = dict(__import__("os").environ, PYTHONPATH=str(MODELS.parent))
    proc = subprocess.run([sys.executable, "-m", "analysis.cli", "run", str(example / "arm_example.toml"),
                           "--out", str(out), "--jobs", "3", "--frames", "0:4", "--fibres", "20",
                           "--resolution", "8", "--quiet", "--no-plots"], env=env, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert (out / "run.json").is_file()
