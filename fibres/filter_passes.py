"""Fused compiled passes of the attachment filter (`fibres.filtering`; Kohout et al., GRAPP
2012, §3.4).

`fibres.filtering.filter_choices` and `apply_filter` are, step by step, some sixty small numpy
operations per call (cut search, cut points, the two attachment areas, the rays' searches,
barycentric coordinates, the resampling record, the point placement). With numba they run as
three compiled passes doing the same arithmetic in the same order, calling the step kernels
themselves (`fibres.attachment_area`, `fibres.ray_triangles`, `fibres.resample`), so the
choices and the points are bit for bit those of the step-by-step path
(tests/fibres/test_filter_passes.py). numpy's order is kept for every reduction: the einsum
and ``sum`` over a triangle's three corners add left to right from 0, the hit test's
einsum dot product adds ``(x0 y0 + x2 y2) + x1 y1``, row norms ``(x0^2 + x1^2) + x2^2``,
``np.clip`` is ``min(max(x, lo), hi)`` with numpy's NaN and comparison rules, and
``np.linspace(0, 1, P)`` is ``j * (1 / (P - 1)) + 0`` with the last value 1.

- `choices_areas_loop`: which fibre ends are cut, in which segment and where; for the ends
  that some fibre cuts, the attachment area (`fibres.attachment_area`), its triangles and
  their owning faces (`fibres.attachment_area.regions_triangles`) and their bounds;
- `choices_ends_loop`: each cut end's ray searches (`fibres.ray_triangles.closest_on_triangles`:
  the template's ray within the tolerance, then the paper's ray for the fibres whose template
  ray does not hit the area), the target's face and barycentric coordinates on it, and the
  resampling record (`fibres.resample.resampling_loop`);
- `apply_loop`: `apply_filter`'s cuts on the current pose, new ends and point placement
  (`fibres.resample.evaluate_loop`).

The numbers numpy gets from BLAS (heights along the axis, the length of a 3-vector) are not
reproducible in a loop; they stay in numpy between the passes (``h = points @ axis``, the
searches' touching tolerance from the areas' bounds).
"""
from __future__ import annotations

import numpy as np

__all__ = ["passes"]

_PASSES = []

#: the step kernels the passes call (compiled, set by `passes`)
_nearest = _within = _edge_sum = _blocks = _triangles = _bounds = _regions = None
_resampling = _evaluate = _cut_s = _geometry = _area = _search = None


def passes():
    """(choices_areas_loop, choices_ends_loop, apply_loop) compiled with numba, or None
    (then `fibres.filtering` runs step by step)."""
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)


def _cut_s_loop(h, r, seg, level, fallback, slack):  # pragma: no cover - compiled by numba
    """`fibres.filtering._cuts`' parameter s of fibre r: ``(level - h_a) / (h_b - h_a)`` in
    segment ``seg`` (``fallback`` for a segment parallel to the plane), clipped to
    [-slack, 1 + slack]."""
    ha, hb = h[r, seg], h[r, seg + 1]
    dh = hb - ha
    s = fallback
    if abs(dh) > 1e-12 * (abs(ha) + abs(hb) + 1e-300):
        s = (level - ha) / dh
    if s != s:
        return s
    lo, hi = -slack, 1.0 + slack
    y = s if s > lo else lo
    return y if y < hi else hi


def _geometry_loop(pts, r, cut, segment, s, t_vert, t_bary, verts, q, tau, c,
                   e):  # pragma: no cover - compiled by numba
    """`fibres.filtering._geometry` of fibre r into row q of tau (M, 2), c and e (M, 2, 3):
    fractional index and point of each cut (the fibre's own end where not cut) and the new
    end ``sum_k t_bary[r, end, k] verts[t_vert[r, end, k]]`` (einsum: from 0, left to
    right)."""
    p = pts.shape[1]
    for end in range(2):
        if cut[r, end]:
            seg, st = segment[r, end], s[end]
            tau[q, end] = seg + st
            for x in range(3):
                a = pts[r, seg, x]
                c[q, end, x] = a + st * (pts[r, seg + 1, x] - a)
                acc = 0.0
                for k in range(3):
                    acc += verts[t_vert[r, end, k], x] * t_bary[r, end, k]
                e[q, end, x] = acc
        else:
            j = 0 if end == 0 else p - 1
            tau[q, end] = 0.0 if end == 0 else p - 1.0
            for x in range(3):
                c[q, end, x] = pts[r, j, x]
                e[q, end, x] = pts[r, j, x]


