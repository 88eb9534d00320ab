"""Probe: one wrap kernel as a casadi expression graph vs the numpy dual-number code.

Usage: python bench/casadi_probe.py [--rows 36000] [--repeat 5]

The kernel is Eberly's closest point on an ellipsoid (OpenSim ``WrapEllipsoid::findClosestPoint``,
the innermost loop of ellipsoid wrapping: the hybrid method calls it on 298 chord samples per
wrapped segment and frame). casadi cannot run a data-dependent ``while``: the Newton
iteration is unrolled to OpenSim's 64 steps, each frozen by ``if_else`` once |f| < 1e-9, and
the point's Jacobian (3 x 3) comes from casadi's algorithmic differentiation. It is evaluated
on ``--rows`` points (a typical Arm26 call: 121 frames x 298 samples) with ``Function.map``
(serial) in casadi's SX virtual machine, and, if a C compiler is found, as generated C code
compiled with ``-O2`` (compile time reported). The numpy side is
``closest_point_on_ellipsoid`` of the numpy oracle (``tests/motion/wrap_oracle``) on its ``Dual`` arrays
seeded with the 3 x 3 identity. Both give the same points (max |difference| printed).

casadi is not a dependency of the package (see ``docs/decisions.md``: it cannot be imported in a
process that has imported opensim 4.6); install it to run this probe (``pip install casadi``),
in a process without opensim.
"""
from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RADII = (0.06, 0.04, 0.05)


def casadi_function(ca):
    """SX function x (3,) -> (closest point (3,), its Jacobian (3, 3)), Newton unrolled."""
    x = ca.SX.sym("x", 3)
    a, b, c = RADII
    a2, b2, c2 = a * a, b * b, c * c
    u, v, w = x[0], x[1], x[2]
    a2u2, b2v2, c2w2 = u * u * a2, v * v * b2, w * w * c2
    inside = (u / a) ** 2 + (v / b) ** 2 + (w / c) ** 2 < 1.0
    t = ca.if_else(inside, 0.0, ca.sqrt(u * u + v * v + w * w) * max(RADII))
    done = ca.SX(0)
    for _ in range(64):
        p, q, r = t + a2, t + b2, t + c2
        p2, q2, r2 = p * p, q * q, r * r
        f = p2 * q2 * r2 - a2u2 * q2 * r2 - b2v2 * p2 * r2 - c2w2 * p2 * q2
        done = ca.logic_or(done, ca.fabs(f) < 1e-9)
        pq, pr, qr = p * q, p * r, q * r
        fp = (pq * r * (qr + pr + pq) - a2u2 * qr * (q + r) - b2v2 * pr * (p + r) - c2w2 * pq * (p + q)) * 2.0
        t = ca.if_else(done, t, t - f / fp)
    point = ca.vertcat(u * a2 / (t + a2), v * b2 / (t + b2), w * c2 / (t + c2))
    return ca.Function("closest", [x], [point, ca.jacobian(point, x)])


def numpy_side(pts):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "motion"))
    from wrap_oracle.dual import Dual      # the numpy oracle of the compiled wrapping
    from wrap_oracle.ellipsoid import closest_point_on_ellipsoid

    eye = np.eye(3)
    u, v, w = (Dual(pts[:, i], np.broadcast_to(eye[i], (len(pts), 3)).copy()) for i in range(3))
    with np.errstate(all="ignore"):
        return closest_point_on_ellipsoid(np.array(RADII), u, v, w, special_axis=None)


def _median(fn, repeat):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=121 * 298)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    try:
        import casadi as ca
    except ImportError:
        print("casadi is not installed (pip install casadi); nothing to compare")
        return 1
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(args.rows, 3)) * 0.05            # inside and outside the ellipsoid
    t0 = time.perf_counter()
    fun = casadi_function(ca)
    mapped = fun.map(args.rows)
    t_build = time.perf_counter() - t0
    t_np, res = _median(lambda: numpy_side(pts), args.repeat)
    t_vm, (p_vm, _) = _median(lambda: mapped(pts.T), args.repeat)
    ours = np.stack([r.v for r in res], axis=0)
    print(f"{args.rows} points, median of {args.repeat}")
    print(f"  numpy dual numbers (motion.wrapping):     {t_np * 1e3:9.1f} ms")
    print(f"  casadi SX virtual machine (map):          {t_vm * 1e3:9.1f} ms  (graph built in {t_build:.2f} s, "
          f"{fun.n_instructions()} instructions per point)  max |d point| {np.abs(np.array(p_vm) - ours).max():.1e}")
    if shutil.which("gcc") or shutil.which("cc"):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            src = Path(tmp) / "closest_map.c"
            cg = ca.CodeGenerator(src.name, {"with_header": False})
            cg.add(mapped)
            cg.generate(tmp + "/")
            lib = Path(tmp) / "closest_map.so"
            import subprocess
            subprocess.run([shutil.which("gcc") or "cc", "-O2", "-fPIC", "-shared", str(src), "-o", str(lib)],
                           check=True)
            compiled = ca.external(mapped.name(), str(lib))
            t_cc = time.perf_counter() - t0
            t_c, (p_c, _) = _median(lambda: compiled(pts.T), args.repeat)
        print(f"  casadi generated C (-O2):                 {t_c * 1e3:9.1f} ms  (generate + compile {t_cc:.1f} s)"
              f"  max |d point| {np.abs(np.array(p_c) - ours).max():.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
