"""The library is safe to call from several threads at once, from a cold start (issue 13).

A fresh Python process with an empty numba cache (``NUMBA_CACHE_DIR``, so that nothing is
loaded from an earlier compile) starts its threads before any decomposition has run: four
threads decompose a generated muscle (both slicings, two templates) while two more run a small
`analysis.run` of the bundled example (three frames, ``jobs=2``: its muscles in threads too).
Every thread must finish without an exception and give the result of the same call made alone
afterwards in the same process (the library keeps no shared mutable state between calls).
"""
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r"""
import json, sys, threading, warnings
import numpy as np

import fibres
from motion import fusiform_surface

axis = np.array([[0.0, 0.0, 0.0], [0.002, 0.0, 0.05], [0.0, 0.001, 0.1]])
v, f = fusiform_surface(axis, max_radius=0.012, n_rings=30, n_around=24)
surface = fibres.as_surface((v, f))
o, i = v[:1] + [0.0, 0.0, 0.003], v[-1:] - [0.0, 0.0, 0.003]
o = o + np.array([[0, 0, 0], [0.002, 0, 0], [0, 0.002, 0]])
i = i + np.array([[0, 0, 0], [0.002, 0, 0], [0, 0.002, 0]])
CASES = [("parallel", "harmonic"), ("pennate", "planes"), ("parallel", "planes"),
         ("pennate", "harmonic")]

def decompose(case):
    template, slicing = case
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fibres.decompose(surface, o, i, template=template, slicing=slicing, n_fibres=20,
                                resolution=8, seed=3).points

def small_run(out):
    from analysis.cli_run import default_spec
    from analysis.run import run
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = run(default_spec(), frames="0:3", jobs=2, quiet=True, keep_surfaces=False)
    return {m.name: np.asarray(m.fibre_lengths) for m in res.muscles}

results, errors = {}, []
barrier = threading.Barrier(len(CASES) + 2)

def work(key, fn, arg):
    barrier.wait()
    try:
        results[key] = fn(arg)
    except BaseException as e:      # reported to the parent
        errors.append(f"{key}: {type(e).__name__}: {e}")

threads = [threading.Thread(target=work, args=(c, decompose, c)) for c in CASES]
threads += [threading.Thread(target=work, args=(("run", k), small_run, k)) for k in range(2)]
for t in threads:
    t.start()
for t in threads:
    t.join()
same = []
for c in CASES:
    if c in results:
        same.append(bool(np.allclose(results[c], decompose(c), rtol=0, atol=1e-12)))
runs = [results.get(("run", k)) for k in range(2)]
if all(r is not None for r in runs):
    same.append(all(np.allclose(runs[0][m], runs[1][m], rtol=0, atol=1e-12, equal_nan=True)
                    for m in runs[0]))
print(json.dumps({"errors": errors, "same": same, "n": len(results)}))
"""


def test_decompositions_and_runs_in_parallel_threads_from_a_cold_start(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"),
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", _CHILD], env=env, cwd=tmp_path,
                         capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["errors"] == []
    assert res["n"] == 6 and len(res["same"]) == 5 and all(res["same"])
