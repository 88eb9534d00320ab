"""Compiled loops that build `fibres.surface_distance.SurfaceGrid`: the mean edge, the
vertex bounds, the uniform grid of the triangles' bounding boxes (CSR), the inside/outside
labels of its empty cells and the triangles' normals, centroids and bounding-sphere radii.
Compiled with numba by `fibres.surface_distance._kernels`.
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
    """Coordinate-wise minimum and maximum of the vertices (V, 3) (running bounds in
    scalars)."""
    lx, ly, lz = v[0, 0], v[0, 1], v[0, 2]
    hx, hy, hz = lx, ly, lz
    for i in range(1, v.shape[0]):
        x, y, z = v[i, 0], v[i, 1], v[i, 2]
        lx, ly, lz = min(lx, x), min(ly, y), min(lz, z)
        hx, hy, hz = max(hx, x), max(hy, y), max(hz, z)
    return np.array([lx, ly, lz]), np.array([hx, hy, hz])


def _put(items, fill, q, t):  # pragma: no cover - compiled by numba (inlined)
    """Append triangle t to cell q's items (next free position fill[q])."""
    p = fill[q]
    items[p] = t
    fill[q] = p + 1


def _grid_loop(v, faces, lo, cell, dims):  # pragma: no cover - compiled by numba
    """The grid of the triangles' bounding boxes as CSR (start (cells + 1,), items), int32.

    Each vertex's cell is computed once: ``floor((x - lo) / cell)`` is monotone in x, so a
    triangle's range is the min/max of its vertices' cells (the cells of its coordinate-wise
    minimum and maximum). The counting pass keeps each triangle's first cell and its spans
    (21 bits each) for the filling pass. A triangle spanning at most 2 cells along each axis
    (nearly all: cells are >= 1.5 mean edges) has its cells enumerated by bit tests, without
    loops (whose short, varying trip counts cost more than the work: on the 15K bench mesh
    0.60 -> 0.48 ms); the others by the nested loops. Items stay in triangle order. (Slower:
    runs of consecutive triangles with equal cells counted and filled at once; (cell,
    triangle) pairs listed, then counting-sorted.)"""
    n_tri, n_v = faces.shape[0], v.shape[0]
    ny, nz = dims[1], dims[2]
    s1, s2 = nz, ny * nz          # the strides of j and i
    vc = np.empty(n_v * 3, np.int32)
    for i in range(n_v):
        for k in range(3):
            vc[3 * i + k] = min(max(int(np.floor((v[i, k] - lo[k]) / cell)), 0), dims[k] - 1)
    count = np.zeros(dims[0] * ny * nz + 1, np.int32)
    base = np.empty(n_tri, np.int32)
    span = np.empty(n_tri, np.int64)
    small = np.int64((1 << 42) | (1 << 21) | 1)   # the span bits of 0 or 1 more cell
    for t in range(n_tri):
        a, b, c = 3 * faces[t, 0], 3 * faces[t, 1], 3 * faces[t, 2]
        i0, i1 = min(vc[a], vc[b], vc[c]), max(vc[a], vc[b], vc[c])
        j0, j1 = min(vc[a + 1], vc[b + 1], vc[c + 1]), max(vc[a + 1], vc[b + 1], vc[c + 1])
        k0, k1 = min(vc[a + 2], vc[b + 2], vc[c + 2]), max(vc[a + 2], vc[b + 2], vc[c + 2])
        q0 = (i0 * ny + j0) * nz + k0
        base[t] = q0
        sp = (np.int64(i1 - i0) << 42) | (np.int64(j1 - j0) << 21) | (k1 - k0)
        span[t] = sp
        if sp & ~small == 0:   # counts (shifted by one: the prefix sum makes the starts)
            q = q0 + 1
            count[q] += 1
            if sp & 1:
                count[q + 1] += 1
            if sp & (1 << 21):
                count[q + s1] += 1
                if sp & 1:
                    count[q + s1 + 1] += 1
            if sp & (1 << 42):
                count[q + s2] += 1
                if sp & 1:
                    count[q + s2 + 1] += 1
                if sp & (1 << 21):
                    count[q + s2 + s1] += 1
                    if sp & 1:
                        count[q + s2 + s1 + 1] += 1
            continue
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
        if sp & ~small == 0:
            _put(items, fill, q0, t)
            if sp & 1:
                _put(items, fill, q0 + 1, t)
            if sp & (1 << 21):
                _put(items, fill, q0 + s1, t)
                if sp & 1:
                    _put(items, fill, q0 + s1 + 1, t)
            if sp & (1 << 42):
                _put(items, fill, q0 + s2, t)
                if sp & 1:
                    _put(items, fill, q0 + s2 + 1, t)
                if sp & (1 << 21):
                    _put(items, fill, q0 + s2 + s1, t)
                    if sp & 1:
                        _put(items, fill, q0 + s2 + s1 + 1, t)
            continue
        for i in range((sp >> 42) + 1):
            for j in range(((sp >> 21) & 2097151) + 1):
                qq = q0 + (i * ny + j) * nz
                for k in range((sp & 2097151) + 1):
                    _put(items, fill, qq + k, t)
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


