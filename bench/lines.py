"""Benchmark: action lines of Gait2392 walking, this project vs OpenSim 4.6 in the same process.

The work timed, per frame of ``subject01_walk1_ik.mot`` (all frames): all 92 path lengths and all
262 moment arms (every muscle x every coordinate it spans).

- ours: ``motion.action_lines(model, motion)`` on the whole motion at once (poses, path points,
  lengths and exact moment arms, vectorised over frames), divided by the number of frames; and
  ``motion.body_poses`` alone.
- OpenSim: what ``../shared/tools/opensim_reference.py`` does per frame: ``Coordinate.setValue``
  for every coordinate + ``Model.assemble`` + ``realizePosition`` (pose), then
  ``GeometryPath.getLength`` per path and ``Muscle.computeMomentArm`` per spanned pair.

Each side is repeated ``--repeats`` times (default 5); the medians per frame are printed with the
ratio OpenSim / ours. Both sides' numbers are also compared (max |difference|) so that the timing
is of the same result. Run from the repository root: ``python bench/lines.py``. Without the
``opensim`` package the OpenSim part is skipped with a note.
"""
from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GAIT = ROOT.parent / "shared" / "opensim" / "Gait2392_Simbody"
MODEL = GAIT / "gait2392_thelen2003muscle.osim"
MOTION = GAIT / "subject01_walk1_ik.mot"


def time_ours(model, mot, repeats):
    """Seconds per frame (list over repeats) for action_lines and for body_poses; the last result."""
    from motion.wrapping.action_lines import action_lines
    from motion.osim.kinematics import body_poses

    lines_s, poses_s, lines = [], [], None
    for _ in range(repeats):
        start = time.perf_counter()
        lines = action_lines(model, mot)
        lines_s.append((time.perf_counter() - start) / mot.n_frames)
        start = time.perf_counter()
        body_poses(model, mot)
        poses_s.append((time.perf_counter() - start) / mot.n_frames)
    return lines_s, poses_s, lines


def time_opensim(osim, mot, lines, repeats):
    """Seconds per frame (lists over repeats) for pose, lengths, moment arms; and the values."""
    osim.Logger.removeFileSink()  # no opensim.log in the working folder
    osim.Logger.setLevelString("error")
    model = osim.Model(str(MODEL))
    state = model.initSystem()
    coord_set = model.getCoordinateSet()
    coords = [coord_set.get(name) for name in mot.coordinate_names]
    forces = model.getForceSet()
    muscles = [osim.Muscle.safeDownCast(forces.get(name)) for name in lines.muscle_names]
    paths = [m.getGeometryPath() for m in muscles]
    pairs = [(m, muscles[m], coord_set.get(lines.coordinate_names[c]))
             for m, c in zip(*np.nonzero(lines.spanned))]
    q = np.asarray(mot.q)
    pose_s, length_s, arm_s = [], [], []
    lengths = np.empty((mot.n_frames, len(paths)))
    arms = np.empty((mot.n_frames, len(pairs)))
    for _ in range(repeats):
        t_pose = t_len = t_arm = 0.0
        for f in range(mot.n_frames):  # OpenSim works one frame at a time
            a = time.perf_counter()
            for coord, value in zip(coords, q[f]):
                coord.setValue(state, float(value), False)
            model.assemble(state)
            model.realizePosition(state)
            b = time.perf_counter()
            for k, path in enumerate(paths):
                lengths[f, k] = path.getLength(state)
            c = time.perf_counter()
            for k, (_, muscle, coord) in enumerate(pairs):
                arms[f, k] = muscle.computeMomentArm(state, coord)
            d = time.perf_counter()
            t_pose, t_len, t_arm = t_pose + b - a, t_len + c - b, t_arm + d - c
        pose_s.append(t_pose / mot.n_frames)
        length_s.append(t_len / mot.n_frames)
        arm_s.append(t_arm / mot.n_frames)
    return pose_s, length_s, arm_s, lengths, arms, pairs


def _ms(values):
    return 1e3 * statistics.median(values)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="repetitions of each side (>= 5)")
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    if not MODEL.is_file():
        print(f"bench/lines.py: the shared data folder is absent ({MODEL.parent} not found).")
        return 1
    sys.path.insert(0, str(ROOT))
    from motion.wrapping.action_lines import action_lines
    from motion.osim.motion_file import load_motion
    from motion.osim.reader import load_model

    model = load_model(MODEL)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mot = load_motion(MOTION, model)
    action_lines(model, mot.select_frames(slice(0, 2)))  # warm-up (caches, imports)
    lines_s, poses_s, lines = time_ours(model, mot, args.repeats)
    n_pairs = int(np.asarray(lines.spanned).sum())
    print(f"Gait2392 walking: {mot.n_frames} frames, {len(lines.muscle_names)} paths, "
          f"{n_pairs} moment-arm pairs, {args.repeats} repeats (median per frame)")
    print(f"  ours    action_lines (poses + lengths + moment arms): {_ms(lines_s):9.4f} ms")
    print(f"  ours    body_poses alone:                            {_ms(poses_s):9.4f} ms")

    if importlib.util.find_spec("opensim") is None:
        print("  OpenSim: skipped (the opensim package is not installed: pip install opensim==4.6)")
        return 0
    import opensim as osim

    pose_s, length_s, arm_s, lengths, arms, pairs = time_opensim(osim, mot, lines, args.repeats)
    work = [a + b for a, b in zip(length_s, arm_s)]
    print(f"  OpenSim pose (setValue + assemble + realize):        {_ms(pose_s):9.4f} ms")
    print(f"  OpenSim {len(lines.muscle_names)} lengths:                                 "
          f"{_ms(length_s):9.4f} ms")
    print(f"  OpenSim {len(pairs)} moment arms:                            {_ms(arm_s):9.4f} ms")
    print(f"  OpenSim lengths + moment arms:                       {_ms(work):9.4f} ms")
    print(f"  ratio OpenSim (lengths + moment arms) / ours (action_lines): "
          f"{_ms(work) / _ms(lines_s):.1f}x")
    print(f"  ratio incl. OpenSim's pose step:                              "
          f"{(_ms(work) + _ms(pose_s)) / _ms(lines_s):.1f}x")
    ours_arms = np.asarray(lines.moment_arms)[:, [m for m, _, _ in pairs],
                                              np.nonzero(lines.spanned)[1]]
    print(f"  same numbers? max |dL| = {np.max(np.abs(np.asarray(lines.lengths) - lengths)):.2e} m, "
          f"max |d moment arm| = {np.max(np.abs(ours_arms - arms)):.2e} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
