"""Benchmark: action lines (lengths + moment arms) of four models, this project vs OpenSim 4.6.

Models and motions (``../shared/opensim``), all frames of each motion:

- ``arm26``: Arm26 with ``arm26_InverseKinematics.mot`` (5 of 6 paths wrap: 2 cylinders,
  2 ellipsoids; TRIlong over three objects in series);
- ``wrap-pin``: MomentArmTests ``WrapPathCustomJointMomentArmTest`` with its sweep (one
  cylinder on a CustomJoint knee);
- ``rajagopal``: RajagopalLaiUhlrich2023 with ``walk_from_gait2392.mot`` (80 paths, 42 wrap
  over cylinders, 4 over two in series; 39 coordinates);
- ``gait2392``: Gait2392 walking (92 paths, no wrapping).

The work timed per frame: every path length and every moment arm of a spanned (path,
coordinate) pair.

- ours: ``motion.action_lines(model, motion)`` on the whole motion at once (poses, path points,
  wrapping, lengths and exact moment arms, vectorised over frames), divided by the number of
  frames. Warm: after one call on the same model (index plans cached); first call: a fresh
  Python process (``--first-call``: import, model and motion loading, then the first
  ``action_lines``, each timed, wall clock and CPU; the first call loads, or with an empty numba
  cache compiles, the polyline and wrap kernels).
- OpenSim: what ``../shared/tools/opensim_reference.py`` does per frame: ``Coordinate.setValue``
  for every coordinate + ``Model.assemble`` + ``realizePosition`` (pose), then
  ``GeometryPath.getLength`` per path and ``Muscle.computeMomentArm`` per spanned pair, in the
  same process.

Both sides are timed in CPU seconds of this process (``time.process_time``; both are
single-threaded), so that waiting for a core on a busy machine counts on neither side. Each
side is repeated ``--repeats`` times (default 5), interleaved (ours, OpenSim, ours, ...) so
that a busy machine slows both alike; the medians per frame are printed with the ratio
OpenSim (lengths + moment arms) / ours. Both sides' lengths are compared (max |difference|) so
that the timing is of the same result. Run from the repository root:
``python bench/lines.py [--models arm26,rajagopal] [--repeats 5] [--first-call]``. Without the
``opensim`` package the OpenSim part is skipped with a note.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import statistics
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OPENSIM = ROOT.parent / "shared" / "opensim"
MODELS = {
    "arm26": ("Arm26/arm26.osim", "Arm26/arm26_InverseKinematics.mot"),
    "wrap-pin": ("MomentArmTests/WrapPathCustomJointMomentArmTest.osim",
                 "MomentArmTests/WrapPathCustomJointMomentArmTest_sweep.mot"),
    "rajagopal": ("RajagopalLaiUhlrich2023/RajagopalLaiUhlrich2023.osim",
                  "RajagopalLaiUhlrich2023/walk_from_gait2392.mot"),
    "gait2392": ("Gait2392_Simbody/gait2392_thelen2003muscle.osim", "Gait2392_Simbody/subject01_walk1_ik.mot"),
}


def load(key):
    """(model, motion) of a MODELS entry."""
    from motion.osim.motion_file import load_motion
    from motion.osim.reader import load_model

    model_rel, motion_rel = MODELS[key]
    model = load_model(OPENSIM / model_rel)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")       # columns the model lacks, etc.
        mot = load_motion(OPENSIM / motion_rel, model)
    return model, mot


def time_ours(model, mot):
    """Seconds per frame of one ``action_lines`` call; the result."""
    from motion.wrapping.action_lines import action_lines

    start = time.process_time()
    lines = action_lines(model, mot)
    return (time.process_time() - start) / mot.n_frames, lines


class OpenSimSide:
    """One OpenSim model posed frame by frame, timed as the module docstring says."""

    def __init__(self, osim, model_file, mot, lines):
        osim.Logger.removeFileSink()  # no opensim.log in the working folder
        osim.Logger.setLevelString("off")
        self.model = osim.Model(str(model_file))
        self.state = self.model.initSystem()
        coord_set = self.model.getCoordinateSet()
        self.coords = [coord_set.get(name) for name in mot.coordinate_names]
        forces = self.model.getForceSet()
        muscles = [osim.PathActuator.safeDownCast(forces.get(name)) for name in lines.muscle_names]
        self.paths = [m.getGeometryPath() for m in muscles]
        self.pairs = [(muscles[m], coord_set.get(lines.coordinate_names[c]))
                      for m, c in zip(*np.nonzero(lines.spanned))]
        self.q = np.asarray(mot.q)
        self.lengths = np.empty((len(self.q), len(self.paths)))

    def run(self):
        """Seconds per frame: (pose, lengths, moment arms)."""
        model, state = self.model, self.state
        t_pose = t_len = t_arm = 0.0
        for f, row in enumerate(self.q):  # OpenSim works one frame at a time
            a = time.process_time()
            for coord, value in zip(self.coords, row):
                coord.setValue(state, float(value), False)
            model.assemble(state)
            model.realizePosition(state)
            b = time.process_time()
            for k, path in enumerate(self.paths):
                self.lengths[f, k] = path.getLength(state)
            c = time.process_time()
            for muscle, coord in self.pairs:
                muscle.computeMomentArm(state, coord)
            d = time.process_time()
            t_pose, t_len, t_arm = t_pose + b - a, t_len + c - b, t_arm + d - c
        n = len(self.q)
        return t_pose / n, t_len / n, t_arm / n


def first_call(key) -> dict:
    """In this (fresh) process: seconds to import, to load model and motion, of the first call."""
    t0 = time.perf_counter()
    from motion.wrapping.action_lines import action_lines
    t1 = time.perf_counter()
    model, mot = load(key)
    t2, c2 = time.perf_counter(), time.process_time()
    action_lines(model, mot)
    t3, c3 = time.perf_counter(), time.process_time()
    return {"import_s": t1 - t0, "load_s": t2 - t1, "first_call_s": t3 - t2, "first_call_cpu_s": c3 - c2}


def _ms(values):
    return 1e3 * statistics.median(values)


def bench_model(key, repeats, osim) -> dict:
    from motion.wrapping.action_lines import action_lines

    model, mot = load(key)
    action_lines(model, mot)                     # warm: index plans cached
    ours, lines = [], None
    side = OpenSimSide(osim, OPENSIM / MODELS[key][0], mot, action_lines(model, mot)) if osim else None
    theirs = []
    for _ in range(repeats):
        t, lines = time_ours(model, mot)
        ours.append(t)
        if side is not None:
            theirs.append(side.run())
    row = {"model": key, "frames": mot.n_frames, "paths": len(lines.muscle_names),
           "wrapped": sum(1 for p in model.paths if p.wraps), "pairs": int(np.asarray(lines.spanned).sum()),
           "ours_ms": _ms(ours)}
    if side is not None:
        pose, length, arm = (_ms([t[i] for t in theirs]) for i in range(3))
        row.update(opensim_pose_ms=pose, opensim_ms=length + arm, ratio=(length + arm) / row["ours_ms"],
                   max_dl=float(np.max(np.abs(np.asarray(lines.lengths) - side.lengths))))
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", default=",".join(MODELS), help=f"comma-separated, of {', '.join(MODELS)}")
    parser.add_argument("--repeats", type=int, default=5, help="repetitions of each side")
    parser.add_argument("--first-call", action="store_true", help="also time a fresh process per model")
    parser.add_argument("--child", help=argparse.SUPPRESS)   # internal: first call of one model, JSON out
    args = parser.parse_args(argv)
    # the wrapped models' notes (e.g. Rajagopal's paths over wraps in series) are not timings
    warnings.filterwarnings("ignore", message=".*wrap objects in series")
    sys.path.insert(0, str(ROOT))
    if args.child:
        print(json.dumps(first_call(args.child)))
        return 0
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    keys = [k.strip() for k in args.models.split(",") if k.strip()]
    unknown = [k for k in keys if k not in MODELS]
    if unknown:
        parser.error(f"unknown model {unknown[0]!r}; choose among {', '.join(MODELS)}")
    if not OPENSIM.is_dir():
        print(f"bench/lines.py: the shared data folder is absent ({OPENSIM} not found).")
        return 1
    osim = None
    if importlib.util.find_spec("opensim") is None:
        print("OpenSim: skipped (the opensim package is not installed: pip install opensim==4.6)")
    else:
        import opensim as osim
    print(f"median CPU ms per frame over {args.repeats} repeats (lengths + moment arms of every spanned pair)")
    print("| model | frames | paths (wrapped) | pairs | ours (ms) | OpenSim (ms) | ratio | OpenSim pose (ms) "
          "| max dL (m) | first call (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for key in keys:
        row = bench_model(key, args.repeats, osim)
        first = ""
        if args.first_call:
            out = subprocess.run([sys.executable, __file__, "--child", key], capture_output=True, text=True,
                                 check=True, cwd=ROOT)
            fc = json.loads(out.stdout.strip().splitlines()[-1])
            first = (f"{fc['first_call_s']:.2f} ({fc.get('first_call_cpu_s', float('nan')):.2f} CPU; "
                     f"import {fc['import_s']:.2f}, load {fc['load_s']:.2f})")
        osim_cols = (f"{row['opensim_ms']:.3f} | {row['ratio']:.1f}x | {row['opensim_pose_ms']:.3f} | "
                     f"{row['max_dl']:.1e}") if "ratio" in row else "- | - | - | -"
        print(f"| {key} | {row['frames']} | {row['paths']} ({row['wrapped']}) | {row['pairs']} | "
              f"{row['ours_ms']:.3f} | {osim_cols} | {first} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
