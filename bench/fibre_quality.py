"""Fibre quality and moment arms of the LHDL hip muscles, harmonic against planar slicing.

    python bench/fibre_quality.py [--quality] [--moment-arms] [--speed] [--stages]
                                  [--paper-kinematics] [--repeats N]

``--quality``: `fibres.finishing.quality` of the four muscles (100 fibres x 15 segments), with the
templates of tests/data/lhdl_hip.toml and with ``parallel``, psoas with its own four lumbar
origin clouds, for both slicings. ``--moment-arms``: `analysis.run` of the TOML over the
dataset's flexion, adduction and rotation motions for both slicings; p5..p95, min..max,
mean and sd of the fibre moment arms over all fibres and frames, and the overlap (intersection
over union) of p5..p95 and of min..max with the ranges of Modenese & Kohout 2020, Table 2 (which
are peak values: the minimum and maximum over all fibres and poses), and the overlap of min..max
with the independent finite-element results of Blemker & Delp 2005 in the same table (their
peaks, as Modenese & Kohout digitised them). ``--speed``: medians of
the rest-pose decomposition (incl. patches and the harmonic solve) and of a frame with the
plan (a copy of the rest pose with 0.1 mm of noise on every vertex), one thread, warm process:
wall-clock time and process CPU time (the CPU time is the fairer figure on a shared, loaded
machine), and the CPU time of a bent frame (`bend`: 5, 10, 15 and 20 degrees, as in
tests/fibres/test_decompose_lhdl.py). ``--stages``: the rest decomposition's CPU time per stage
(medians over the repeats of each stage's summed calls; the stages are timed by wrapping the
functions `fibres.decompose` and `fibres.slicing.harmonic` call, so their sum is less than the
whole). ``--paper-kinematics``: the rest fibres of the TOML's muscles moved as Modenese & Kohout
2020 moved theirs (their Eq. 1: each point follows a blend of the pelvis' and the femur's
transforms, weight ``a t^2 - (a + 1) t + 1`` of the pelvis at the point's place ``t`` along the
fibre, ``a`` per muscle from their text; ``t`` by arc length, which is their point index on
evenly spaced points), each fibre's length fitted by a 4th-order polynomial of the coordinate and
its moment arm ``-dl/dq`` (their tendon excursion): the same statistics and overlaps as
``--moment-arms``, so that the fibres' geometry is compared under the paper's kinematics rather
than ours. Default: the first three.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
LHDL = ROOT.parent / "shared" / "muscles" / "LHDL_hip_r"
TOML = ROOT / "tests" / "data" / "lhdl_hip.toml"
MUSCLES = ("glut_max_r", "glut_med_r", "iliacus_r", "psoas_r")
TOML_TEMPLATES = {"glut_max_r": "parallel", "glut_med_r": "fanned", "iliacus_r": "fanned",
                  "psoas_r": "parallel"}
#: Modenese & Kohout 2020, Table 2, highly discretised muscles: the peak values (minimum and
#: maximum over all fibres and poses), the mean and its standard deviation (cm)
PAPER_CM = {
    "flexion": {"psoas_r": (0.9, 2.6, 1.9, 0.3), "iliacus_r": (1.3, 4.6, 3.0, 0.4),
                "glut_max_r": (-9.2, -1.9, -5.7, 0.9), "glut_med_r": (-3.5, 1.5, -1.5, 0.3)},
    "adduction": {"psoas_r": (0.5, 2.1, 1.4, 0.2), "iliacus_r": (-1.0, 1.6, 0.2, 0.2),
                  "glut_max_r": (-6.8, 5.4, -0.6, 0.3), "glut_med_r": (-7.5, -0.4, -5.1, 0.6)},
    "rotation": {"psoas_r": (-0.5, 0.4, -0.1, 0.1), "iliacus_r": (-0.2, 0.9, 0.3, 0.1),
                 "glut_max_r": (-3.9, 0.0, -2.3, 0.3), "glut_med_r": (-3.5, 3.1, -0.4, 0.5)}}
#: the same table's row "Blemker and Delp (2005)": peaks and mean (sd) of the finite-element
#: model of Blemker & Delp (Ann. Biomed. Eng. 33:661-673, 2005), digitised by Modenese & Kohout
#: from its Figs. 6 and 7 -- an independent reference for both models' fibres (cm)
BLEMKER_CM = {
    "flexion": {"psoas_r": (1.7, 3.0, 2.3, 0.1), "iliacus_r": (1.9, 5.1, 3.0, 0.4),
                "glut_max_r": (-7.2, -0.9, -4.2, 0.3), "glut_med_r": (-1.7, 2.1, 0.0, 0.3)},
    "adduction": {"psoas_r": (-0.5, 2.0, 1.2, 0.5), "iliacus_r": (-1.5, 1.5, 0.0, 0.5),
                  "glut_max_r": (-6.1, 7.1, 0.8, 1.9), "glut_med_r": (-5.4, 0.6, -3.1, 0.7)},
    "rotation": {"psoas_r": (-1.8, 0.8, -0.2, 0.4), "iliacus_r": (-0.1, 0.9, 0.5, 0.1),
                 "glut_max_r": (-4.2, -0.1, -2.2, 0.0), "glut_med_r": (-2.7, 2.2, -0.4, 0.2)}}
PAPER_FLEXION_CM = {name: v[:2] for name, v in PAPER_CM["flexion"].items()}
TASKS = {"flexion": ("hip_flexion.mot", "hip_flexion_r"),
         "adduction": ("hip_adduction.mot", "hip_adduction_r"),
         "rotation": ("hip_rotation.mot", "hip_rotation_r")}


def landmarks(muscle, *, own_origin=True):
    import pandas as pd

    tab = pd.read_csv(LHDL / "attachments" / "attachment_landmarks.csv")
    src = muscle if (own_origin or muscle != "psoas_r") else "iliacus_r"
    o = tab[(tab.muscle == src) & (tab.type == "origin")]
    i = tab[(tab.muscle == muscle) & (tab.type == "insertion")]
    if muscle == "glut_max_r":
        i = i[i.cloud == 1]
    cols = ["x_mm", "y_mm", "z_mm"]
    return o[cols].to_numpy(float) * 1e-3, i[cols].to_numpy(float) * 1e-3


def surface(muscle):
    from fibres import as_surface

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return as_surface(LHDL / "muscles_clean" / f"{muscle}.vtk", units="mm")


def bender(origin, insertion):
    """The smooth bend of the LHDL bend sweeps (tests/fibres/test_decompose_lhdl.py, `_bender`):
    a point turns by ``deg * t`` about an axis through the origin centroid, t its place along the
    attachment line clipped to 0..1."""
    import sys

    sys.path.insert(0, str(ROOT / "tests" / "fibres"))
    from test_decompose_lhdl import _bender

    return _bender(origin, insertion)


def quality():
    from fibres import decompose

    print("| muscle | template | slicing | empty > 5 mm | empty > spacing | turn max | turn p95 |"
          " origin covered | insertion covered | outside |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for muscle in MUSCLES:
        s = surface(muscle)
        o, i = landmarks(muscle)
        for template in dict.fromkeys((TOML_TEMPLATES[muscle], "parallel")):
            for slicing in ("harmonic", "planes"):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    b = decompose(s, o, i, template=template, n_fibres=100, resolution=15,
                                  slicing=slicing)
                q = b.quality
                print(f"| {muscle} | {template} | {slicing} | {q.empty_5mm:.1%} | "
                      f"{q.empty_spacing:.1%} | {q.turn_max:.1f} | {q.turn_p95:.1f} | "
                      f"{q.origin_covered:.0%} | {q.insertion_covered:.0%} | {q.outside} |")


def _iou(a, b):
    inter = max(0.0, min(a[1], b[1]) - max(a[0], b[0]))
    union = max(a[1], b[1]) - min(a[0], b[0])
    return inter / union if union > 0 else 0.0


def _print_moment_arms(task, name, r, lines, paper):
    """One line: p5..p95, min..max, mean (sd) of ``r`` (cm), the lines' range, the paper's
    peaks and mean (sd), the overlaps of p5..p95 and of min..max with the paper's peaks, and
    the overlaps of min..max with Blemker & Delp's peaks (`BLEMKER_CM`) for ours and for the
    paper's."""
    lo, hi = np.percentile(r, [5, 95])
    shown = "" if lines is None else f"   lines {lines.min():6.2f} .. {lines.max():6.2f}"
    fe = BLEMKER_CM[task][name]
    print(f"  {task:9s} {name:11s} {lo:6.2f} .. {hi:6.2f}   min..max {r.min():6.2f} .. "
          f"{r.max():6.2f}  mean {r.mean():5.2f} (sd {r.std():.2f}){shown}   paper "
          f"{paper[0]:.1f} .. {paper[1]:.1f} mean {paper[2]:.1f} (sd {paper[3]:.1f})  IoU "
          f"p5..p95 {_iou((lo, hi), paper[:2]):.2f}, min..max "
          f"{_iou((r.min(), r.max()), paper[:2]):.2f}   Blemker & Delp {fe[0]:.1f} .. "
          f"{fe[1]:.1f}: IoU min..max ours {_iou((r.min(), r.max()), fe[:2]):.2f}, paper's "
          f"{_iou(paper[:2], fe[:2]):.2f}")