def _area_loop(vt, verts, landmarks, radius, blocks):  # pragma: no cover - compiled by numba
    """`fibres.attachment_area._region_indices` (compiled branch): the radius (the landmarks'
    median nearest-neighbour distance, at least ``radius``), the nearest vertex of every
    landmark, the vertices within the radius of those; sorted vertex indices."""
    k = landmarks.shape[0]
    if k > 1:
        near = np.empty(k)
        for a in range(k):
            best = np.inf
            for b in range(k):
                if b != a:
                    dx = landmarks[b, 0] - landmarks[a, 0]
                    dy = landmarks[b, 1] - landmarks[a, 1]
                    dz = landmarks[b, 2] - landmarks[a, 2]
                    best = min(best, np.sqrt((dx * dx + dy * dy) + dz * dz))
            near[a] = best
        near = np.sort(near)
        hk = k // 2
        med = near[hk] if k % 2 else (near[hk - 1] + near[hk]) / 2
        if med > radius:
            radius = med
    nearest = _nearest(vt, landmarks, blocks)
    proj = np.unique(nearest)
    within = _within(vt, np.ascontiguousarray(verts[proj]), radius * radius, blocks)
    for i in range(k):
        within[nearest[i]] = True
    return np.flatnonzero(within)


def choices_areas_loop(pts, h, h_o, h_i, tol, vt, verts, faces, origin, insertion,
                       mean_edge):  # pragma: no cover - compiled by numba
    """The cuts of `fibres.filtering.filter_choices` and the areas of the ends they cut.

    Parameters: fibres (N, P, 3), their heights along the axis (N, P), the planes' heights,
    the tie tolerance, the vertices (3, V) and (V, 3), faces (T, 3), the landmarks (K, 3) of
    each end and the mean edge length (< 0: not known, measured when some fibre is cut).

    Returns cut (N, 2) bool, segment (N, 2), cut_param (N, 2) (zero when nothing is cut),
    then per end (origin, insertion) the area's triangles: corner indices (T_e, 3), owning
    faces (T_e,) and corners (T_e, 3, 3) (empty for an end no fibre cuts), and their bounds
    (2, 2, 3) (end, lo / hi)."""
    n, p = h.shape
    cut = np.zeros((n, 2), np.bool_)
    segment = np.zeros((n, 2), np.int64)
    cut_param = np.zeros((n, 2))
    jo, ji = np.empty(n, np.int64), np.empty(n, np.int64)
    lo_o, hi_i = h_o - tol, h_i + tol
    need = np.zeros(2, np.bool_)
    for r in range(n):
        j_o, j_i, inside = -1, p, False
        for j in range(p):
            x = h[r, j]
            if x < lo_o:                        # beyond the origin plane: the last one
                j_o = j
            if x > hi_i and j_i == p:           # beyond the insertion plane: the first one
                j_i = j
            if x >= lo_o and x <= hi_i:
                inside = True
        ok = inside and j_o < j_i - 1
        cut[r, 0] = ok and j_o >= 0
        cut[r, 1] = ok and j_i <= p - 1
        need[0] |= cut[r, 0]
        need[1] |= cut[r, 1]
        jo[r], ji[r] = j_o, j_i
    bounds = np.zeros((2, 2, 3))
    areas = []
    for end in range(2):
        areas.append((np.zeros((0, 3), np.int64), np.zeros(0, np.int64),
                      np.zeros((0, 3, 3))))
    if not (need[0] or need[1]):
        return cut, segment, cut_param, areas[0], areas[1], bounds
    for r in range(n):
        segment[r, 0] = min(max(jo[r], 0), p - 2)
        segment[r, 1] = min(max(ji[r], 1), p - 1) - 1
        cut_param[r, 0] = _cut_s(h, r, segment[r, 0], h_o, 0.0, 0.0)
        cut_param[r, 1] = _cut_s(h, r, segment[r, 1], h_i, 0.0, 0.0)
    if mean_edge < 0:  # not given: `fibres.attachment_area._mean_edge`
        mean_edge = 0.0
        if faces.shape[0]:
            mean_edge = _edge_sum(vt, faces) / (3 * faces.shape[0])
    blocks = _blocks(vt)
    n_r = 0
    idx_o = idx_i = np.zeros(0, np.int64)
    if need[0]:
        idx_o = _area(vt, verts, origin, mean_edge, blocks)
        n_r += 1
    if need[1]:
        idx_i = _area(vt, verts, insertion, mean_edge, blocks)
        n_r += 1
    flat = np.concatenate((idx_o, idx_i))
    starts = np.zeros(n_r + 1, np.int64)
    starts[1] = idx_o.shape[0] if need[0] else idx_i.shape[0]
    if n_r == 2:
        starts[2] = flat.shape[0]
    corners, face, off = _regions(faces, flat, starts, verts.shape[0])
    r = 0
    for end in range(2):
        if need[end]:
            cn = corners[off[r]:off[r + 1]].copy()
            tv = np.empty((cn.shape[0], 3, 3))
            for t in range(cn.shape[0]):
                for i in range(3):
                    for x in range(3):
                        tv[t, i, x] = verts[cn[t, i], x]
            lo, hi = _bounds(tv)
            bounds[end, 0], bounds[end, 1] = lo, hi
            areas[end] = (cn, face[off[r]:off[r + 1]].copy(), tv)
            r += 1
    return cut, segment, cut_param, areas[0], areas[1], bounds


