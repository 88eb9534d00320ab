"""Benchmark `fibres.decompose` on muscle-like closed surfaces (one core).

A fusiform muscle (spindle of revolution, elliptic cross-section, bent and twisted along its
length so that no section is a circle) is meshed as a closed latitude-longitude surface of
about 1K, 15K and 60K vertices; it is decomposed into 25/100/400 fibres x 20 points (parallel
template, default attachment filtering and smoothing). Each case is timed over >= 15
repeats (median), both without a plan (every choice made afresh, the rest-pose cost) and
with the plan of the first run reused on a slightly deformed copy (the per-frame cost of a
motion).

    OMP_NUM_THREADS=1 python bench/decompose.py [--repeats 15] [--profile] [--breakdown]

``--breakdown`` times the stages of the 15K x 100 rest-pose decomposition (no plan) in
context: each stage function is wrapped with a CPU-time timer for the run (inclusive
times; the functions called inside a stage are listed indented under it).
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402


def fusiform_surface(n_vertices: int, *, length: float = 0.2):
    """Closed spindle-shaped muscle surface with about ``n_vertices`` vertices (metres).

    Returns (vertices (V, 3), faces (T, 3), origin (K, 3), insertion (K, 3)).
    """
    n_z = max(int(round(np.sqrt(n_vertices / 1.5))), 4)
    n_t = max(int(round(n_vertices / n_z)), 8)
    u = np.linspace(0.0, 1.0, n_z + 2)[1:-1]                   # rings (poles separate)
    th = np.linspace(0.0, 2 * np.pi, n_t, endpoint=False)
    radius = 0.02 * np.sin(np.pi * u) ** 0.8 + 0.002
    z = length * (u - 0.5)
    bend = 0.02 * np.sin(np.pi * u)                           # bow to +x
    twist = 0.6 * u
    a = radius[:, None] * 1.4 * np.cos(th[None])
    b = radius[:, None] * 0.8 * np.sin(th[None])
    x = np.cos(twist)[:, None] * a - np.sin(twist)[:, None] * b + bend[:, None]
    y = np.sin(twist)[:, None] * a + np.cos(twist)[:, None] * b
    v = np.stack([x, y, np.broadcast_to(z[:, None], x.shape)], -1).reshape(-1, 3)
    v = np.vstack([v, [0, 0, -length / 2], [0, 0, length / 2]])
    i, j = np.arange(n_z - 1)[:, None], np.arange(n_t)[None]
    p, q = i * n_t + j, i * n_t + (j + 1) % n_t
    faces = [np.stack([p, q + n_t, q], -1).reshape(-1, 3),
             np.stack([p, p + n_t, q + n_t], -1).reshape(-1, 3)]
    s, n = n_z * n_t, n_z * n_t + 1
    jj = np.arange(n_t)
    last = (n_z - 1) * n_t
    faces += [np.stack([np.full(n_t, s), jj, (jj + 1) % n_t], 1),
              np.stack([np.full(n_t, n), last + (jj + 1) % n_t, last + jj], 1)]
    f = np.vstack(faces).astype(np.int64)[:, ::-1]             # outward normals
    tip_o, tip_i = v[-2], v[-1]
    ring = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    spread = 0.004 * np.c_[np.cos(ring), np.sin(ring), np.zeros(8)]
    return v, f, tip_o + spread + [0, 0, 0.004], tip_i + spread - [0, 0, 0.004]


def _median_ms(fn, repeats):
    """Median wall-clock and CPU (process) time in ms; CPU time is the robust one on a
    shared machine."""
    fn()                                                        # warm-up (JIT, caches)
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return 1e3 * float(np.median(wall)), 1e3 * float(np.median(cpu))


#: (module, function, users importing it by name) timed by --breakdown; indented rows are
#: inside the row above them
_STAGES = (("fibres.decompose", "_clean_tuple", ()),
           ("fibres.mesh.surface", "clean_mesh_geometry", ("fibres.decompose",)),
           ("fibres.decompose", "_new_plan", ()),
           ("fibres.fit.fitting", "principal_frame", ("fibres.decompose",)),
           ("fibres.decompose", "_cross_section_ref", ()),
           ("fibres.fit.fitting", "fit_box", ("fibres.decompose",)),
           ("fibres.decompose", "_sweep", ()),
           ("fibres.plan", "box_and_local", ("fibres.decompose",)),
           ("fibres.slicing.planes", "slice_mesh", ("fibres.decompose",)),
           ("fibres.slicing.contours", "choose_loops", ("fibres.decompose",)),
           ("fibres.slicing.morph", "slice_maps", ("fibres.decompose",)),
           ("fibres.decompose", "_morph_fibres", ()),
           ("fibres.slicing.morph", "morph_local", ("fibres.decompose",)),
           ("fibres.attachments.filtering", "filter_choices", ("fibres.decompose",)),
           ("fibres.attachments.filtering", "_fused_choices", ()),
           ("fibres.attachments.filtering", "apply_filter", ("fibres.decompose",)),
           ("fibres.decompose", "contain_points", ()),
           ("fibres.finishing.smoothing", "smooth", ("fibres.decompose",)))
_INNER = {"clean_mesh_geometry", "principal_frame", "_cross_section_ref", "fit_box",
          "box_and_local", "slice_mesh", "choose_loops", "slice_maps", "morph_local",
          "_fused_choices"}


def breakdown(n_runs: int = 40):
    """Per-stage CPU time (ms per decomposition, min over 3 rounds of ``n_runs``) of the 15K
    x 100 rest-pose decomposition, measured in context by wrapping the stage functions."""
    import importlib

    from fibres import decompose

    acc = {}

    def timed(name, fn):
        def run(*a, **k):
            t0 = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                acc[name] = acc.get(name, 0.0) + time.process_time() - t0
        return run

    saved = []
    for mod_name, name, users in _STAGES:  # wrap each stage where it is looked up
        try:
            fn = getattr(importlib.import_module(mod_name), name)
        except (ImportError, AttributeError):       # a stage this version does not have
            continue
        for m in (mod_name,) + users:
            mod = importlib.import_module(m)
            if hasattr(mod, name):
                saved.append((mod, name, getattr(mod, name)))
                setattr(mod, name, timed(name, fn))
    v, f, o, i = fusiform_surface(15_000)
    try:
        decompose((v, f), o, i)                                  # warm-up
        best, total = {}, float("inf")
        for _ in range(3):  # rounds
            acc.clear()
            t0 = time.process_time()
            for _ in range(n_runs):  # decompositions
                decompose((v, f), o, i)
            total = min(total, (time.process_time() - t0) / n_runs)
            for k, t in acc.items():
                best[k] = min(best.get(k, float("inf")), t / n_runs)
    finally:
        for mod, name, fn in saved:
            setattr(mod, name, fn)
    print(f"stages of one 15K x 100 rest-pose decomposition, CPU ms (total {1e3 * total:.2f})")
    for _, name, _ in _STAGES:
        if name in best:
            indent = "    " if name in _INNER else "  "
            print(f"{indent}{name:<24s} {1e3 * best[name]:7.3f}")


def main(argv=None):
    from fibres import decompose

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--profile", action="store_true", help="cProfile the 15K x 100 case")
    ap.add_argument("--breakdown", action="store_true",
                    help="time the stages of the 15K x 100 rest-pose case and stop")
    args = ap.parse_args(argv)
    if args.breakdown:
        breakdown()
        return
    print("median over repeats, ms: wall (cpu). no plan = rest pose, every choice afresh; "
          "plan = per frame; core = plan, no attachment filter, no smoothing")
    print(f"{'vertices':>9} {'fibres':>6} {'points':>6} {'no plan':>16} {'plan':>16} "
          f"{'core':>16}")
    for n_v in (1_000, 15_000, 60_000):
        v, f, o, i = fusiform_surface(n_v)
        for n_f in ((25, 100, 400) if n_v == 15_000 else (100,)):
            rest = decompose((v, f), o, i, n_fibres=n_f, resolution=19)
            moved = v + 1e-4 * np.sin(v[:, [2, 0, 1]] * 30.0)     # a small smooth deformation
            t_fresh = _median_ms(lambda: decompose((v, f), o, i, n_fibres=n_f, resolution=19),
                                 args.repeats)
            t_plan = _median_ms(lambda: decompose((moved, f), o, i, n_fibres=n_f, resolution=19,
                                                  plan=rest.plan), args.repeats)
            t_core = _median_ms(lambda: decompose((moved, f), o, i, n_fibres=n_f, resolution=19,
                                                  plan=rest.plan, filter_attachments=False,
                                                  smoothing_iterations=0), args.repeats)
            cells = " ".join(f"{w:>8.2f} ({c:>5.1f})" for w, c in (t_fresh, t_plan, t_core))
            print(f"{len(v):>9} {n_f:>6} {20:>6} {cells}", flush=True)
    if args.profile:
        import cProfile
        import pstats

        v, f, o, i = fusiform_surface(15_000)
        rest = decompose((v, f), o, i)
        cProfile.runctx("for _ in range(20): decompose((v, f), o, i, plan=rest.plan)",
                        globals(), {"decompose": decompose, "v": v, "f": f, "o": o, "i": i,
                                    "rest": rest}, "/tmp/decompose.prof")
        pstats.Stats("/tmp/decompose.prof").sort_stats("tottime").print_stats(25)


if __name__ == "__main__":
    main()
