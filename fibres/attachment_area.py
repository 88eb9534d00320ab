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

The area's surface (what the filter's rays search, `fibres.ray_triangles`): the faces whose
three corners are all in the area, plus each area vertex on no such face as a point (a
degenerate triangle held by a face with that corner): `region_triangles`, or
`regions_triangles` for both areas with one pass over the faces.
"""
from __future__ import annotations

import numpy as np

__all__ = ["attachment_region", "region_triangles", "regions_triangles"]


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
    lengths, vertex blocks' boxes, an area's triangles, several areas' triangles) compiled
    with numba, or None (then numpy, component-wise: the same arithmetic in the same
    order)."""
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)


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


def _region_loop(faces, region, n_vertices):  # pragma: no cover - compiled by numba
    """`region_triangles` in one pass over the faces (the array version's outputs: full
    faces in index order, then the lone area vertices in area order, each owned by the
    last face holding it in the corner-by-corner scan)."""
    n_t = faces.shape[0]
    inside = np.zeros(n_vertices, np.bool_)
    for r in region:
        inside[r] = True
    full = np.empty(n_t, np.int64)
    n_full = 0
    covered = np.zeros(n_vertices, np.bool_)
    for t in range(n_t):
        if inside[faces[t, 0]] and inside[faces[t, 1]] and inside[faces[t, 2]]:
            full[n_full] = t
            n_full += 1
            covered[faces[t, 0]] = True
            covered[faces[t, 1]] = True
            covered[faces[t, 2]] = True
    n_lone = 0
    for r in region:
        n_lone += not covered[r]
    corners = np.empty((n_full + n_lone, 3), np.int64)
    face = np.empty(n_full + n_lone, np.int64)
    for q in range(n_full):
        t = full[q]
        corners[q, 0], corners[q, 1], corners[q, 2] = faces[t, 0], faces[t, 1], faces[t, 2]
        face[q] = t
    if n_lone:
        owner = np.full(n_vertices, -1, np.int64)
        for j in range(3):  # corner by corner, the last face wins (as the array version)
            for t in range(n_t):
                if inside[faces[t, j]] and not covered[faces[t, j]]:
                    owner[faces[t, j]] = t
        q = n_full
        for r in region:
            if not covered[r]:
                corners[q, 0], corners[q, 1], corners[q, 2] = r, r, r
                face[q] = owner[r]
                q += 1
    return corners, face


def _regions_loop(faces, flat, starts, n_vertices):  # pragma: no cover - compiled by numba
    """`_region_loop` for up to 8 areas (``flat[starts[r]:starts[r + 1]]``) with one pass over
    the faces for their full faces (a bit per area marks its vertices); then each area's
    lone vertices and owners as `_region_loop`. Returns the areas' corners and faces back to
    back and their offsets (n_r + 1,)."""
    n_t = faces.shape[0]
    n_r = starts.shape[0] - 1
    mark = np.zeros(n_vertices, np.uint8)
    for r in range(n_r):
        for q in range(starts[r], starts[r + 1]):
            mark[flat[q]] |= np.uint8(1 << r)
    full = np.empty((n_r, n_t), np.int64)
    n_full = np.zeros(n_r, np.int64)
    # the owner of every marked vertex in the same pass: the array version scans the faces
    # corner by corner (column 0, 1, 2, each in face order) and the last face wins, i.e.
    # the last face in the highest column holding the vertex (the test on a lone vertex
    # depends on the vertex only)
    owner = np.full(n_vertices, -1, np.int64)
    o_col = np.zeros(n_vertices, np.int8)
    for t in range(n_t):
        x0, x1, x2 = faces[t, 0], faces[t, 1], faces[t, 2]
        m0, m1, m2 = mark[x0], mark[x1], mark[x2]
        if m0 | m1 | m2:
            if m0 and o_col[x0] <= 0:
                owner[x0] = t
            if m1 and o_col[x1] <= 1:
                owner[x1] = t
                o_col[x1] = 1
            if m2:
                owner[x2] = t
                o_col[x2] = 2
            m = m0 & m1 & m2
            if m:
                for r in range(n_r):
                    if m & (1 << r):
                        full[r, n_full[r]] = t
                        n_full[r] += 1
    covered = np.zeros((n_r, n_vertices), np.bool_)
    out = np.zeros(n_r + 1, np.int64)
    n_lone = np.zeros(n_r, np.int64)
    for r in range(n_r):
        for q in range(n_full[r]):
            t = full[r, q]
            covered[r, faces[t, 0]] = True
            covered[r, faces[t, 1]] = True
            covered[r, faces[t, 2]] = True
        for q in range(starts[r], starts[r + 1]):
            n_lone[r] += not covered[r, flat[q]]
        out[r + 1] = out[r] + n_full[r] + n_lone[r]
    corners = np.empty((out[n_r], 3), np.int64)
    face = np.empty(out[n_r], np.int64)
    for r in range(n_r):
        o = out[r]
        for q in range(n_full[r]):
            t = full[r, q]
            corners[o + q, 0], corners[o + q, 1], corners[o + q, 2] = (
                faces[t, 0], faces[t, 1], faces[t, 2])
            face[o + q] = t
        if n_lone[r]:
            q = o + n_full[r]
            for i in range(starts[r], starts[r + 1]):
                x = flat[i]
                if not covered[r, x]:
                    corners[q, 0], corners[q, 1], corners[q, 2] = x, x, x
                    face[q] = owner[x]
                    q += 1
    return corners, face, out