def _search_loop(tv, corners, start, direction, eps2, reach, within2,
                 hit_blocks):  # pragma: no cover - compiled by numba
    """`fibres.ray_triangles.closest_on_triangles(tv, start, direction, within=...,
    corner_ids=corners)`: unit directions and rounding slack as its wrapper, then its
    compiled loop (``reach``: the largest corner coordinate size of ``tv``;
    ``hit_blocks``: its pre-test's block sizes)."""
    m = start.shape[0]
    dn = np.empty((m, 3))
    slack = np.empty(m)
    for i in range(m):
        d0, d1, d2 = direction[i, 0], direction[i, 1], direction[i, 2]
        nrm = np.sqrt((d0 * d0 + d1 * d1) + d2 * d2)
        dn[i, 0], dn[i, 1], dn[i, 2] = d0 / nrm, d1 / nrm, d2 / nrm
        size = max(max(abs(start[i, 0]), abs(start[i, 1])), abs(start[i, 2]))
        slack[i] = 1e-14 * (size + reach)
    index, bary = _triangles(tv, start, dn, eps2, slack, within2, corners, hit_blocks[0],
                             hit_blocks[1])
    return index, bary, dn


def choices_ends_loop(pts, ref, use_ref, cut, segment, cut_param, area_o, area_i, bounds,
                      eps2, within2, tol, verts, faces,
                      hit_blocks):  # pragma: no cover - compiled by numba
    """The new ends and the resampling record of `fibres.filtering.filter_choices`.

    Parameters: fibres (N, P, 3), reference fibres (N, P, 3) used when ``use_ref``, the
    outputs of `choices_areas_loop`, each area's touching tolerance squared (2,) and
    ``within`` squared of the reference rays, the tie tolerance, vertices (V, 3), faces and
    the block sizes of the restricted search's pre-test (`ray_triangles._HIT_BLOCKS`).

    Returns target_face (N, 2), target_vertices (N, 2, 3), target_bary (N, 2, 3), piece
    (N, P) int8, param (N, P)."""
    n, p = pts.shape[0], pts.shape[1]
    t_face = np.full((n, 2), -1, np.int64)
    t_vert = np.zeros((n, 2, 3), np.int64)
    t_bary = np.zeros((n, 2, 3))
    for end in range(2):
        corners, owner, tv = area_o if end == 0 else area_i
        rows = np.flatnonzero(cut[:, end])
        m = rows.shape[0]
        if m == 0:
            continue
        reach = 0.0
        for x in range(3):
            reach = max(reach, max(abs(bounds[end, 0, x]), abs(bounds[end, 1, x])))
        start = np.empty((m, 3))
        d_ref, d_fib = np.empty((m, 3)), np.empty((m, 3))
        for i in range(m):
            r = rows[i]
            seg, st = segment[r, end], cut_param[r, end]
            # the ray continues the last kept segment: towards the origin / the insertion
            ia, ib = (seg + 1, seg) if end == 0 else (seg, seg + 1)
            for x in range(3):
                a = pts[r, seg, x]
                start[i, x] = a + st * (pts[r, seg + 1, x] - a)
                d_fib[i, x] = pts[r, ib, x] - pts[r, ia, x]
                if use_ref:
                    d_ref[i, x] = ref[r, ib, x] - ref[r, ia, x]
        k = np.zeros(m, np.int64)
        w = np.zeros((m, 3))
        miss = np.ones(m, np.bool_)
        if use_ref:  # the template's direction where its ray hits the area
            k2, w2, dn = _search(tv, corners, start, d_ref, eps2[end], reach, within2,
                                 hit_blocks)
            for i in range(m):
                if k2[i] < 0:
                    continue
                q = np.empty(3)
                for x in range(3):
                    acc = 0.0
                    for j in range(3):
                        acc += tv[k2[i], j, x] * w2[i, j]
                    q[x] = acc - start[i, x]
                along = (q[0] * dn[i, 0] + q[2] * dn[i, 2]) + q[1] * dn[i, 1]
                if not along != along:   # np.maximum(along, 0): NaN kept
                    along = along if along > 0.0 else 0.0
                g0 = q[0] - along * dn[i, 0]
                g1 = q[1] - along * dn[i, 1]
                g2 = q[2] - along * dn[i, 2]
                if np.sqrt((g0 * g0 + g1 * g1) + g2 * g2) <= tol:
                    miss[i] = False
                    k[i] = k2[i]
                    w[i] = w2[i]
        sub = np.flatnonzero(miss)
        if sub.shape[0]:  # the paper's ray for the others (each ray on its own)
            k3, w3, _ = _search(tv, corners, start[sub], d_fib[sub], eps2[end], reach,
                                np.inf, hit_blocks)
            for j in range(sub.shape[0]):
                k[sub[j]] = k3[j]
                w[sub[j]] = w3[j]
        for i in range(m):  # barycentric coordinates on the owning face's corners
            r, f = rows[i], owner[k[i]]
            t_face[r, end] = f
            for a in range(3):
                t_vert[r, end, a] = faces[f, a]
                acc = 0.0
                for b in range(3):
                    acc += (1.0 if faces[f, a] == corners[k[i], b] else 0.0) * w[i, b]
                t_bary[r, end, a] = acc
    # the resampling record: every point's piece and parameter (fibres.resample)
    lin = np.empty(p)
    step = 1.0 / (p - 1)
    for j in range(p):
        lin[j] = j * step + 0.0
    lin[p - 1] = 1.0
    piece = np.ones((n, p), np.int8)
    param = np.empty((n, p))
    for r in range(n):
        param[r] = lin
        piece[r, 0], param[r, 0] = 0, 0.0
        piece[r, p - 1], param[r, p - 1] = 2, 1.0
    sel = np.flatnonzero(cut[:, 0] | cut[:, 1])
    m = sel.shape[0]
    fib = np.empty((m, p, 3))
    tau, c, e = np.empty((m, 2)), np.empty((m, 2, 3)), np.empty((m, 2, 3))
    for q in range(m):
        r = sel[q]
        fib[q] = pts[r]
        _geometry(pts, r, cut, segment, cut_param[r], t_vert, t_bary, verts, q, tau, c, e)
    pc, pr = _resampling(fib, tau[:, 0].copy(), tau[:, 1].copy(), c[:, 0].copy(),
                         c[:, 1].copy(), e[:, 0].copy(), e[:, 1].copy(), lin)
    for q in range(m):
        piece[sel[q]] = pc[q]
        param[sel[q]] = pr[q]
    return t_face, t_vert, t_bary, piece, param


