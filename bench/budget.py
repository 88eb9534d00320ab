"""Peak memory of `analysis.run` against its up-front estimate (`analysis.budget`).

    python bench/budget.py FRAMES FIBRES RESOLUTION JOBS      # e.g. 200 100 19 1

Runs the bundled example over a synthetic elbow flexion of FRAMES frames and builds the two big
tables, then prints the growth of the peak resident size during the run beside the estimate
(`settings["estimate"]["memory_bytes"]`) and their ratio. Measured (shared 2-core machine):
200 x 100 x 19, 1 job: 918 MiB vs 987 MiB (0.93); 400 x 300 x 19, 1 job: 2996 vs 4654 MiB (0.64);
200 x 300 x 19, 2 jobs: 1769 vs 4572 MiB (0.39: the estimate counts both muscles' peaks at once).
"""
import resource
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import analysis  # noqa: E402
import motion  # noqa: E402
from analysis.budget import resident_bytes  # noqa: E402
from analysis.tables import fibre_lengths_table, fibre_moment_arms_table  # noqa: E402


def main(argv):
    warnings.simplefilter("ignore")
    frames, fibres, resolution, jobs = (int(a) for a in argv)
    spec = analysis.load_spec(Path(__file__).resolve().parents[1] / "models" / "arm_example.toml")
    q = np.radians(np.linspace(0, 130, frames))[:, None]
    mot = motion.Motion.from_array(spec.model, np.arange(frames) * 0.01, q)
    before = resident_bytes()
    res = analysis.run(spec, mot, fibres=fibres, resolution=resolution, jobs=jobs)
    fibre_lengths_table(res)
    fibre_moment_arms_table(res)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    est = res.settings["estimate"]["memory_bytes"]
    print(f"{frames} frames x {fibres} fibres x {resolution} segments, {jobs} job(s): peak growth "
          f"{(peak - before) / 2**20:.0f} MiB, estimate {est / 2**20:.0f} MiB, ratio {(peak - before) / est:.2f}")


if __name__ == "__main__":
    main(sys.argv[1:] or ["200", "100", "19", "1"])
