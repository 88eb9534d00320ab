"""Threads: two processes at once in the default environment against one pinned process
(issue 13's acceptance: within 1.3x).

Workloads, each in fresh subprocesses:

- ``decompose``: an LHDL muscle (default gluteus maximus, 7.5K vertices / 15K triangles), 100
  fibres x 15 segments, default (harmonic) slicing; one warm-up call, then the median of
  ``--repeats`` calls (wall clock);
- ``run``: ``fibres run`` of the bundled example (``--no-plots --no-scene``, output to a
  temporary folder), the whole process's wall clock (after one earlier run, so numba's cache
  of the one action-line kernel is warm).

"pinned": one process with ``OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
NUMBA_NUM_THREADS=1``. "default x2": the same workload in two processes started together
with none of those variables set (what a user or a Dask worker has); the figure is the mean of
the two processes. The ratio is default x2 / pinned. On a machine shared with other work,
two processes also compete with each other and the rest for the cores: "pinned x2" (two pinned
processes at once) separates that from the thread policy (default x2 / pinned x2).

    python bench/threads.py [--repeats 9] [--only decompose|run]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LHDL = ROOT.parent / "shared" / "muscles" / "LHDL_hip_r"
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")

_DECOMPOSE = r"""
import json, statistics, sys, time, warnings
import pandas as pd
import fibres
lhdl, muscle, repeats = sys.argv[1], sys.argv[2], int(sys.argv[3])
table = pd.read_csv(lhdl + "/attachments/attachment_landmarks.csv")
rows = table[table.muscle == muscle]
origin = rows[rows.type == "origin"][["x_mm", "y_mm", "z_mm"]].to_numpy()
ins = rows[(rows.type == "insertion") & (rows.cloud == 1)][["x_mm", "y_mm", "z_mm"]].to_numpy()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    surface = fibres.as_surface(lhdl + f"/muscles_clean/{muscle}.vtk", units="mm")
fibres.decompose(surface, origin, ins, units="mm", n_fibres=100, resolution=15)
ts = []
for _ in range(repeats):
    t = time.perf_counter()
    fibres.decompose(surface, origin, ins, units="mm", n_fibres=100, resolution=15)
    ts.append(time.perf_counter() - t)
print(json.dumps({"seconds": statistics.median(ts)}))
"""


def _env(pinned: bool) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    env["PYTHONPATH"] = str(ROOT)
    if pinned:
        env.update({k: "1" for k in THREAD_VARS})
    return env


def _start(kind: str, pinned: bool, repeats: int, muscle: str, out: Path):
    if kind == "decompose":
        cmd = [sys.executable, "-c", _DECOMPOSE, str(LHDL), muscle, str(repeats)]
    else:
        cmd = [sys.executable, "-c", "import sys; from analysis.cli import main; sys.exit(main())",
               "run", "--no-plots", "--no-scene", "--quiet", "--out", str(out)]
    return subprocess.Popen(cmd, env=_env(pinned), cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True), time.perf_counter()


def _finish(kind: str, proc_t0) -> float:
    proc, t0 = proc_t0
    out, err = proc.communicate()
    wall = time.perf_counter() - t0
    if proc.returncode:
        raise RuntimeError(err[-2000:])
    return json.loads(out.strip().splitlines()[-1])["seconds"] if kind == "decompose" else wall


def measure(kind: str, repeats: int, muscle: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if kind == "run":        # warm numba's cache of the action-line kernel once
            _finish(kind, _start(kind, True, repeats, muscle, tmp / "warm"))
        n_runs = 1 if kind == "decompose" else max(1, repeats // 3)
        pinned, double, pinned2 = [], [], []
        for k in range(n_runs):
            pinned.append(_finish(kind, _start(kind, True, repeats, muscle, tmp / f"p{k}")))
            pair = [_start(kind, False, repeats, muscle, tmp / f"d{k}{j}") for j in range(2)]
            double.append(statistics.mean(_finish(kind, p) for p in pair))
            pair = [_start(kind, True, repeats, muscle, tmp / f"q{k}{j}") for j in range(2)]
            pinned2.append(statistics.mean(_finish(kind, p) for p in pair))
    p, d, p2 = statistics.median(pinned), statistics.median(double), statistics.median(pinned2)
    return {"pinned": p, "default_x2": d, "ratio": d / p, "pinned_x2": p2, "ratio_x2": d / p2}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--muscle", default="glut_max_r")
    ap.add_argument("--only", choices=("decompose", "run"))
    args = ap.parse_args(argv)
    for kind in ("decompose", "run"):
        if args.only and kind != args.only:
            continue
        r = measure(kind, args.repeats, args.muscle)
        unit = 1e3 if kind == "decompose" else 1.0
        name = "ms" if kind == "decompose" else "s"
        print(f"{kind}: pinned {r['pinned'] * unit:.1f} {name}, default x2 "
              f"{r['default_x2'] * unit:.1f} {name}, ratio {r['ratio']:.2f}; pinned x2 "
              f"{r['pinned_x2'] * unit:.1f} {name}, default x2 / pinned x2 {r['ratio_x2']:.2f}",
              flush=True)


if __name__ == "__main__":
    main()
