"""Fibre-resolved OpenSim models in OpenSim 4.6: per muscle, how well OpenSim's fibre-muscle
lengths and computeMomentArm match our fibre lengths and moment arms over the motion.

Usage (from the repository root; needs the opensim package)::

    python bench/osim_export.py [SPEC ...] [--fibres N]

Default SPECs: the bundled arm (models/arm_example.toml) and the LHDL hip (tests/data/lhdl_hip.toml,
skipped without ../shared). For each: `analysis.run` over the fibre model's motion, `fibres
export-osim`'s `export_osim`, then OpenSim loads the model, initSystem(), poses every frame and
reports per muscle the median and worst |L_opensim - L_ours| and |r_opensim - r_ours| over all
frames and fibres (mm), the fibres over the acceptance limits (0.5 mm, 1 mm), the orders and
samples chosen, and the times. Then AnalyzeTool with a MuscleAnalysis runs on the model.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def opensim_check(osim_file, result, names):
    import opensim as osim

    model = osim.Model(str(osim_file))
    state = model.initSystem()
    cs = model.getCoordinateSet()
    out = {}
    for m in result.muscles:
        muscles = [model.getMuscles().get(n) for n in names[m.name]]
        coords = [cs.get(c) for c in m.coordinates]
        lengths = np.empty(m.fibre_lengths.shape)
        arms = np.empty(m.fibre_moment_arms.shape)
        for f in range(len(result.time)):
            for i, name in enumerate(result.coordinate_names):
                cs.get(name).setValue(state, float(result.q[f, i]), False)
            model.realizePosition(state)
            for k, mus in enumerate(muscles):
                lengths[f, k] = mus.getLength(state)
                for j, c in enumerate(coords):
                    arms[f, k, j] = mus.computeMomentArm(state, c)
        out[m.name] = (np.abs(lengths - m.fibre_lengths), np.abs(arms - m.fibre_moment_arms))
    return out


def muscle_analysis(osim_file, motion_file, folder):
    import opensim as osim

    tool = osim.AnalyzeTool()
    tool.setModelFilename(str(osim_file))
    tool.setName("check")
    tool.setCoordinatesFileName(str(motion_file))
    tool.setInitialTime(-1e9)
    tool.setFinalTime(1e9)
    tool.setResultsDir(str(folder))
    ma = osim.MuscleAnalysis()
    ma.setComputeMoments(False)
    tool.getAnalysisSet().cloneAndAppend(ma)
    tool.printToXML(str(Path(folder) / "setup.xml"))
    ok = osim.AnalyzeTool(str(Path(folder) / "setup.xml")).run()
    table = osim.TimeSeriesTable(str(Path(folder) / "check_MuscleAnalysis_Length.sto"))
    return ok, table.getNumRows(), table.getNumColumns()


def main():
    import analysis
    from analysis.osim_export import export_osim, fibre_muscle_names
    from analysis.spec import load_spec

    ap = argparse.ArgumentParser()
    ap.add_argument("specs", nargs="*", default=[str(ROOT / "models" / "arm_example.toml"),
                                                  str(ROOT / "tests" / "data" / "lhdl_hip.toml")])
    ap.add_argument("--fibres", type=int, default=None)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    for spec_file in args.specs:
        try:
            spec = load_spec(spec_file)
        except Exception as exc:   # noqa: BLE001 - e.g. ../shared absent
            print(f"{spec_file}: skipped ({exc})")
            continue
        t0 = time.perf_counter()
        result = analysis.run(spec, fibres=args.fibres, keep_points=False)
        t1 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "fibres.osim"
            record = export_osim(spec, result, out)
            t2 = time.perf_counter()
            names = {m.name: fibre_muscle_names(m.name, m.n_fibres) for m in result.muscles}
            errors = opensim_check(out, result, names)
            ok, rows, cols = muscle_analysis(out, spec.motion_path, tmp)
        print(f"{Path(spec_file).name}: {len(result.time)} frames; run {t1 - t0:.1f} s, fit + export {t2 - t1:.1f} s; "
              f"AnalyzeTool/MuscleAnalysis ran: {ok} ({rows} rows x {cols} fibre muscles)")
        print(f"  {'muscle':12s} {'L median':>9s} {'L worst':>8s} {'r median':>9s} {'r worst':>8s}  "
              f"{'>0.5mm':>6s} {'>1mm':>5s}  samples  orders")
        for name, (dl, dr) in errors.items():
            rep = record["muscles"][name]
            orders = np.bincount(rep["order"])
            print(f"  {name:12s} {1e3 * np.median(dl):9.4f} {1e3 * dl.max():8.4f} {1e3 * np.median(dr):9.4f} "
                  f"{1e3 * dr.max():8.4f}  {int((dl.max(0) > 5e-4).sum()):6d} {int((dr.max(axis=(0, 2)) > 1e-3).sum()):5d}"
                  f"  {rep['n_samples']:7d}  " + " ".join(f"{o}:{c}" for o, c in enumerate(orders) if c))


if __name__ == "__main__":
    main()
