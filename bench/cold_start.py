"""Cold start: the first `fibres.decompose` and the first `fibres run` in a fresh process with an
empty numba cache (issue 13's acceptance: <= 10 s and <= 60 s, progress within 5 s).

Every measurement runs in a new subprocess with ``NUMBA_CACHE_DIR`` set to a new empty temporary
folder, after checking that no compiled-kernel cache (``*.nbi``/``*.nbc``) lies beside the sources
(numba would otherwise load it). The environment is the caller's (no thread variables are set).

    python bench/cold_start.py [--repeats 1] [--skip-run] [--muscle glut_max_r] [--root DIR]

``--root`` measures another checkout (e.g. the commit before this work, for the "before"
figures). Wall-clock and CPU (user + system) seconds: on a shared machine the wall clock includes waiting
for a core, the CPU time does not. Prints per-stage timings of the decomposition child (import, mesh read, first and
second decompose) and, for ``fibres run`` (the README's first command: the bundled example with
defaults, output to a temporary folder), the time to its first line on stderr and the total.
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

_CHILD = r"""
import json, sys, time, warnings
t0 = time.perf_counter()
import numpy as np, pandas as pd
import fibres
t1 = time.perf_counter()
lhdl, muscle = sys.argv[1], sys.argv[2]
table = pd.read_csv(lhdl + "/attachments/attachment_landmarks.csv")
rows = table[table.muscle == muscle]
origin = rows[rows.type == "origin"][["x_mm", "y_mm", "z_mm"]].to_numpy()
ins = rows[(rows.type == "insertion") & (rows.cloud == 1)][["x_mm", "y_mm", "z_mm"]].to_numpy()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    surface = fibres.as_surface(lhdl + f"/muscles_clean/{muscle}.vtk", units="mm")
t2 = time.perf_counter()
slicing = sys.argv[3]
b = fibres.decompose(surface, origin, ins, units="mm", n_fibres=100, resolution=15, slicing=slicing)
t3 = time.perf_counter()
b = fibres.decompose(surface, origin, ins, units="mm", n_fibres=100, resolution=15, slicing=slicing)
t4 = time.perf_counter()
print(json.dumps({"vertices": len(surface.vertices), "import": t1 - t0, "read": t2 - t1,
                  "first_decompose": t3 - t2, "second_decompose": t4 - t3}))
"""


def _child_cpu():
    """User + system CPU seconds of the finished children of this process."""
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _stray_caches(root: Path):
    return [p for p in root.rglob("__pycache__/*") if p.suffix in (".nbi", ".nbc")]


def _env(root: Path, cache: str):
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(root))
    env.pop("FIBRES_PROGRESS", None)
    return env


def decompose_once(root: Path, muscle: str, slicing: str) -> dict:
    with tempfile.TemporaryDirectory() as cache:
        t0, c0 = time.perf_counter(), _child_cpu()
        out = subprocess.run([sys.executable, "-c", _CHILD, str(LHDL), muscle, slicing],
                             env=_env(root, cache), cwd=root, capture_output=True, text=True)
        wall, cpu = time.perf_counter() - t0, _child_cpu() - c0
        if out.returncode:
            raise RuntimeError(out.stderr)
        res = json.loads(out.stdout.strip().splitlines()[-1])
        res["process"] = wall
        res["process_cpu"] = cpu
        res["cache_files"] = sum(1 for _ in Path(cache).rglob("*.nbi"))
        return res


def run_once(root: Path) -> dict:
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out_dir:
        cmd = [sys.executable, "-c", "import sys; from analysis.cli import main; sys.exit(main())",
               "run", "--out", str(Path(out_dir) / "out")]
        t0, c0 = time.perf_counter(), _child_cpu()
        proc = subprocess.Popen(cmd, env=_env(root, cache), cwd=out_dir, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        first = None
        lines = []
        for line in proc.stderr:
            if first is None:
                first = time.perf_counter() - t0
            lines.append(line.rstrip())
        proc.wait()
        total, cpu = time.perf_counter() - t0, _child_cpu() - c0
        if proc.returncode:
            raise RuntimeError("\n".join(lines))
        return {"first_line": first, "total": total, "cpu": cpu, "first_text": lines[0] if lines else "",
                "cache_files": sum(1 for _ in Path(cache).rglob("*.nbi"))}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--muscle", default="glut_max_r")
    ap.add_argument("--root", type=Path, default=ROOT)
    ap.add_argument("--skip-run", action="store_true")
    ap.add_argument("--skip-decompose", action="store_true")
    ap.add_argument("--slicing", choices=("harmonic", "planes"), action="append",
                    help="slicing(s) to decompose with (default both)")
    args = ap.parse_args(argv)
    root = args.root.resolve()
    stray = _stray_caches(root)
    if stray:
        sys.exit(f"compiled-kernel caches beside the sources (delete them first): {stray[:3]} ...")
    if not args.skip_decompose:
        for slicing in args.slicing or ("harmonic", "planes"):
            runs = [decompose_once(root, args.muscle, slicing) for _ in range(args.repeats)]
            med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
            print(f"decompose {args.muscle} ({int(med['vertices'])} vertices, slicing={slicing}): "
                  + ", ".join(f"{k} {v:.2f} s" for k, v in med.items()
                              if k not in ("vertices", "cache_files"))
                  + f"; {int(med['cache_files'])} kernels cached", flush=True)
    if not args.skip_run:
        runs = [run_once(root) for _ in range(args.repeats)]
        print(f"fibres run (bundled example): first stderr line after "
              f"{statistics.median(r['first_line'] or float('nan') for r in runs):.2f} s "
              f"({runs[0]['first_text']!r}), total {statistics.median(r['total'] for r in runs):.1f} s"
              f" (CPU {statistics.median(r['cpu'] for r in runs):.1f} s)"
              f"; {runs[0]['cache_files']} kernels cached", flush=True)


if __name__ == "__main__":
    main()