def moment_arms():
    from analysis import run

    for slicing in ("harmonic", "planes"):
        print(f"\nslicing = {slicing}: fibre moment arms p5..p95 over fibres and frames (cm); "
              "action lines' range")
        for task, (mot, coord) in TASKS.items():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = run(TOML, LHDL / "model" / "motions" / mot, slicing=slicing,
                          keep_points=False)
            for m in res.muscles:
                c = list(m.coordinates).index(coord)
                _print_moment_arms(task, m.name, m.fibre_moment_arms[:, :, c] * 100,
                                   m.action_line_moment_arms[:, :, c] * 100,
                                   PAPER_CM[task][m.name])


#: Modenese & Kohout 2020, the blending parameter ``a`` of each muscle (their "Fibres
#: kinematics" paragraph; chosen there by eye against bone penetration)
PAPER_BLEND_A = {"psoas_r": -0.042, "iliacus_r": -0.024, "glut_max_r": -0.042, "glut_med_r": 0.0}


def paper_kinematics():
    from fibres import decompose
    from motion import body_poses, load_model, load_motion

    model = load_model(LHDL / "model" / "LHDL_hip_r.osim")
    bodies = [list(model.body_names).index(b) for b in ("pelvis", "femur_r")]
    print("\nfibres moved by the paper's pelvis/femur blend (harmonic slicing, the TOML's "
          "attachments): moment arms (cm) over fibres and frames")
    for muscle in MUSCLES:
        o, i = landmarks(muscle, own_origin=False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pts = decompose(surface(muscle), o, i, template=TOML_TEMPLATES[muscle],
                            n_fibres=100, resolution=15).points      # (N, P, 3), body frames
        arc = np.concatenate([np.zeros((len(pts), 1)),
                              np.cumsum(np.linalg.norm(np.diff(pts, axis=1), axis=-1), 1)], 1)
        t = arc / arc[:, -1:]
        a = PAPER_BLEND_A[muscle]
        w = (a * t ** 2 - (a + 1) * t + 1)[None, :, :, None]                # pelvis' weight
        homog = np.concatenate([pts, np.ones(pts.shape[:2] + (1,))], -1)
        for task, (mot, coord) in TASKS.items():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                motion = load_motion(LHDL / "model" / "motions" / mot, model)
            tf = body_poses(model, motion).tf_ground_body[:, bodies]          # (F, 2, 4, 4)
            moved = [np.einsum("fij,npj->fnpi", tf[:, k], homog)[..., :3] for k in (0, 1)]
            points = w * moved[0] + (1 - w) * moved[1]
            lengths = np.linalg.norm(np.diff(points, axis=2), axis=-1).sum(-1)   # (F, N)
            q = motion.q[:, list(motion.coordinate_names).index(coord)]
            fit = np.polynomial.polynomial.polyfit(q, lengths, 4)              # (5, N)
            r = -np.polynomial.polynomial.polyval(q, np.polynomial.polynomial.polyder(fit)).T
            _print_moment_arms(task, muscle, r * 100, None, PAPER_CM[task][muscle])


def speed(repeats):
    from fibres import decompose

    print("\n| muscle | vertices | rest decomposition (ms) | frame with the plan (ms) |"
          " rest, CPU (ms) | frame, CPU (ms) | bent frame, CPU (ms) |")
    print("|---|---|---|---|---|---|---|")
    for muscle in MUSCLES:
        s = surface(muscle)
        o, i = landmarks(muscle)
        v, f = s.vertices, s.faces
        opts = dict(template=TOML_TEMPLATES[muscle], n_fibres=100, resolution=15)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            b = decompose((v, f), o, i, **opts)
            rest, frame, rest_cpu, frame_cpu, bent_cpu = [], [], [], [], []
            bend = bender(o, i)
            bent = [(bend(v, deg), bend(o, deg), bend(i, deg)) for deg in (5, 10, 15, 20)]
            rng = np.random.default_rng(0)
            for _ in range(repeats):
                t, c = time.perf_counter(), time.process_time()
                decompose((v, f), o, i, **opts)
                rest.append(time.perf_counter() - t)
                rest_cpu.append(time.process_time() - c)
                w = v + 1e-4 * rng.standard_normal(v.shape)   # a deformed copy
                t, c = time.perf_counter(), time.process_time()
                decompose((w, f), o, i, plan=b.plan, **opts)
                frame.append(time.perf_counter() - t)
                frame_cpu.append(time.process_time() - c)
                for w, bo, bi in bent:
                    c = time.process_time()
                    decompose((w, f), bo, bi, plan=b.plan, **opts)
                    bent_cpu.append(time.process_time() - c)
        print(f"| {muscle} | {len(v)} | {np.median(rest) * 1e3:.1f} | {np.median(frame) * 1e3:.1f} | "
              f"{np.median(rest_cpu) * 1e3:.1f} | {np.median(frame_cpu) * 1e3:.1f} | "
              f"{np.median(bent_cpu) * 1e3:.1f} |")


#: (module, function, label) of the rest decomposition's stages timed by ``--stages``
STAGES = (("fibres.decompose", "_inputs", "inputs (mesh clean check)"),
          ("fibres.slicing.harmonic", "mesh_edges", "plan: mesh edges"),
          ("fibres.slicing.harmonic", "attachment_patches", "plan: attachment patches"),
          ("fibres.slicing.harmonic", "harmonic_field", "plan: harmonic field solve"),
          ("fibres.slicing.harmonic_sections", "_levels", "slices: levels"),
          ("fibres.slicing.harmonic_sections", "isoline_loops_at", "slices: isoline loops"),
          ("fibres.slicing.harmonic_sections", "_registered_seam", "slices: seams"),
          ("fibres.slicing.harmonic", "_slices", "slices (all)"),
          ("fibres.slicing.harmonic", "mean_value_coordinates", "fibre map: mean value coords"),
          ("fibres.slicing.harmonic", "area_points", "fibre map: ends onto the patches"),
          ("fibres.slicing.harmonic", "relax_on_patches", "fibre map: ends' Lloyd steps"),
          ("fibres.slicing.harmonic", "_fibre_matrix", "fibre map (all)"),
          ("fibres.slicing.harmonic", "fairing_operator", "fairing matrices"),
          ("fibres.finishing.carried_pull", "contain", "containment pull (all rounds)"))


def stages(repeats):
    import importlib
    from collections import defaultdict

    from fibres import decompose

    spent = defaultdict(float)
    for mod, name, label in STAGES:
        module = importlib.import_module(mod)

        def timed(*a, _f=getattr(module, name), _label=label, **k):
            c = time.process_time()
            try:
                return _f(*a, **k)
            finally:
                spent[_label] += time.process_time() - c
        setattr(module, name, timed)
    table = {}
    for muscle in MUSCLES:
        s = surface(muscle)
        o, i = landmarks(muscle)
        opts = dict(template=TOML_TEMPLATES[muscle], n_fibres=100, resolution=15)
        runs = defaultdict(list)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            decompose((s.vertices, s.faces), o, i, **opts)
            for _ in range(repeats):
                spent.clear()
                c = time.process_time()
                decompose((s.vertices, s.faces), o, i, **opts)
                runs["whole rest decomposition"].append(time.process_time() - c)
                for label, t in spent.items():
                    runs[label].append(t)
        table[muscle] = {k: np.median(v) * 1e3 for k, v in runs.items()}
    print("\n| stage, CPU ms | " + " | ".join(MUSCLES) + " |")
    print("|---|" + "---|" * len(MUSCLES))
    labels = ["whole rest decomposition"] + [label for _, _, label in STAGES]
    for label in labels:
        print(f"| {label} | " + " | ".join(f"{table[m].get(label, 0.0):.1f}" for m in MUSCLES)
              + " |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quality", action="store_true")
    parser.add_argument("--moment-arms", action="store_true")
    parser.add_argument("--speed", action="store_true")
    parser.add_argument("--stages", action="store_true")
    parser.add_argument("--paper-kinematics", action="store_true")
    parser.add_argument("--repeats", type=int, default=11)
    args = parser.parse_args()
    every = not (args.quality or args.moment_arms or args.speed or args.stages
                 or args.paper_kinematics)
    if not LHDL.is_dir():
        raise SystemExit(f"needs the LHDL data at {LHDL}")
    if every or args.quality:
        quality()
    if every or args.speed:
        speed(args.repeats)
    if every or args.moment_arms:
        moment_arms()
    if args.stages:
        stages(args.repeats)
    if args.paper_kinematics:
        paper_kinematics()


if __name__ == "__main__":
    main()
