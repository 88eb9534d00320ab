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

import math

import numpy as np
from numba import njit

__all__ = ["mean_value_coordinates", "mvc_map", "strict"]

#: Switch on costly invariant checks (partition of unity, linear precision); tests only.
strict = False

# A point is "on" edge i when |sin(alpha_i)| <= _ON_EDGE and cos(alpha_i) < 0: alpha_i is
# within 1e-14 rad of pi, i.e. the point is within ~1e-14 * edge length of the edge, where
# linear interpolation along the edge is exact to rounding.
_ON_EDGE = 1e-14


def mean_value_coordinates(points, polygon, groups=None) -> np.ndarray:
    """Mean value coordinates of many points with respect to one closed polygon, or each
    point with respect to its own polygon of a stack.

    Parameters
    ----------
    points : (N, 2) float
        Query points.
    polygon : (K, 2) float, or (G, K, 2) with ``groups``
        Polygon vertices in order (either orientation; convex or not), K >= 3, not
        repeated at the end. Consecutive coincident vertices are allowed.
    groups : (N,) int in [0, G), optional
        With a stack of G polygons: the polygon of each point.

    Returns
    -------
    lam : (N, K) float
        ``lam[n] @ polygon == points[n]`` (``polygon[groups[n]]``) and ``lam[n].sum() ==
        1``. Rows for points on a vertex are unit vectors; rows for points on an edge are
        the linear interpolation weights of that edge's two vertices.

    Notes
    -----
    One compiled loop over the points (`_mvc_kernel`; Hormann & Floater 2006, eq. for
    ``w_i`` with the half-angle tangent written as ``2A / (r r' + D)``), all polygons in
    one call.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    polys = np.ascontiguousarray(polygon, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (N, 2), got {pts.shape}")
    if groups is None:
        polys, grp = polys[None], np.zeros(len(pts), dtype=np.int64)
    else:
        grp = np.ascontiguousarray(groups, dtype=np.int64)
        if grp.shape != (len(pts),) or (len(grp) and (grp.min() < 0
                                                      or grp.max() >= len(polys))):
            raise ValueError("groups must be (N,) indices of the polygons")
    if polys.ndim != 3 or polys.shape[2] != 2 or polys.shape[1] < 3:
        shape = polys.shape[1:] if groups is None else polys.shape
        raise ValueError(f"polygon must have shape (K, 2) (or (G, K, 2) with groups) with "
                         f"K >= 3, got {shape}")
    k = polys.shape[1]
    lam = _mvc_kernel(pts, grp, polys, np.empty((len(pts), k)), np.empty((4, k)))
    if strict:
        _check(lam, pts, polys[grp])
    return lam


@njit(cache=True, nogil=True, error_model="numpy")
def _mvc_kernel(pts, group, polys, lam, work):
    """(N, K) coordinates into ``lam`` (N, K) (every entry written; work space ``work``
    (4, K)), one point at a time, point ``p`` with respect to ``polys[group[p]]``: ``s_i``,
    ``r_i``, the half-angle tangents ``2 A_i / (r_i r_{i+1} + D_i)``, then ``w_i`` (times
    the reciprocal of their sum); a point on a vertex (``r_i == 0``) gets
    the unit vector of the first such vertex, a point on an edge (``|2 A_i| <= _ON_EDGE
    r_i r_{i+1}`` or ``r r' + D <= 0``, with ``D_i < 0`` and ``r_i r_{i+1} > 0``) the linear
    interpolation weights of the first such edge."""
    n, k = pts.shape[0], polys.shape[1]
    sx, sy, r, tan_half = work[0], work[1], work[2], work[3]
    for p in range(n):
        poly = polys[group[p]]
        vertex = -1
        px, py = pts[p, 0], pts[p, 1]
        for i in range(k):
            xi, yi = poly[i, 0] - px, poly[i, 1] - py
            sx[i], sy[i] = xi, yi
            r[i] = math.sqrt(xi * xi + yi * yi)
            if r[i] == 0.0 and vertex < 0:
                vertex = i
        edge = -1
        if vertex < 0:
            for i in range(k):
                j = i + 1 if i + 1 < k else 0
                xi, yi, xj, yj = sx[i], sy[i], sx[j], sy[j]
                rr = r[i] * r[j]
                cross = xi * yj - yi * xj
                dot = xi * xj + yi * yj
                denom = rr + dot
                if dot < 0.0 and rr > 0.0 and (abs(cross) <= _ON_EDGE * rr or denom <= 0.0):
                    edge = i
                    break
                tan_half[i] = cross / denom
        if vertex >= 0 or edge >= 0:
            for i in range(k):
                lam[p, i] = 0.0
        if vertex >= 0:
            lam[p, vertex] = 1.0
        elif edge >= 0:
            j = edge + 1 if edge + 1 < k else 0
            ra, rb = r[edge], r[j]
            lam[p, edge] = rb / (ra + rb)
            lam[p, j] += ra / (ra + rb)
        else:
            total = 0.0
            for i in range(k):
                w = (tan_half[i - 1 if i > 0 else k - 1] + tan_half[i]) / r[i]
                lam[p, i] = w
                total += w
            inv = 1.0 / total
            for i in range(k):
                lam[p, i] *= inv
    return lam


def _check(lam, pts, polys):
    """The invariants (``strict``): partition of unity and linear precision; ``polys``
    (N, K, 2), each point's polygon."""
    assert np.allclose(lam.sum(axis=1), 1.0, atol=1e-9)
    assert np.allclose(np.einsum("nk,nkd->nd", lam, polys), pts,
                       atol=1e-9 * (1.0 + np.abs(polys).max(initial=0.0)))


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
    `mean_value_coordinates` is evaluated per polygon (all points of a polygon at once).
    """
    pts = np.ascontiguousarray(points, dtype=float)
    groups = np.ascontiguousarray(groups, dtype=np.int64)
    w = np.ones(len(pts)) if weights is None else np.ascontiguousarray(weights, dtype=float)
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


