"""Throughput of ``fibres study``: a 3 subjects x 3 trials study from the shared data, its wall
time on a 2-worker LocalCluster against the sum of single ``fibres run`` of its trials on one core.

    python bench/study.py                 # build the study in a temp folder, measure, compare
    python bench/study.py --build DIR     # only write the study (study.toml and its inputs) to DIR
    python bench/study.py --engine processes --workers 2

The study (`build_study`), options ``fibres = 20``, ``resolution = 8``, no plots, no scene:
- ``arm``: the bundled example (`models/arm_example.toml`, 3 meshed muscles), its elbow flexion
  cut into three sub-range motions (rows 0-8, 9-17, 18-26);
- ``gait``: Gait2392 (``../shared/opensim/Gait2392_Simbody``) with three generated muscles
  (rect_fem_r, vas_lat_r, bifemlh_r), the walking trial cut into three sub-ranges of 10 frames;
- ``lhdl``: the LHDL hip (`tests/data/lhdl_hip.toml`, four meshed muscles) with its three motions,
  every 5th of the first 30 frames (``frames = "0:30:5"``).

Single runs: each trial as its own ``python -m analysis.cli run`` process pinned to one core
(``taskset -c 0``, one BLAS/numba thread), the same options, summed; also each trial inside one
warm process (no start-up, rest decomposition not shared), summed. The study: a fresh output
folder, ``analysis.study(..., workers=2)``, wall time including the cluster's start. The
comparison checks every table of every trial against its single run (CSV bytes).
"""
from __future__ import annotations

import argparse
import filecmp
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
GAIT = SHARED / "opensim" / "Gait2392_Simbody"
TABLES = ("fibre_lengths", "fibre_moment_arms", "action_lines", "action_line_moment_arms", "summary",
          "fibre_quality")


def write_sub_motion(src: Path, dst: Path, rows) -> Path:
    """Write the data rows ``rows`` of the motion ``src`` as a new motion file ``dst`` (header
    kept, ``nRows`` corrected)."""
    lines = src.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if ln.strip().lower() == "endheader")
    header, columns, data = lines[:end + 1], lines[end + 1], [ln for ln in lines[end + 2:] if ln.strip()]
    chosen = [data[r] for r in rows]
    header = [f"nRows={len(chosen)}" if ln.lower().startswith("nrows=") else ln for ln in header]
    dst.write_text("\n".join(header + [columns] + chosen) + "\n")
    return dst


