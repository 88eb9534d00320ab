"""Generated (meshless) muscles of whole OpenSim models: fibres against their action lines and
against OpenSim's own moment arms.

    python bench/generated_moment_arms.py [--model gait2392|arm26|rajagopal|both] [--frames START:STOP:STEP]
                                          [--fibres N] [--resolution R] [--muscle NAME]... [--jobs N]

For every muscle of the model a fusiform surface (with tendons) is generated around its path
(no mesh), fibres are decomposed and carried through the motion (`analysis.run`, default
``bind`` transport), and per muscle-coordinate pair and frame the median fibre moment arm is
compared with the action line's where |r_line| > 5 mm (issue 12's acceptance: within
max(5 %, 1 mm)). Also the median fibre length against the rigid-tendon belly length
``L_path - tendon_slack_length`` (within 5 %; L of the path OpenSim draws). Prints the worst pairs and the counts. Where
the model has OpenSim 4.6 reference numbers (``../shared/opensim/reference``), the median fibre
moment arm is also compared with OpenSim's ``computeMomentArm`` (independent coordinates, the
reference's motion rows): the median, p95 and largest difference and the worst pairs. That is
the oracle where OpenSim's -dL/dq and computeMomentArm disagree (Rajagopal's gastrocnemii over
wrap objects in series, `motion.wrapping.action_lines.ActionLines.drawn_lengths`).

Gait2392: ``subject01_walk1_ik.mot`` (walking, every 3rd row: the reference's); Arm26:
``arm26_elbow_flexion_sweep.mot``; Rajagopal 2023: ``walk_from_gait2392.mot`` (every 4th row).
Reads ``../shared/opensim`` (read-only); writes only a temporary TOML.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OPENSIM = ROOT.parent / "shared" / "opensim"
REFERENCE = OPENSIM / "reference"
#: model, motion, default rows, OpenSim reference folder
MODELS = {
    "gait2392": (OPENSIM / "Gait2392_Simbody" / "gait2392_thelen2003muscle.osim",
                 OPENSIM / "Gait2392_Simbody" / "subject01_walk1_ik.mot", "0:211:3",
                 REFERENCE / "Gait2392_Simbody" / "subject01_walk1_ik"),
    "arm26": (OPENSIM / "Arm26" / "arm26.osim", OPENSIM / "Arm26" / "arm26_elbow_flexion_sweep.mot", None,
              REFERENCE / "Arm26" / "elbow_flexion_sweep"),
    "rajagopal": (OPENSIM / "RajagopalLaiUhlrich2023" / "RajagopalLaiUhlrich2023.osim",
                  OPENSIM / "RajagopalLaiUhlrich2023" / "walk_from_gait2392.mot", "0:209:4",
                  REFERENCE / "RajagopalLaiUhlrich2023" / "walk_from_gait2392"),
}
#: the acceptance bound: max(5 %, 1 mm); lines with |r| <= 5 mm are not compared
REL, ABS, MIN_ARM = 0.05, 1e-3, 5e-3


def write_toml(directory, model_path, motion_path, muscles, *, fibres=30, resolution=12) -> Path:
    """A fibre model with one generated muscle per OpenSim muscle (parallel template)."""
    lines = [f'model = "{model_path}"', f'motion = "{motion_path}"', "[defaults]",
             'template = "parallel"', f"fibres = {fibres}", f"resolution = {resolution}"]
    for name in muscles:
        lines += [f"[muscles.{name}]", f'action_lines = ["{name}"]']
    path = Path(directory) / "generated.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def compare(result, tendon_slack, drawn):
    """Rows (muscle, coordinate, worst excess over the bound (m), |median - line| (m) there,
    line r there, frames compared) and (muscle, worst relative belly-length error); the belly is
    ``drawn[muscle] - tendon slack``, the path OpenSim draws (`ActionLines.drawn_lengths`)."""
    pairs, lengths = [], []
    for m in result.muscles:
        r_line = np.asarray(m.action_line_moment_arms)[:, 0]            # (F, C)
        r_med = np.median(np.asarray(m.fibre_moment_arms), axis=1)       # (F, C)
        for c, coord in enumerate(m.coordinates):
            sel = np.abs(r_line[:, c]) > MIN_ARM
            if not sel.any():
                continue
            diff = np.abs(r_med[sel, c] - r_line[sel, c])
            bound = np.maximum(REL * np.abs(r_line[sel, c]), ABS)
            k = int(np.argmax(diff - bound))
            pairs.append((m.name, coord, float((diff - bound)[k]), float(diff[k]), float(r_line[sel, c][k]),
                          int(sel.sum())))
        belly = drawn[m.name] - tendon_slack.get(m.name, 0.0)
        med = np.median(np.asarray(m.fibre_lengths), axis=1)
        ok = belly > 0
        if ok.any():
            lengths.append((m.name, float(np.max(np.abs(med[ok] / belly[ok] - 1.0)))))
    return pairs, lengths


def compare_opensim(result, ref_dir):
    """|median fibre moment arm - OpenSim's computeMomentArm| (m) at the reference's motion rows,
    independent coordinates: (array of all, rows (muscle, coordinate, worst diff, r there))."""
    import json

    import pandas as pd

    ref = pd.read_csv(ref_dir / "moment_arms.csv")
    rows = json.loads((ref_dir / "metadata.json").read_text())["motion"]["source_rows_used"]
    ref = ref[ref.coord_status == "independent"]
    at = {int(r): k for k, r in enumerate(result.frames)}
    diffs, worst = [], []
    for m in result.muscles:
        r_med = np.median(np.asarray(m.fibre_moment_arms), axis=1)       # (F, C)
        for (coord, group) in ref[ref.muscle == m.name].groupby("coordinate"):
            if coord not in m.coordinates:
                continue
            frames = [(at[rows[f]], v) for f, v in zip(group.frame, group.moment_arm) if rows[f] in at]
            if not frames:
                continue
            k, osim = np.array([f for f, _ in frames]), np.array([v for _, v in frames])
            d = np.abs(r_med[k, m.coordinates.index(coord)] - osim)
            diffs.append(d)
            worst.append((m.name, coord, float(d.max()), float(osim[np.argmax(d)])))
    return (np.concatenate(diffs) if diffs else np.zeros(0)), worst


def run_model(key, *, frames=None, fibres=30, resolution=12, muscles=None, jobs=1):
    from analysis.run import run
    from motion import action_lines, load_model
    from motion.osim.muscle_parameters import muscle_parameters

    model_path, motion_path, default_frames, _ = MODELS[key]
    model = load_model(model_path)
    names = list(muscles) if muscles else [p.name for p in model.paths]
    slack = {n: muscle_parameters(model, n).tendon_slack_length or 0.0 for n in names}
    with tempfile.TemporaryDirectory() as tmp:
        toml = write_toml(tmp, model_path, motion_path, names, fibres=fibres, resolution=resolution)
        t0 = time.perf_counter()
        res = run(toml, frames=frames or default_frames, quiet=True, jobs=jobs)
        elapsed = time.perf_counter() - t0
    lines = action_lines(model, np.asarray(res.q), muscles=[m.name for m in res.muscles])
    drawn = {n: lines.drawn_lengths[:, k] for k, n in enumerate(lines.muscle_names)}
    return res, slack, drawn, elapsed


def report(key, res, slack, drawn, elapsed, *, worst=12) -> bool:
    pairs, lengths = compare(res, slack, drawn)
    bad = [p for p in pairs if p[2] > 0]
    print(f"\n{key}: {len(res.muscles)} muscles, {len(res.frames)} frames, {len(pairs)} muscle-coordinate pairs "
          f"with |r_line| > 5 mm, {elapsed:.0f} s")
    print(f"  pairs outside max(5 %, 1 mm): {len(bad)}")
    print("  worst pairs (excess over the bound, |median fibre - line|, line r at that frame; mm):")
    for name, coord, excess, diff, r, n in sorted(pairs, key=lambda p: -p[2])[:worst]:
        print(f"    {name:16s} {coord:20s} excess {1e3 * excess:7.2f}  diff {1e3 * diff:6.2f}  "
              f"r_line {1e3 * r:7.2f}  ({n} frames)")
    lengths.sort(key=lambda x: -x[1])
    print("  median fibre length vs L_path - tendon_slack_length (L of the drawn path): worst relative errors")
    for name, err in lengths[:worst]:
        print(f"    {name:16s} {100 * err:6.2f} %")
    n_len_bad = sum(1 for _, e in lengths if e > 0.05)
    print(f"  muscles outside 5 %: {n_len_bad} of {len(lengths)}")
    ref_dir = MODELS[key][3]
    if (ref_dir / "moment_arms.csv").is_file():
        diffs, worst_pairs = compare_opensim(res, ref_dir)
        if diffs.size:
            print(f"  median fibre vs OpenSim's computeMomentArm ({len(worst_pairs)} pairs, {diffs.size} values): "
                  f"median {1e3 * np.median(diffs):.3f} mm, p95 {1e3 * np.quantile(diffs, 0.95):.3f} mm, "
                  f"max {1e3 * diffs.max():.2f} mm; worst pairs (max diff, OpenSim's r there; mm):")
            for name, coord, d, r in sorted(worst_pairs, key=lambda p: -p[2])[:5]:
                print(f"    {name:16s} {coord:20s} {1e3 * d:6.2f}  r {1e3 * r:7.2f}")
    notes = [(m.name, n) for m in res.muscles for n in m.notes]
    if notes:
        print("  notes:")
        for name, n in notes[:40]:
            print(f"    {name}: {n}")
    return not bad and not n_len_bad


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="both", choices=("gait2392", "arm26", "rajagopal", "both"),
                        help="both: gait2392 and arm26")
    parser.add_argument("--frames", default=None,
                        help="motion rows (default: the OpenSim reference's: every 3rd for Gait2392, every 4th "
                             "for Rajagopal, all of Arm26's sweep)")
    parser.add_argument("--fibres", type=int, default=30)
    parser.add_argument("--resolution", type=int, default=12)
    parser.add_argument("--muscle", action="append", default=None)
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args(argv)
    if not OPENSIM.is_dir():
        print(f"needs {OPENSIM}", file=sys.stderr)
        return 2
    warnings.simplefilter("ignore")
    ok = True
    for key in (("gait2392", "arm26") if args.model == "both" else (args.model,)):
        res, slack, drawn, elapsed = run_model(key, frames=args.frames, fibres=args.fibres,
                                               resolution=args.resolution, muscles=args.muscle, jobs=args.jobs)
        ok &= report(key, res, slack, drawn, elapsed)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
