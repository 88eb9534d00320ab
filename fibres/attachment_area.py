"""Attachment areas of the attachment filter (`fibres.filtering`; Kohout et al., GRAPP 2012, §3.4).

Attachment area on the surface (our reading of "the part of the surface cut out at the contour
of the projected landmarks"): every landmark is projected to its nearest surface vertex; the
area is the set of surface vertices within ``r`` of a projected landmark, where r is the median
distance between neighbouring landmarks (at least the mean edge length of the surface), plus
the projections themselves. For one landmark the area is its projection and that vertex's
neighbourhood of radius r = mean edge length.

`_region_indices` finds the area by brute force over the vertices (no KD-tree of the surface:
K landmarks need K distances per vertex, cheaper than building a tree); numba-compiled loops
(`_nearest_loop`, `_within_loop`) prune that search with the bounding boxes of blocks of
consecutive vertices (`_blocks_loop`) -- exact, the same areas as the array version.
"""
from __future__ import annotations

import numpy as np

__all__ = ["attachment_region"]


def _region_indices(vertices, faces, landmarks, vt=None, mean_edge=None,
                   blocks=None) -> np.ndarray:
    """Vertex indices of an attachment area (module docstring), by brute force over the
    vertices, component-wise (no KD-tree of the surface: K landmarks need K distances per
    vertex, cheaper than building a tree; compiled: pruned by the vertex blocks' boxes,
    `_blocks_loop`). ``vt`` (3, V), ``mean_edge`` and (compiled) ``blocks``
    (`_blocks_loop` of ``vt``) may be passed when already computed."""
    vt = np.ascontiguousarray(vertices.T) if vt is None else vt
    landmarks = np.asarray(landmarks, float).reshape(-1, 3)
    radius = _mean_edge(vt, faces) if mean_edge is None else mean_edge
    if len(landmarks) > 1:
        dl = np.sqrt(_sq_distances(np.ascontiguousarray(landmarks.T), landmarks))
        np.fill_diagonal(dl, np.inf)
        near = np.sort(dl.min(axis=1))  # their median (np.median's arithmetic, ~10x faster)
        h = len(near) // 2
        radius = max(radius, float(near[h] if len(near) % 2 else (near[h - 1] + near[h]) / 2))
    kernels = _kernels()
    if kernels is not None:
        blocks = kernels[3](vt) if blocks is None else blocks
        nearest = kernels[0](vt, landmarks, blocks)
        within = kernels[1](vt, np.ascontiguousarray(vertices[np.unique(nearest)]),
                            radius * radius, blocks)
        within[nearest] = True          # the sorted union, without np.unique's sort
        return np.flatnonzero(within)
    d2 = _sq_distances(vt, landmarks)                                  # (K, V)
    nearest = np.argmin(d2, axis=1)
    proj = np.unique(nearest)
    # |x - proj| <= r needs |x - landmark| <= r + |landmark - proj| (triangle inequality):
    # only those candidates are measured exactly
    reach = radius + np.sqrt(d2[np.arange(len(landmarks)), nearest])
    cand = np.flatnonzero((d2 <= (reach[:, None] * (1 + 1e-9)) ** 2).any(axis=0))
    near = (_sq_distances(vt[:, cand], vertices[proj]) <= radius * radius).any(axis=0)
    return np.unique(np.concatenate([cand[near], nearest.astype(np.int64)]))


_KERNELS = []


def _kernels():
    """(nearest vertex per point, vertices within a radius of some point, sum of edge
    lengths) compiled with numba, or None (then numpy, component-wise: the same arithmetic
    in the same order)."""
    if not _KERNELS:
        try:
            import numba
        except ImportError:                                     # pragma: no cover - optional
            _KERNELS.append(None)
        else:
            jit = numba.njit(cache=True, nogil=True)
            _KERNELS.append((jit(_nearest_loop), jit(_within_loop), jit(_edge_sum_loop),
                             jit(_blocks_loop)))
    return _KERNELS[0]


#: vertices per block of `_blocks_loop`
_BLOCK = 64


def _blocks_loop(vt):  # pragma: no cover - compiled by numba
    """Bounding boxes (B, 6) (x lo, x hi, y lo, y hi, z lo, z hi) of the vertices (3, V) in
    blocks of `_BLOCK` consecutive indices, for the pruned searches of `_nearest_loop` and
    `_within_loop` (made once per `filter_choices` call, shared by both areas).

    Pruning with them is exact: a vertex x in a block with box [lo, hi] has
    ``|p - x| >= max(lo - p, p - hi, 0)`` per coordinate, and rounding (subtraction, square,
    sum in the same order) is monotone, so the rounded box distance is at most the rounded
    vertex distance."""
    n_v = vt.shape[1]
    bs = _BLOCK
    n_b = (n_v + bs - 1) // bs
    box = np.empty((n_b, 6))
    for b in range(n_b):
        i0, i1 = b * bs, min(b * bs + bs, n_v)
        for c in range(3):
            # four independent running minima / maxima (one chain is latency-bound; the
            # minimum and maximum do not depend on the order)
            l0 = l1 = l2 = l3 = h0 = h1 = h2 = h3 = vt[c, i0]
            i = i0 + 1
            while i + 4 <= i1:
                x0, x1, x2, x3 = vt[c, i], vt[c, i + 1], vt[c, i + 2], vt[c, i + 3]
                l0, l1, l2, l3 = min(l0, x0), min(l1, x1), min(l2, x2), min(l3, x3)
                h0, h1, h2, h3 = max(h0, x0), max(h1, x1), max(h2, x2), max(h3, x3)
                i += 4
            while i < i1:
                l0, h0 = min(l0, vt[c, i]), max(h0, vt[c, i])
                i += 1
            box[b, 2 * c] = min(min(l0, l1), min(l2, l3))
            box[b, 2 * c + 1] = max(max(h0, h1), max(h2, h3))
    return box