def _flood(label, comp, s1, s2, stack, top, value, cid):  # pragma: no cover - numba
    """Flood the empty unlabelled cells (label 0) face-connected to the cells on the stack
    with ``value`` (and component ``cid`` when >= 0). The stacked cells are interior (not in
    the grid's border layer), so their six neighbours ``q -+ s2, q -+ s1, q -+ 1`` (strides
    of i and j) exist: no coordinates (divisions) and no range tests."""
    while top > 0:
        top -= 1
        q = stack[top]
        for a in range(6):
            if a == 0:
                w = q - s2
            elif a == 1:
                w = q + s2
            elif a == 2:
                w = q - s1
            elif a == 3:
                w = q + s1
            elif a == 4:
                w = q - 1
            else:
                w = q + 1
            if label[w] == 0:
                label[w] = value
                comp[w] = cid
                stack[top] = w
                top += 1


def _label_loop(start, dims):  # pragma: no cover - compiled by numba
    """Label the grid cells: 1 holds a triangle, 2 empty and face-connected to the grid's
    border through empty cells (outside), 3 the other empty cells, grouped in face-connected
    components ``comp`` (-1 elsewhere) with one representative cell each (its first cell in
    flat order). The empty border cells are labelled 2 first and the flood starts from
    their empty interior neighbours, so that `_flood` only ever stacks interior cells (the
    enclosed components hold no border cell either: every empty border cell is outside)."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    n = nx * ny * nz
    label = np.zeros(n, np.int8)
    comp = np.full(n, -1, np.int32)
    stack = np.empty(n, np.int64)
    top = 0
    for q in range(n):
        if start[q + 1] > start[q]:
            label[q] = 1
    for rnd in range(2):  # the empty border cells; then their empty interior neighbours
        for i in range(nx):
            for j in range(ny):  # (inner rows: their two end cells only)
                edge = i == 0 or j == 0 or i == nx - 1 or j == ny - 1
                for k in range(0, nz, 1 if edge else nz - 1):
                    q = (i * ny + j) * nz + k
                    if rnd == 0:
                        if label[q] == 0:
                            label[q] = 2
                        continue
                    if label[q] != 2:
                        continue
                    for a in range(6):
                        ii, jj, kk = i, j, k
                        if a == 0:
                            ii -= 1
                        elif a == 1:
                            ii += 1
                        elif a == 2:
                            jj -= 1
                        elif a == 3:
                            jj += 1
                        elif a == 4:
                            kk -= 1
                        else:
                            kk += 1
                        if 0 <= ii < nx and 0 <= jj < ny and 0 <= kk < nz:
                            w = (ii * ny + jj) * nz + kk
                            if label[w] == 0:
                                label[w] = 2
                                stack[top] = w
                                top += 1
    _flood(label, comp, nz, ny * nz, stack, top, 2, -1)
    reps = []
    for q in range(n):
        if label[q] == 0:
            cid = len(reps)
            reps.append(q)
            label[q] = 3
            comp[q] = cid
            stack[0] = q
            _flood(label, comp, nz, ny * nz, stack, 1, 3, cid)
    return label, comp, np.array(reps, dtype=np.int64)