def build_study(folder: Path, *, fibres=20, resolution=8) -> Path:
    """Write the bench study (module docstring) into ``folder``; returns the study file."""
    folder = Path(folder)
    for sub in ("arm", "gait", "lhdl"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    arm_mot = ROOT / "models" / "elbow_flexion.mot"
    for k, name in enumerate(("flex_early", "flex_mid", "flex_late")):
        write_sub_motion(arm_mot, folder / "arm" / f"{name}.mot", range(9 * k, 9 * k + 9))
    walk = GAIT / "subject01_walk1_ik.mot"
    for k, name in enumerate(("walk_a", "walk_b", "walk_c")):
        write_sub_motion(walk, folder / "gait" / f"{name}.mot", range(70 * k, 70 * k + 70, 7))
    gait_toml = folder / "gait" / "fibres.toml"
    muscles = ("rect_fem_r", "vas_lat_r", "bifemlh_r")
    gait_toml.write_text("\n".join(
        [f'model = "{GAIT / "gait2392_thelen2003muscle.osim"}"', "[defaults]", 'template = "parallel"']
        + [f'[muscles.{m}]\naction_lines = ["{m}"]' for m in muscles]) + "\n")
    lhdl = SHARED / "muscles" / "LHDL_hip_r" / "model" / "motions"
    study = folder / "study.toml"
    study.write_text(f"""# bench/study.py: 3 subjects x 3 trials
[options]
fibres = {fibres}
resolution = {resolution}
no-plots = true
no-scene = true

[subjects.arm]
model = "{ROOT / 'models' / 'arm_example.toml'}"
trials = ["arm/flex_*.mot"]

[subjects.gait]
model = "gait/fibres.toml"
trials = ["gait/walk_*.mot"]

[subjects.lhdl]
model = "{ROOT / 'tests' / 'data' / 'lhdl_hip.toml'}"
trials = ["{lhdl}/hip_*.mot"]
options = {{ frames = "0:30:5" }}
""")
    return study


def single_run_commands(study_file: Path, out: Path) -> list:
    """(label, argv) of a single ``fibres run`` per trial of the study, into ``out/<subject>/<trial>``."""
    from analysis.study_file import load_study

    cmds = []
    for t in load_study(study_file).trials:
        argv = ["run", str(t.spec), "--motion", str(t.motion), "--out", str(out / t.folder), "--quiet"]
        for dest, value in t.options.items():
            flag = "--" + dest.replace("_", "-")
            if dest == "sto":
                argv.append("--sto" if value else "--no-sto")
            elif value is True:
                argv.append(flag)
            elif isinstance(value, list):
                for item in value:
                    argv += [flag, str(item)]
            elif value is not False:
                argv += [flag, str(value)]
        cmds.append((t.label, t.folder, argv))
    return cmds


def same_tables(a: Path, b: Path) -> list:
    """Tables (CSV) of two trial folders that differ (byte comparison)."""
    return [t for t in TABLES if not filecmp.cmp(a / f"{t}.csv", b / f"{t}.csv", shallow=False)]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build", metavar="DIR", help="only write the study into DIR")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--engine", choices=("dask", "processes"), default=None)
    parser.add_argument("--keep", metavar="DIR", help="work in DIR (kept) instead of a temp folder")
    args = parser.parse_args(argv)
    if args.build:
        print(build_study(Path(args.build)))
        return 0
    work = Path(args.keep or tempfile.mkdtemp(prefix="bench-study-"))
    study_file = build_study(work / "input")
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               MKL_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    def cpu(who):
        r = resource.getrusage(who)
        return r.ru_utime + r.ru_stime

    singles = {}
    cpu0 = cpu(resource.RUSAGE_CHILDREN)
    for label, folder, cmd in single_run_commands(study_file, work / "single"):
        t0 = time.perf_counter()
        subprocess.run(["taskset", "-c", "0", sys.executable, "-m", "analysis.cli", *cmd], env=env, check=True)
        singles[label] = time.perf_counter() - t0
        print(f"single run {label}: {singles[label]:.2f} s", flush=True)
    cpu_singles = cpu(resource.RUSAGE_CHILDREN) - cpu0
    warm = subprocess.run(["taskset", "-c", "0", sys.executable, "-c", (
        "import sys, time, json; sys.path.insert(0, %r); from bench.study import single_run_commands;"
        "from analysis.cli import main; from pathlib import Path;"
        "cmds = single_run_commands(Path(%r), Path(%r)); main(cmds[0][2]); out = {}\n"
        "for label, folder, cmd in cmds:\n"
        "    t0 = time.perf_counter(); main(cmd); out[label] = time.perf_counter() - t0\n"
        "print(json.dumps(out))") % (str(ROOT), str(study_file), str(work / "warm"))],
        env=env, check=True, capture_output=True, text=True)
    import json

    warm_times = json.loads(warm.stdout.strip().splitlines()[-1])
    from analysis.study import study

    out = work / "study"
    shutil.rmtree(out, ignore_errors=True)
    cpu1 = cpu(resource.RUSAGE_CHILDREN) + cpu(resource.RUSAGE_SELF)
    t0 = time.perf_counter()
    report = study(study_file, out, workers=args.workers, engine=args.engine, quiet=False)
    wall = time.perf_counter() - t0
    time.sleep(1.0)    # the workers are reaped
    cpu_study = cpu(resource.RUSAGE_CHILDREN) + cpu(resource.RUSAGE_SELF) - cpu1
    print(report.table())
    diffs = {t.label: same_tables(out / t.folder, work / "single" / t.folder)
             for t in __import__("analysis.study_file", fromlist=["x"]).load_study(study_file).trials}
    total, total_warm = sum(singles.values()), sum(warm_times.values())
    print(f"sum of single `fibres run` processes on one core: {total:.1f} s")
    print(f"sum of single runs in one warm process on one core: {total_warm:.1f} s")
    print(f"study on {args.workers} workers ({report.engine}): {wall:.1f} s = {wall / total:.2f} x the "
          f"processes' sum, {wall / total_warm:.2f} x the warm sum")
    print(f"CPU time (user + sys): single processes {cpu_singles:.1f} s, study (client and workers) "
          f"{cpu_study:.1f} s; load average during the run: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print("tables equal to the single runs:", "all" if not any(diffs.values()) else diffs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
