"""Benchmark: surface wrapping of one 15K-vertex muscle, one frame and a 100-frame motion.

Usage: python bench/wrap.py [--vertices 15000] [--frames 100] [--repeat 7]

A fusiform surface of ~15,000 vertices around a 0.25 m action line; its insertion body turns
about a pin 0.1 m from the origin (0-120 degrees over the motion). Times the per-motion call
`SurfaceBinding.deform` (resampling, rotation-minimising frames, sparse binding products,
cubic volume solve) without obstacles and with a wrap cylinder at the joint, and prints the
median over ``--repeat`` runs, total and per muscle-frame. Binding (once per muscle) is timed
separately.
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def _pin(theta, centre):
    c, s = np.cos(theta), np.sin(theta)
    tf = np.tile(np.eye(4), (len(theta), 1, 1))
    tf[:, 0, 0], tf[:, 0, 1], tf[:, 1, 0], tf[:, 1, 1] = c, -s, s, c
    tf[:, :3, 3] = centre - np.einsum("fij,j->fi", tf[:, :3, :3], centre)
    return tf


def _median_time(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv=None):
    from motion.surface.bind import bind_surface
    from motion.surface.collision import WrapObstacle
    from motion.surface.generate import fusiform_surface

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=15000)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args(argv)

    n_around = 50
    n_rings = max(3, round((args.vertices - 2) / n_around) + 2)
    origin, insertion = np.array([0.0, 0.03, 0.0]), np.array([0.25, 0.03, 0.0])
    rest_line = np.linspace(origin, insertion, 5)
    verts, faces = fusiform_surface(rest_line, max_radius=0.02, n_rings=n_rings, n_around=n_around)
    centre = np.array([0.1, 0.0, 0.0])

    t0 = time.perf_counter()
    binding = bind_surface(verts, faces, [rest_line], np.eye(4), np.eye(4), origin[None], insertion[None])
    t_bind = time.perf_counter() - t0

    def motion(n):
        theta = np.deg2rad(np.linspace(0.0, 120.0, n))
        tf_ins = _pin(theta, centre)
        ins = np.einsum("fij,j->fi", tf_ins[:, :3, :3], insertion) + tf_ins[:, :3, 3]
        # an action line with a few points, as a path with via points would have
        mid = centre + [0.0, 0.03, 0.0]
        line = np.stack([np.broadcast_to(origin, ins.shape), np.broadcast_to(mid, ins.shape), ins], axis=1)
        return [line], np.tile(np.eye(4), (n, 1, 1)), tf_ins

    tf_cyl = np.eye(4)
    tf_cyl[:3, 3] = centre
    pulley = [WrapObstacle("cylinder", tf_cyl, np.array([0.015, 0.015, 0.1]))]
    binding.deform(*motion(2))  # compile the volume kernel (numba) outside the timing
    print(f"surface: {len(verts)} vertices, {len(faces)} triangles; bind (once): {t_bind * 1e3:.1f} ms")
    for label, obstacles in (("no obstacles", ()), ("wrap cylinder", pulley)):
        for n in (1, args.frames):
            curves, tf_o, tf_i = motion(n)
            t = _median_time(lambda: binding.deform(curves, tf_o, tf_i, obstacles=obstacles), args.repeat)
            print(f"{label:14s} {n:4d} frame(s): median {t * 1e3:8.2f} ms  = {t * 1e3 / n:6.3f} ms per muscle-frame")


if __name__ == "__main__":
    main()