def _nearest_loop(vt, points, box):  # pragma: no cover - compiled by numba
    """Index of the nearest of the vertices (3, V) to each point (K, 3) (first on ties).

    The vertices are taken in blocks of `_BLOCK` with their bounding boxes ``box``
    (`_blocks_loop`): a block whose box is farther than the best distance so far cannot
    hold a nearer vertex (exact, see there) and is skipped. The search starts in the block
    with the nearest box, then scans the blocks in order, keeping the first index among
    equal distances -- the plain scan's answer."""
    n_v = vt.shape[1]
    bs = _BLOCK
    n_b = box.shape[0]
    out = np.zeros(points.shape[0], np.int64)
    lb = np.empty(n_b)
    for k in range(points.shape[0]):
        px, py, pz = points[k, 0], points[k, 1], points[k, 2]
        first = 0
        for b in range(n_b):
            gx = max(box[b, 0] - px, px - box[b, 1], 0.0)
            gy = max(box[b, 2] - py, py - box[b, 3], 0.0)
            gz = max(box[b, 4] - pz, pz - box[b, 5], 0.0)
            lb[b] = gx * gx + gy * gy + gz * gz
            if lb[b] < lb[first]:
                first = b
        best = np.inf
        bi = 0
        for r in range(n_b + 1):
            b = first if r == 0 else r - 1
            if (r > 0 and b == first) or lb[b] > best:
                continue
            for i in range(b * bs, min(b * bs + bs, n_v)):
                dx, dy, dz = vt[0, i] - px, vt[1, i] - py, vt[2, i] - pz
                d2 = dx * dx + dy * dy + dz * dz
                if d2 < best or (d2 == best and i < bi):
                    best = d2
                    bi = i
        out[k] = bi
    return out


def _within_loop(vt, points, r2, box):  # pragma: no cover - compiled by numba
    """Whether each vertex (3, V) lies within squared distance r2 of some point (K, 3).

    Block by block (``box``: `_blocks_loop`): only the points whose box distance is within
    r2 are measured against the block's vertices (the others cannot be: exact, see
    `_blocks_loop`), point-major (the vertex loop has no exit and vectorises); a block no
    point reaches is skipped. The same answers as measuring every pair."""
    n_v = vt.shape[1]
    bs = _BLOCK
    out = np.zeros(n_v, np.bool_)
    x, y, z = vt[0], vt[1], vt[2]
    near = np.empty(points.shape[0], np.int64)
    for b in range(box.shape[0]):
        n_near = 0
        for k in range(points.shape[0]):
            px, py, pz = points[k, 0], points[k, 1], points[k, 2]
            gx = max(box[b, 0] - px, px - box[b, 1], 0.0)
            gy = max(box[b, 2] - py, py - box[b, 3], 0.0)
            gz = max(box[b, 4] - pz, pz - box[b, 5], 0.0)
            if gx * gx + gy * gy + gz * gz <= r2:
                near[n_near] = k
                n_near += 1
        i1 = min(b * bs + bs, n_v)
        for q in range(n_near):
            k = near[q]
            px, py, pz = points[k, 0], points[k, 1], points[k, 2]
            for i in range(b * bs, i1):
                dx, dy, dz = px - x[i], py - y[i], pz - z[i]
                out[i] |= dx * dx + dy * dy + dz * dz <= r2
    return out


def _edge_sum_loop(vt, faces):  # pragma: no cover - compiled by numba
    """Sum of the lengths of the faces' (T, 3) directed edges, vertices (3, V)."""
    total = 0.0
    for t in range(faces.shape[0]):
        for j in range(3):
            a, b = faces[t, j], faces[t, (j + 1) % 3]
            dx, dy, dz = vt[0, b] - vt[0, a], vt[1, b] - vt[1, a], vt[2, b] - vt[2, a]
            total += np.sqrt(dx * dx + dy * dy + dz * dz)
    return total


def _sq_distances(vt, points):
    """(K, V) squared distances of points (K, 3) to vertices given as (3, V)."""
    d2 = (vt[0] - points[:, 0, None]) ** 2
    d2 += (vt[1] - points[:, 1, None]) ** 2
    d2 += (vt[2] - points[:, 2, None]) ** 2
    return d2


def _mean_edge(vt, faces) -> float:
    """Mean length of the faces' (directed) edges, from (3, V) vertices."""
    if len(faces) == 0:
        return 0.0
    kernels = _kernels()
    if kernels is not None:
        f = np.ascontiguousarray(faces, dtype=np.int64)
        return float(kernels[2](vt, f) / (3 * len(f)))
    c = np.take(vt, np.ascontiguousarray(faces.T), axis=1)              # (3, 3, T)
    e = c[:, [1, 2, 0]] - c
    return float(np.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).mean())


def attachment_region(vertices, faces, landmarks) -> np.ndarray:
    """Surface points of an attachment area (module docstring).

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (T, 3) int
    landmarks : (K, 3) float

    Returns
    -------
    (C, 3) float
        Surface vertices belonging to the area.
    """
    vertices = np.asarray(vertices, float)
    return vertices[_region_indices(vertices, np.asarray(faces, np.int64),
                                    np.asarray(landmarks, float).reshape(-1, 3))]
