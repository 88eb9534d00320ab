"""Mean value coordinates of points with respect to an arbitrary planar polygon.

Hormann, K. and Floater, M. S. (2006). "Mean value coordinates for arbitrary planar
polygons". ACM Transactions on Graphics 25(4):1424-1441.

For a point ``x`` and polygon vertices ``v_i`` (i = 0..K-1, closed), with
``s_i = v_i - x``, ``r_i = |s_i|`` and ``alpha_i`` the *signed* angle between ``s_i`` and
``s_{i+1}``, the weights are

    w_i = (tan(alpha_{i-1} / 2) + tan(alpha_i / 2)) / r_i,      lambda_i = w_i / sum_j w_j.

They are defined for any simple polygon (convex or not, either orientation) and every
point not on the boundary; they sum to one and reproduce linear functions exactly
(sum_i lambda_i v_i = x). On the boundary they extend continuously to linear
interpolation along the edge (and to the unit vector on a vertex); that case is handled
explicitly here, so points on edges and vertices get exact coordinates.

``tan(alpha/2)`` is evaluated as ``2 A_i / (r_i r_{i+1} + D_i)`` with ``A_i`` half the
cross product and ``D_i`` the dot product of ``s_i`` and ``s_{i+1}``: this form is
stable for small angles (and for coincident consecutive vertices, where it is 0) and is
singular only when ``x`` lies on the edge (alpha = pi), the case treated separately (a
point within ~1e-14 of an edge's length from the edge counts as on it, and so does a point
nearly on it whose denominator ``r r' + D`` rounds to zero or below).
"""
from __future__ import annotations

import numpy as np

__all__ = ["mean_value_coordinates", "mvc_map", "strict"]

#: Switch on costly invariant checks (partition of unity, linear precision); tests only.
strict = False

# A point is "on" edge i when |sin(alpha_i)| <= _ON_EDGE and cos(alpha_i) < 0: alpha_i is
# within 1e-14 rad of pi, i.e. the point is within ~1e-14 * edge length of the edge, where
# linear interpolation along the edge is exact to rounding.
_ON_EDGE = 1e-14


