"""Benchmark of `fibres run` on the LHDL hip (tests/data/lhdl_hip.toml), one core.

    python bench/run.py [--frames START:STOP:STEP] [--repeat N] [--transport bind|decompose]

Prints (1) wall time per muscle-frame for wrap + decompose + lengths (no moment arms) and with
moment arms about the three hip coordinates (7 evaluations per frame: q, q +- h e_c), medians
of N repeats (target <= 20 ms per muscle-frame with moment arms); (2) per muscle and task
(flexion / adduction / rotation motions of the dataset) the range (p5..p95 over fibres) of the
fibre moment arms at a few angles beside the action lines' values, with the flexion ranges of
Modenese & Kohout 2020, Table 2, for comparison.

Set NUMBA_NUM_THREADS=1 / OMP_NUM_THREADS=1 for a strict one-core figure (done below when not
set by the caller).
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import importlib  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TOML = ROOT / "tests" / "data" / "lhdl_hip.toml"
MOTIONS = ROOT.parent / "shared" / "muscles" / "LHDL_hip_r" / "model" / "motions"
#: Modenese & Kohout 2020, Table 2: hip-flexion moment-arm ranges over the fibres (cm)
PAPER_FLEXION_CM = {"psoas_r": (0.9, 2.6), "iliacus_r": (1.3, 4.6), "glut_max_r": (-9.2, -1.9),
                    "glut_med_r": (-3.5, 1.5)}
TASKS = {"flexion": ("hip_flexion.mot", "hip_flexion_r"), "adduction": ("hip_adduction.mot", "hip_adduction_r"),
         "rotation": ("hip_rotation.mot", "hip_rotation_r")}


def _timed_run(spec, motion, frames, *, muscles, transport):
    from analysis.run import run

    t0 = time.perf_counter()
    res = run(spec, motion, frames=frames, muscles=muscles, quiet=True, transport=transport)
    return time.perf_counter() - t0, res


@contextlib.contextmanager
def _no_fd():
    """analysis.run with no coordinate spanned: wrap + decompose + lengths only."""
    mod = importlib.import_module("analysis.muscle_chain")
    orig = mod.spanned_coordinates

    def none(ctx, mspec):
        idx, rows = orig(ctx, mspec)
        return idx[:0], rows

    mod.spanned_coordinates = none
    try:
        yield
    finally:
        mod.spanned_coordinates = orig


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", default="0:36:1", help="frames of hip_flexion.mot to time (default all)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--transport", default="bind", choices=("bind", "decompose"))
    parser.add_argument("--angles", default="-10,0,20,40,60", help="angles (deg) to print moment arms at")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    from analysis.run import run
    from analysis.spec import load_spec

    spec = load_spec(TOML)
    names = spec.muscle_names
    flex = MOTIONS / "hip_flexion.mot"
    run(spec, flex, frames="0:2", muscles=names[:1], transport=args.transport)   # warm-up (imports, numba)
    print(f"LHDL hip, {len(names)} muscles, {spec.muscles[0].n_fibres} fibres x {spec.muscles[0].resolution} "
          f"segments, transport={args.transport}, frames {args.frames} of {flex.name}")
    for label, no_fd in (("wrap+decompose+lengths", True), ("with moment arms (3 coords)", False)):
        per = {m: [] for m in names}
        for _ in range(args.repeat):
            for m in names:
                with _no_fd() if no_fd else contextlib.nullcontext():
                    t, res = _timed_run(spec, flex, args.frames, muscles=[m], transport=args.transport)
                per[m].append(1e3 * t / len(res.time))
        med = {m: float(np.median(v)) for m, v in per.items()}
        print(f"\n{label}: ms per muscle-frame (median of {args.repeat}, load+action lines included)")
        for m, v in med.items():
            print(f"  {m:12s} {v:8.1f}")
        print(f"  {'mean':12s} {np.mean(list(med.values())):8.1f}")
    print("\nFibre moment arms (cm): p5 .. p95 over fibres [median] vs action lines, per task and angle")
    angles = [float(a) for a in args.angles.split(",")]
    for task, (fname, coord) in TASKS.items():
        res = run(spec, MOTIONS / fname, quiet=True, transport=args.transport)
        q = np.rad2deg(res.coordinate_values(coord))
        rows = [int(np.argmin(np.abs(q - a))) for a in angles if q.min() - 1 <= a <= q.max() + 1]
        print(f"\n{task} ({coord}):")
        for m in res.muscles:
            k = m.coordinates.index(coord)
            r = m.fibre_moment_arms[:, :, k] * 100
            al = m.action_line_moment_arms[:, :, k] * 100
            paper = f"  paper flexion range {PAPER_FLEXION_CM[m.name]}" if task == "flexion" else ""
            print(f"  {m.name}: all frames p5..p95 {np.percentile(r, 5):.2f} .. {np.percentile(r, 95):.2f}{paper}")
            for f in rows:
                lines = ", ".join(f"{n}={v:.2f}" for n, v in zip(m.action_lines, al[f]))
                print(f"    {q[f]:6.1f} deg: {np.percentile(r[f], 5):6.2f} .. {np.percentile(r[f], 95):6.2f} "
                      f"[{np.median(r[f]):6.2f}]   lines: {lines}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