def regions_triangles(faces, regions, n_vertices):
    """`region_triangles` of several areas (at most 8) with one pass over the faces.

    Parameters
    ----------
    faces : (T, 3) int
    regions : sequence of (C_r,) int
        The areas' vertex indices (each without repeats; areas may overlap).
    n_vertices : int
        V.

    Returns
    -------
    list of (corners (T'_r, 3) int, face (T'_r,) int)
        Exactly `region_triangles` of each area.
    """
    kernels = _kernels()
    if kernels is None or len(regions) > 8 or len(regions) == 0:
        return [region_triangles(faces, r, n_vertices) for r in regions]
    flat = np.concatenate([np.asarray(r, dtype=np.int64).ravel() for r in regions])
    starts = np.cumsum([0] + [np.size(r) for r in regions]).astype(np.int64)
    corners, face, out = kernels[5](np.ascontiguousarray(faces, dtype=np.int64), flat,
                                    starts, int(n_vertices))
    return [(corners[out[r]:out[r + 1]], face[out[r]:out[r + 1]])
            for r in range(len(regions))]


def region_triangles(faces, region, n_vertices):
    """The attachment area's surface: the faces with all three corners in the area, plus
    each area vertex on no such face as a point (a degenerate triangle (v, v, v)).

    Parameters
    ----------
    faces : (T, 3) int
    region : (C,) int
        The area's vertex indices.
    n_vertices : int
        V.

    Returns
    -------
    corners : (T', 3) int
        The area triangles' vertex indices (a point: its vertex three times).
    face : (T',) int
        For each, a face of the mesh holding it (for a point: a face with that corner).
    """
    kernels = _kernels()
    if kernels is not None:
        return kernels[4](np.ascontiguousarray(faces, dtype=np.int64),
                          np.ascontiguousarray(region, dtype=np.int64), int(n_vertices))
    inside = np.zeros(n_vertices, bool)
    inside[region] = True
    f0, f1, f2 = faces[:, 0], faces[:, 1], faces[:, 2]
    # column by column (faces may be a strided view; a (T, 3) gather is ~6x slower)
    full = np.flatnonzero(inside[f0] & inside[f1] & inside[f2])
    covered = np.zeros(n_vertices, bool)
    covered[faces[full].ravel()] = True
    lone = region[~covered[region]]
    if len(lone) == 0:
        return faces[full], full
    alone = np.zeros(n_vertices, bool)
    alone[lone] = True
    owner = np.full(n_vertices, -1, np.int64)          # a face holding each lone vertex
    for col in (f0, f1, f2):  # the three corners
        rows = np.flatnonzero(alone[col])
        owner[col[rows]] = rows
    corners = np.concatenate([faces[full], np.repeat(lone[:, None], 3, axis=1)])
    return corners, np.concatenate([full, owner[lone]])
