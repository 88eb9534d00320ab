"""Test meshes and OpenSim read-outs shared by the motion tests."""
from __future__ import annotations

import numpy as np

from motion.surface.volume import mesh_volume


def capped_tube(start, end, radius, *, n_around=48, n_rings=61, ref=None):
    """Closed cylinder from ``start`` to ``end`` with flat caps (outward faces).

    Vertices: the start-cap centre, ``n_rings`` rings of ``n_around`` (ring angle 0 along ``ref``,
    a unit vector perpendicular to the axis; default: one chosen from the axis), the end-cap centre.
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    axis = end - start
    u = axis / np.linalg.norm(axis)
    if ref is None:
        e1 = np.cross(u, [0, 0, 1.0] if abs(u[2]) < 0.9 else [1.0, 0, 0])
        e1 /= np.linalg.norm(e1)
    else:
        e1 = np.asarray(ref, float)
    e2 = np.cross(u, e1)
    s = np.linspace(0, 1, n_rings)
    phi = 2 * np.pi * np.arange(n_around) / n_around
    ring = (start + s[:, None, None] * axis
            + radius * (np.cos(phi)[None, :, None] * e1 + np.sin(phi)[None, :, None] * e2))
    verts = np.concatenate([start[None], ring.reshape(-1, 3), end[None]])
    idx = 1 + np.arange(n_rings * n_around).reshape(n_rings, n_around)
    nxt = np.roll(idx, -1, axis=1)
    last = len(verts) - 1
    faces = np.concatenate([
        np.stack([np.zeros(n_around, int), nxt[0], idx[0]], 1),
        np.stack([idx[:-1], nxt[:-1], nxt[1:]], -1).reshape(-1, 3),
        np.stack([idx[:-1], nxt[1:], idx[1:]], -1).reshape(-1, 3),
        np.stack([np.full(n_around, last), idx[-1], nxt[-1]], 1)])
    if mesh_volume(verts, faces) < 0:
        faces = faces[:, ::-1]
    return verts, faces


def opensim_ground_transforms(bodies, state) -> list:
    """(B, 4, 4) transforms in ground of OpenSim bodies at ``state`` (v_ground = R v_body + t)."""
    out = []
    for body in bodies:
        x = body.getTransformInGround(state)
        tf = np.eye(4)
        tf[:3, 3] = [x.p()[i] for i in range(3)]
        tf[:3, :3] = [[x.R().get(i, j) for j in range(3)] for i in range(3)]
        out.append(tf)
    return out