def apply_loop(pts, h, h_o, h_i, cut, segment, cut_param, t_vert, t_bary, piece, param,
               verts, slack):  # pragma: no cover - compiled by numba
    """`fibres.filtering.apply_filter` on fibres (n, P, 3) with heights h (n, P) and the
    first n of the recorded choices: the cuts on the current planes (within ``slack``),
    the recorded new ends and every point from its piece and parameter.

    Returns the points (n, P, 3) and which fibres were cut (n,) bool."""
    n, p = pts.shape[0], pts.shape[1]
    out = pts.copy()
    sel = cut[:n, 0] | cut[:n, 1]
    rows = np.flatnonzero(sel)
    m = rows.shape[0]
    if m == 0:
        return out, sel
    fib = np.empty((m, p, 3))
    tau, c, e = np.empty((m, 2)), np.empty((m, 2, 3)), np.empty((m, 2, 3))
    s = np.empty(2)
    for q in range(m):
        r = rows[q]
        fib[q] = pts[r]
        s[0] = _cut_s(h, r, segment[r, 0], h_o, cut_param[r, 0], slack)
        s[1] = _cut_s(h, r, segment[r, 1], h_i, cut_param[r, 1], slack)
        _geometry(pts, r, cut, segment, s, t_vert, t_bary, verts, q, tau, c, e)
    pc, pr = np.empty((m, p), np.int8), np.empty((m, p))
    for q in range(m):
        pc[q], pr[q] = piece[rows[q]], param[rows[q]]
    placed = _evaluate(fib, tau[:, 0].copy(), tau[:, 1].copy(), c[:, 0].copy(), c[:, 1].copy(),
                       e[:, 0].copy(), e[:, 1].copy(), pc, pr)
    for q in range(m):
        out[rows[q]] = placed[q]
    return out, sel
