"""Compiled loops that build `fibres.surface_distance.SurfaceGrid`: the mean edge, the
vertex bounds, the uniform grid of the triangles' bounding boxes (CSR) and the triangles'
normals, centroids and bounding-sphere radii. Compiled with numba by
`fibres.surface_distance._kernels`.
"""
from __future__ import annotations

import numpy as np

__all__ = []


def _edge_loop(v, faces):  # pragma: no cover - compiled by numba
    """Mean length of the faces' edges."""
    total = 0.0
    for t in range(faces.shape[0]):
        for k in range(3):
            a, b = faces[t, k], faces[t, (k + 1) % 3]
            dx, dy, dz = v[b, 0] - v[a, 0], v[b, 1] - v[a, 1], v[b, 2] - v[a, 2]
            total += np.sqrt(dx * dx + dy * dy + dz * dz)
    return total / max(3 * faces.shape[0], 1)


def _bounds_loop(v):  # pragma: no cover - compiled by numba
    """Coordinate-wise minimum and maximum of the vertices (V, 3)."""
    lo = v[0].copy()
    hi = v[0].copy()
    for i in range(1, v.shape[0]):
        for k in range(3):
            lo[k] = min(lo[k], v[i, k])
            hi[k] = max(hi[k], v[i, k])
    return lo, hi


def _grid_loop(v, faces, lo, cell, dims):  # pragma: no cover - compiled by numba
    """The grid of the triangles' bounding boxes as CSR (start (cells + 1,), items), int32.

    Each vertex's cell is computed once: ``floor((x - lo) / cell)`` is monotone in x, so a
    triangle's range is the min/max of its vertices' cells (the cells of its coordinate-wise
    minimum and maximum). The counting pass keeps each triangle's first cell and its spans
    (21 bits each) for the filling pass."""
    n_tri, n_v = faces.shape[0], v.shape[0]
    ny, nz = dims[1], dims[2]
    vc = np.empty(n_v * 3, np.int32)
    for i in range(n_v):
        for k in range(3):
            vc[3 * i + k] = min(max(int(np.floor((v[i, k] - lo[k]) / cell)), 0), dims[k] - 1)
    count = np.zeros(dims[0] * ny * nz + 1, np.int32)
    base = np.empty(n_tri, np.int32)
    span = np.empty(n_tri, np.int64)
    for t in range(n_tri):
        a, b, c = 3 * faces[t, 0], 3 * faces[t, 1], 3 * faces[t, 2]
        i0, i1 = min(vc[a], vc[b], vc[c]), max(vc[a], vc[b], vc[c])
        j0, j1 = min(vc[a + 1], vc[b + 1], vc[c + 1]), max(vc[a + 1], vc[b + 1], vc[c + 1])
        k0, k1 = min(vc[a + 2], vc[b + 2], vc[c + 2]), max(vc[a + 2], vc[b + 2], vc[c + 2])
        q0 = (i0 * ny + j0) * nz + k0
        base[t] = q0
        span[t] = (np.int64(i1 - i0) << 42) | (np.int64(j1 - j0) << 21) | (k1 - k0)
        for i in range(i1 - i0 + 1):
            for j in range(j1 - j0 + 1):
                qq = q0 + (i * ny + j) * nz + 1
                for k in range(k1 - k0 + 1):
                    count[qq + k] += 1
    for q in range(1, count.shape[0]):
        count[q] += count[q - 1]
    items = np.empty(count[-1], np.int32)
    fill = count[:-1].copy()
    for t in range(n_tri):
        q0, sp = base[t], span[t]
        for i in range((sp >> 42) + 1):
            for j in range(((sp >> 21) & 2097151) + 1):
                qq = q0 + (i * ny + j) * nz
                for k in range((sp & 2097151) + 1):
                    items[fill[qq + k]] = t
                    fill[qq + k] += 1
    return count, items


def _triangle_shape(t, v, faces, nrm, centre, radius):  # pragma: no cover - compiled by numba
    """Unit normal, centroid and bounding-sphere radius of triangle t (in place)."""
    a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
    for k in range(3):
        centre[t, k] = (v[a, k] + v[b, k] + v[c, k]) / 3.0
    r2 = 0.0
    for q in (a, b, c):
        dx, dy, dz = v[q, 0] - centre[t, 0], v[q, 1] - centre[t, 1], v[q, 2] - centre[t, 2]
        r2 = max(r2, dx * dx + dy * dy + dz * dz)
    radius[t] = np.sqrt(r2)
    ux, uy, uz = v[b, 0] - v[a, 0], v[b, 1] - v[a, 1], v[b, 2] - v[a, 2]
    wx, wy, wz = v[c, 0] - v[a, 0], v[c, 1] - v[a, 1], v[c, 2] - v[a, 2]
    gx, gy, gz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    length = np.sqrt(gx * gx + gy * gy + gz * gz)
    if length > 0.0:
        nrm[t, 0], nrm[t, 1], nrm[t, 2] = gx / length, gy / length, gz / length
    else:
        nrm[t, 0] = nrm[t, 1] = nrm[t, 2] = 0.0


def _shapes_loop(v, faces, nrm, centre, radius):  # pragma: no cover - compiled by numba
    """`_triangle_shape` of every triangle (a plain loop, no per-triangle flags: ~5x faster
    than the lazy `fibres.surface_distance._shape` when all are needed)."""
    for t in range(faces.shape[0]):
        _triangle_shape(t, v, faces, nrm, centre, radius)