def mean_value_coordinates(points, polygon) -> np.ndarray:
    """Mean value coordinates of many points with respect to one closed polygon.

    Parameters
    ----------
    points : (N, 2) float
        Query points.
    polygon : (K, 2) float
        Polygon vertices in order (either orientation; convex or not), K >= 3, not
        repeated at the end. Consecutive coincident vertices are allowed.

    Returns
    -------
    lam : (N, K) float
        ``lam[n] @ polygon == points[n]`` and ``lam[n].sum() == 1``. Rows for points on a
        vertex are unit vectors; rows for points on an edge are the linear interpolation
        weights of that edge's two vertices.

    Notes
    -----
    One array expression for all points (Hormann & Floater 2006, eq. for ``w_i`` with the
    half-angle tangent written as ``2A / (r r' + D)``).
    """
    pts = np.asarray(points, dtype=float)
    poly = np.asarray(polygon, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (N, 2), got {pts.shape}")
    if poly.ndim != 2 or poly.shape[1] != 2 or poly.shape[0] < 3:
        raise ValueError(f"polygon must have shape (K, 2) with K >= 3, got {poly.shape}")
    k = poly.shape[0]
    nxt = np.append(np.arange(1, k), 0)
    prv = np.append(k - 1, np.arange(k - 1))
    sx = poly[:, 0] - pts[:, 0, None]                           # (N, K)
    sy = poly[:, 1] - pts[:, 1, None]
    sxn = sx[:, nxt]                                            # s_{i+1}
    syn = sy[:, nxt]
    r = np.sqrt(sx * sx + sy * sy)
    rr = r * r[:, nxt]
    cross = sx * syn - sy * sxn                                 # 2 A_i
    dot = sx * sxn + sy * syn                                   # D_i
    denom = rr + dot                                            # r r' (1 + cos alpha)
    on_edge = ((np.abs(cross) <= _ON_EDGE * rr) | (denom <= 0.0)) & (dot < 0.0)
    on_vertex = r == 0.0
    if not (on_edge.any() or on_vertex.any()):
        tan_half = cross / denom
        w = (tan_half[:, prv] + tan_half) / r
        return _finish(w / w.sum(axis=1, keepdims=True), pts, poly)
    on_edge &= rr > 0.0
    special = on_vertex.any(axis=1) | on_edge.any(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        tan_half = np.where(denom > 0.0, cross / np.where(denom > 0.0, denom, 1.0), 0.0)
        w = (tan_half[:, prv] + tan_half) / np.where(on_vertex, 1.0, r)
        lam = w / w.sum(axis=1, keepdims=True)
    rn = r[:, nxt]
    lam[special] = _boundary_coordinates(on_vertex[special], on_edge[special],
                                         r[special], rn[special])
    return _finish(lam, pts, poly)


def _finish(lam, pts, poly):
    if strict:
        assert np.allclose(lam.sum(axis=1), 1.0, atol=1e-9)
        assert np.allclose(lam @ poly, pts, atol=1e-9 * (1.0 + np.abs(poly).max()))
    return lam


def _boundary_coordinates(on_vertex, on_edge, r, rn) -> np.ndarray:
    """Exact coordinates for points on a vertex or an edge.

    Parameters
    ----------
    on_vertex, on_edge : (M, K) bool
    r, rn : (M, K) float
        Distances to vertex i and vertex i+1.

    Returns
    -------
    lam : (M, K) float
    """
    m, k = r.shape
    lam = np.zeros((m, k))
    rows = np.arange(m)
    has_vertex = on_vertex.any(axis=1)
    vi = np.argmax(on_vertex, axis=1)
    ei = np.argmax(on_edge, axis=1)
    e_rows = rows[~has_vertex]
    e = ei[~has_vertex]
    ra = r[e_rows, e]
    rb = rn[e_rows, e]
    lam[e_rows, e] = rb / (ra + rb)
    lam[e_rows, (e + 1) % k] += ra / (ra + rb)
    lam[rows[has_vertex], vi[has_vertex]] = 1.0
    return lam


class Planes(tuple):
    """A tuple of per-plane (K_g, 2) arrays that are consecutive views of one (K, 2) array
    ``flat`` (``offsets`` (G + 1,)): `mvc_map` then uses ``flat`` instead of concatenating
    the views again. Built by `planes`; any other tuple or list works as well."""

    flat: np.ndarray
    offsets: np.ndarray


def planes(flat, offsets) -> Planes:
    """`Planes` of the rows ``flat[offsets[g]:offsets[g + 1]]`` (views, as np.split)."""
    offsets = np.asarray(offsets, dtype=np.int64)
    off = offsets.tolist()
    out = Planes([flat[a:b] for a, b in zip(off[:-1], off[1:])])
    out.flat, out.offsets = flat, offsets
    return out


def mvc_map(points, groups, sources, targets, *, weights=None) -> np.ndarray:
    """Map points through mean value coordinates: ``sum_i lambda_i(x; source) target_i``.

    For each point ``x = points[j]`` the coordinates with respect to polygon
    ``sources[groups[j]]`` are applied to the vertices of ``targets[groups[j]]`` (same
    vertex count), without forming the (N, K) coordinate matrix. The morph of Kohout 2012
    §3.3 is this map with the subdivided rectangle as source and the contour as target.

    Parameters
    ----------
    points : (M, 2) float
    groups : (M,) int
        Polygon index of each point.
    sources, targets : sequences of G (K_g, 2) float arrays
    weights : (M,) float, optional
        Multiply each mapped point (blending); default 1.

    Returns
    -------
    (M, 2) float

    Notes
    -----
    Compiled with numba when it is installed (one pass over the polygon per point, exact on
    vertices and edges like `mean_value_coordinates`); otherwise `mean_value_coordinates`
    is evaluated per polygon.
    """
    pts = np.ascontiguousarray(points, dtype=float)
    groups = np.ascontiguousarray(groups, dtype=np.int64)
    w = np.ones(len(pts)) if weights is None else np.ascontiguousarray(weights, dtype=float)
    kernel = _kernel()
    if kernel is not None:
        src, dst, offsets = packed(sources, targets)
        res = np.empty_like(pts)
        kernel(pts, groups, w, np.ascontiguousarray(src[:, 0]), np.ascontiguousarray(src[:, 1]),
               src, dst, offsets, _ON_EDGE, res)
        return res
    res = np.zeros_like(pts)
    order = np.argsort(groups, kind="stable")
    bounds = np.searchsorted(groups[order], np.arange(len(sources) + 1))
    for g in range(len(sources)):
        sel = order[bounds[g]:bounds[g + 1]]
        if sel.size:
            lam = mean_value_coordinates(pts[sel], sources[g])
            res[sel] = w[sel, None] * (lam @ np.asarray(targets[g], dtype=float))
    return res


def packed(sources, targets):
    """The polygons back to back: sources (K, 2), targets (K, 2) float (C order) and the
    offsets (G + 1,) int64 -- `Planes` with the same offsets as they are, else
    concatenated."""
    if (isinstance(sources, Planes) and isinstance(targets, Planes)
            and np.array_equal(sources.offsets, targets.offsets)):
        return (np.ascontiguousarray(sources.flat, dtype=float),
                np.ascontiguousarray(targets.flat, dtype=float), sources.offsets)
    offsets = np.zeros(len(sources) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([len(s) for s in sources])
    return (np.ascontiguousarray(np.concatenate(sources), dtype=float),
            np.ascontiguousarray(np.concatenate(targets), dtype=float), offsets)


_KERNEL = []


def _kernel():
    """The numba-compiled loop of `mvc_map`, or None without numba (compiled once)."""
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)


#: the compiled `_mvc_map_loop` (set by `_kernel`), called by `_mvc_map_vec`
_mvc_scalar = None


def _mvc_map_vec(pts, groups, wts, src_x, src_y, src, dst, offsets, eps,
                 res):  # pragma: no cover - compiled by numba
    """`_mvc_map_loop` with the points as the inner loop: the points are bucketed by
    polygon and, for each polygon vertex in turn, every point of that polygon advances by
    one edge (its current vector to the vertex, distance and previous half-angle tangent
    are kept per point), so the roots and divisions run over independent points and the
    compiler vectorises them. Per point these are the same operations in the same order
    as `_mvc_map_loop` (the weights summed in vertex order), hence the same result bit for
    bit. A point on a vertex or an edge goes through `_mvc_map_loop`."""
    n = pts.shape[0]
    n_g = offsets.size - 1
    start = np.zeros(n_g + 1, dtype=np.int64)         # points bucketed by polygon (stable)
    for j in range(n):
        start[groups[j] + 1] += 1
    for g in range(n_g):
        start[g + 1] += start[g]
    fill = start[:n_g].copy()
    order = np.empty(n, dtype=np.int64)
    for j in range(n):
        order[fill[groups[j]]] = j
        fill[groups[j]] += 1
    m_max = 0
    for g in range(n_g):
        m_max = max(m_max, start[g + 1] - start[g])
    px, py, sw, ax, ay = (np.empty(m_max), np.empty(m_max), np.empty(m_max),
                          np.empty(m_max), np.empty(m_max))
    csx, csy, cr, tp = np.empty(m_max), np.empty(m_max), np.empty(m_max), np.empty(m_max)
    sx0, sy0, r0 = np.empty(m_max), np.empty(m_max), np.empty(m_max)
    special = np.empty(m_max, dtype=np.int64)
    for g in range(n_g):
        m = start[g + 1] - start[g]
        if m == 0:
            continue
        lo = offsets[g]
        k = offsets[g + 1] - lo
        for q in range(m):
            j = order[start[g] + q]
            px[q] = pts[j, 0]
            py[q] = pts[j, 1]
        # vertex 0, and the tangent of the last edge (k-1 -> 0), which enters w_0
        ux, uy = src_x[lo], src_y[lo]
        lx, ly = src_x[lo + k - 1], src_y[lo + k - 1]
        for q in range(m):
            sx = ux - px[q]
            sy = uy - py[q]
            r = np.sqrt(sx * sx + sy * sy)
            sxl = lx - px[q]
            syl = ly - py[q]
            rl = np.sqrt(sxl * sxl + syl * syl)
            cross = sxl * sy - syl * sx
            dot = sxl * sx + syl * sy
            rr = rl * r
            tp[q] = cross / (rr + dot)
            special[q] = (rl == 0.0) | (((abs(cross) <= eps * rr) | (rr + dot <= 0.0))
                                        & (dot < 0.0))
            csx[q], csy[q], cr[q] = sx, sy, r
            sx0[q], sy0[q], r0[q] = sx, sy, r
            sw[q] = 0.0
            ax[q] = 0.0
            ay[q] = 0.0
        for i in range(k):  # vertex i: edge i -> i+1, weight w_i
            last = i == k - 1
            nx, ny = src_x[lo + i + 1 - k * last], src_y[lo + i + 1 - k * last]
            dxi, dyi = dst[lo + i, 0], dst[lo + i, 1]
            for q in range(m):
                sxn = nx - px[q]
                syn = ny - py[q]
                rn = np.sqrt(sxn * sxn + syn * syn)
                cross = csx[q] * syn - csy[q] * sxn
                dot = csx[q] * sxn + csy[q] * syn
                rr = cr[q] * rn
                t = cross / (rr + dot)
                special[q] |= (cr[q] == 0.0) | (((abs(cross) <= eps * rr) | (rr + dot <= 0.0))
                                                & (dot < 0.0))
                w = (tp[q] + t) / cr[q]
                sw[q] += w
                ax[q] += w * dxi
                ay[q] += w * dyi
                tp[q] = t
                csx[q], csy[q], cr[q] = sxn, syn, rn
        for q in range(m):
            j = order[start[g] + q]
            if special[q]:
                _mvc_scalar(pts[j:j + 1], groups[j:j + 1], wts[j:j + 1], src, dst, offsets,
                            eps, res[j:j + 1])
            else:
                res[j, 0] = wts[j] * (ax[q] / sw[q])
                res[j, 1] = wts[j] * (ay[q] / sw[q])


def _mvc_map_loop(pts, groups, wts, src, dst, offsets, eps, res):  # pragma: no cover - numba
    """One point at a time: w_i = (t_{i-1} + t_i) / r_i with t_i = 2A_i / (r_i r_{i+1} + D_i)
    (Hormann & Floater 2006), rolling over the edges; vertex/edge hits are exact."""
    for j in range(pts.shape[0]):
        lo = offsets[groups[j]]
        k = offsets[groups[j] + 1] - lo
        x = pts[j, 0]
        y = pts[j, 1]
        sx0 = src[lo, 0] - x
        sy0 = src[lo, 1] - y
        r0 = np.sqrt(sx0 * sx0 + sy0 * sy0)
        rx = 0.0
        ry = 0.0
        done = False
        if r0 == 0.0:
            rx, ry, done = dst[lo, 0], dst[lo, 1], True
        if not done:
            # edge (k-1 -> 0) first: its tangent enters w_0
            sxl = src[lo + k - 1, 0] - x
            syl = src[lo + k - 1, 1] - y
            rl = np.sqrt(sxl * sxl + syl * syl)
            cross = sxl * sy0 - syl * sx0
            dot = sxl * sx0 + syl * sy0
            rr = rl * r0
            if rl == 0.0:
                rx, ry, done = dst[lo + k - 1, 0], dst[lo + k - 1, 1], True
            elif (abs(cross) <= eps * rr or rr + dot <= 0.0) and dot < 0.0:
                a = r0 / (rl + r0)
                rx = a * dst[lo + k - 1, 0] + (1.0 - a) * dst[lo, 0]
                ry = a * dst[lo + k - 1, 1] + (1.0 - a) * dst[lo, 1]
                done = True
            else:
                t_prev = cross / (rr + dot)
        if not done:
            sxi, syi, ri = sx0, sy0, r0
            sumw = 0.0
            ax = 0.0
            ay = 0.0
            for i in range(k):
                i1 = i + 1 if i + 1 < k else 0
                sxn = src[lo + i1, 0] - x
                syn = src[lo + i1, 1] - y
                rn = np.sqrt(sxn * sxn + syn * syn)
                if rn == 0.0:
                    rx, ry, done = dst[lo + i1, 0], dst[lo + i1, 1], True
                    break
                cross = sxi * syn - syi * sxn
                dot = sxi * sxn + syi * syn
                rr = ri * rn
                if (abs(cross) <= eps * rr or rr + dot <= 0.0) and dot < 0.0:
                    a = rn / (ri + rn)
                    rx = a * dst[lo + i, 0] + (1.0 - a) * dst[lo + i1, 0]
                    ry = a * dst[lo + i, 1] + (1.0 - a) * dst[lo + i1, 1]
                    done = True
                    break
                t = cross / (rr + dot)
                w = (t_prev + t) / ri
                sumw += w
                ax += w * dst[lo + i, 0]
                ay += w * dst[lo + i, 1]
                t_prev = t
                sxi, syi, ri = sxn, syn, rn
            if not done:
                rx = ax / sumw
                ry = ay / sumw
        res[j, 0] = wts[j] * rx
        res[j, 1] = wts[j] * ry
