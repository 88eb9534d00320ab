"""A whole model over a whole trial, as a user runs it: Gait2392 walking, every muscle.

    python bench/whole_model.py [--jobs 2] [--frames START:STOP:STEP] [--plots] [--repeat 1]
                                [--muscles N] [--fibres N] [--keep DIR]

Writes a fibre model with one generated muscle per OpenSim muscle of
``../shared/opensim/Gait2392_Simbody`` (92 muscles, parallel template, the defaults of the TOML:
100 fibres x 19 segments), then runs the command line ``fibres run`` on it in a fresh process
over ``subject01_walk1_ik.mot`` (211 frames; moment arms about every spanned coordinate), in the
default environment (no thread variables), and prints per repeat the wall time, the peak
resident memory of the process and the size written, then their medians. ``--plots`` draws the
plots too (default: ``--no-plots``). Nothing is written inside the repository (a temporary folder,
or ``--keep DIR``).
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GAIT = ROOT.parent / "shared" / "opensim" / "Gait2392_Simbody"
MODEL = GAIT / "gait2392_thelen2003muscle.osim"
MOTION = GAIT / "subject01_walk1_ik.mot"


def write_spec(folder: Path, n_muscles=None, fibres=None) -> Path:
    """A fibre-model TOML with one generated muscle per path of the model (first ``n_muscles``)."""
    sys.path.insert(0, str(ROOT))
    from motion import load_model

    names = list(load_model(MODEL).path_names)[:n_muscles]
    lines = [f'model = "{MODEL}"', f'motion = "{MOTION}"', "[defaults]", 'template = "parallel"']
    if fibres:
        lines.append(f"fibres = {int(fibres)}")
    for name in names:
        lines += [f"[muscles.{name}]", f'action_lines = ["{name}"]']
    path = folder / "gait2392_all.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _size(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def run_once(spec: Path, out: Path, args) -> tuple:
    """(wall s, peak RSS bytes, bytes written) of one ``fibres run`` in a fresh process."""
    cmd = [sys.executable, "-m", "analysis.cli", "run", str(spec), "--out", str(out), "--force",
           "--jobs", str(args.jobs)]
    if not args.plots:
        cmd.append("--no-plots")
    if args.frames:
        cmd += ["--frames", args.frames]
    env = {k: v for k, v in os.environ.items()
           if k not in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"fibres run failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024   # the largest child so far
    return wall, peak, _size(out)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--frames", default=None)
    parser.add_argument("--plots", action="store_true")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--muscles", type=int, default=None, help="only the first N muscles")
    parser.add_argument("--fibres", type=int, default=None)
    parser.add_argument("--keep", default=None, help="write the outputs here (else a temporary folder)")
    args = parser.parse_args(argv)
    if not MODEL.is_file():
        print(f"needs {MODEL}", file=sys.stderr)
        return 1
    tmp = Path(tempfile.mkdtemp(prefix="whole_model_"))
    try:
        spec = write_spec(tmp, args.muscles, args.fibres)
        out = Path(args.keep) if args.keep else tmp / "out"
        rows = []
        for k in range(args.repeat):
            wall, peak, size = run_once(spec, out, args)
            rows.append((wall, peak, size))
            print(f"run {k + 1}: {wall:.1f} s wall, peak RSS {peak / 2**30:.2f} GiB, "
                  f"written {size / 2**30:.2f} GiB", flush=True)
        print(f"median over {len(rows)}: {statistics.median(r[0] for r in rows):.1f} s wall, "
              f"jobs {args.jobs}, plots {'on' if args.plots else 'off'}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
