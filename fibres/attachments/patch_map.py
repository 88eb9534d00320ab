"""Fibre ends on an attachment patch: the unit square onto the patch, by area, in order.

`fibres.slicing.harmonic` spreads the fibres' ends over the whole origin and insertion
patches: template end coordinates ``(X, Y)`` in [0, 1]^2 go onto the patch by the
Knothe-Rosenblatt rearrangement of the uniform square onto the patch's area measure
(`area_points`). The result is a face and barycentric weights: a material point that rides
a deformed copy of the surface.

Compiled (numba, module level, ``cache=True``): the conditional measure's per-point sums
(`_window`), the grid map (`_grid_map`) and the Lloyd steps (`_lloyd`); what is one
vectorised step per patch (triangles, samples, weights, the finishing barycentric weights)
is numpy around them.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit

from ..mesh.closest_point import closest_point
from .patch import cross_rows

__all__ = ["area_points", "relax_on_patch", "relax_on_patches", "LLOYD", "grid_area_map",
           "knothe_rosenblatt", "kr_coordinates", "locate", "WINDOW", "SAMPLES"]


#: nearest triangles tried first when locating a point (`locate`)
CANDIDATES = 12
#: about this many samples of a patch's area measure (each triangle split into n^2 equal parts)
SAMPLES = 1500


@lru_cache(maxsize=16)
def _sub_centroids(n: int) -> np.ndarray:
    """(n^2, 3) barycentric weights of the centroids of a triangle's regular split into n^2
    equal sub-triangles (one read-only array per n)."""
    out = []
    for i in range(n):
        for j in range(n - i):
            out.append(((i + 1 / 3) / n, (j + 1 / 3) / n))
            if i + j <= n - 2:
                out.append(((i + 2 / 3) / n, (j + 2 / 3) / n))
    uv = np.array(out)
    sub = np.c_[1.0 - uv.sum(axis=1), uv]
    sub.flags.writeable = False
    return sub


#: conditional window width of `area_points`, as a share of the patch's extent along e1
WINDOW = 0.08


def _quantile(values, weights, q):
    """Weighted quantiles (piecewise linear in the mid-point cumulative weights)."""
    order = np.argsort(values, kind="stable")
    v, w = values[order], weights[order]
    cum = np.cumsum(w)
    mid = (cum - 0.5 * w) / cum[-1]
    return np.interp(q, mid, v)


#: e^a in `_window`: a = j ln 2 + r, |r| <= ln 2 / 2 (Cody & Waite, ln 2 in two parts:
#: fdlibm's), e^r by Taylor to r^13, times 2^j from a table (a >= -600). Within 2 ulp of
#: math.exp, and vectorised by the compiler (math.exp is a library call per element).
_LN2_HI, _LN2_LO, _LOG2E = 6.93147180369123816490e-01, 1.90821492927058770002e-10, 1 / math.log(2)
_POW2 = np.ldexp(1.0, np.arange(-900, 1))                  # 2^j, j = -900 .. 0


@njit(cache=True, nogil=True, error_model="numpy")
def _window(sx, sw, x, h, q, k, out, work):
    """The conditional measure of `knothe_rosenblatt` and `kr_coordinates` at each ``x[i]``:
    the samples' weights ``sw`` times the Gaussian window of width ``h`` about ``x[i]``
    (its exponent at least -600: beyond 34 widths from every sample, as where no sample's
    window reaches, the weights are ``sw``'s own), in the samples' order, and their
    mid-point cumulative sums ``half_s = cum_s - w_s / 2``,
    ``total`` the last ``cum_s``. Where ``k[i] < 0`` on entry it becomes the count of
    ``half_s < q[i] * total`` clipped to [1, S - 1]; ``out[i]`` gets ``half[k - 1], half[k],
    total, half[0], half[S - 1]``. Work space ``work`` (S,)."""
    n = sx.shape[0]
    for i in range(x.shape[0]):
        for s in range(n):
            d = (sx[s] - x[i]) / h
            a = max(-0.5 * (d * d), -600.0)
            j = math.floor(a * _LOG2E + 0.5)
            r = (a - j * _LN2_HI) - j * _LN2_LO
            e = r * (1.0 / 6227020800.0) + 1.0 / 479001600.0
            for c in (39916800.0, 3628800.0, 362880.0, 40320.0, 5040.0, 720.0, 120.0,
                      24.0, 6.0, 2.0, 1.0, 1.0):
                e = e * r + 1.0 / c
            work[s] = e * _POW2[j + 900]
        cum = 0.0
        for s in range(n):
            w = work[s] * sw[s]
            cum += w
            work[s] = cum - 0.5 * w
        if not cum > 0.0:                         # all of sw zero (or not finite)
            cum = 0.0
            for s in range(n):
                cum += sw[s]
                work[s] = cum - 0.5 * sw[s]
        if k[i] < 0:
            below, limit = 0, q[i] * cum
            for s in range(n):
                below += work[s] < limit
            k[i] = min(max(below, 1), n - 1)
        out[i, 0], out[i, 1], out[i, 2] = work[k[i] - 1], work[k[i]], cum
        out[i, 3], out[i, 4] = work[0], work[n - 1]


def knothe_rosenblatt(px, py, area, X, Y, *, samples: int = SAMPLES):
    """Planar targets ``(x*, y*)`` of unit-square coordinates ``(X, Y)`` under the
    Knothe-Rosenblatt map onto the area measure of triangles with projected corners ``px``,
    ``py`` (T, 3) and areas ``area`` (T,): ``x* = F1^-1(X)`` (the area quantile along x),
    ``y* = F2^-1(Y | x*)`` (along y among the triangles near x*, a Gaussian window of
    `WINDOW` of the extent along x). The measure is sampled at the centroids of each
    triangle's split into n^2 equal parts (n so that there are about ``samples``, at least
    one per triangle)."""
    n = int(np.clip(np.sqrt(samples / max(len(px), 1)), 1, 8))
    sub = _sub_centroids(n)
    sx = (px @ sub.T).reshape(-1)
    sy = (py @ sub.T).reshape(-1)
    sw = np.repeat(np.asarray(area, dtype=np.float64) / len(sub), len(sub))
    xs = _quantile(sx, sw, np.clip(X, 0.0, 1.0))
    h = WINDOW * max(float(sx.max() - sx.min()), 1e-12)
    order = np.argsort(sy, kind="stable")
    sy, sx, sw = sy[order], sx[order], sw[order]
    q = np.clip(Y, 0.0, 1.0)
    k = np.full(len(xs), -1, dtype=np.int64)
    half = np.empty((len(xs), 5))                    # (N, 5): `_window`'s sums
    _window(sx, sw, xs, h, q, k, half, np.empty(len(sx)))
    total = half[:, 2]
    m0, m1 = half[:, 0] / total, half[:, 1] / total
    f = np.clip((q - m0) / np.maximum(m1 - m0, 1e-300), 0.0, 1.0)
    ys = sy[k - 1] + f * (sy[k] - sy[k - 1])
    below, above = q <= half[:, 3] / total, q >= half[:, 4] / total
    ys = np.where(below, sy[0], np.where(above, sy[-1], ys))
    return xs, ys


def grid_area_map(mass, X, Y, groups=None):
    """Unit-square coordinates ``(X, Y)`` onto the square itself, spread by a cell density.

    ``mass`` (G, G) is the mass of the grid cells of [0, 1]^2 (cell ``(a, b)`` spans
    ``[a, a + 1] / G`` along x and ``[b, b + 1] / G`` along y): here the area of a
    membrane's image of each cell (`fibres.slicing.harmonic`). The map is Knothe-Rosenblatt
    (Rosenblatt 1952) in the square's own coordinates: ``x* = F1^-1(X)`` with F1 the
    cumulative column masses (piecewise linear between the grid lines), then
    ``y* = F2^-1(Y | x*)`` with the conditional profile of y interpolated linearly between
    the two columns whose centres bracket x* (so that y* is continuous in x*). Equal areas
    of the square go to about equal masses, and the map is one-to-one and continuous in X,
    Y and the masses: unlike a map in a projection of the membrane, it cannot jump between
    two sheets of a folded projection.

    With ``groups`` (N,) ints in [0, L), ``mass`` is a stack (L, G, G) and each point goes
    through the map of its own grid (one compiled pass, `_grid_map`).

    Returns
    -------
    xs, ys : (N,) float in [0, 1]
    """
    m = np.maximum(np.asarray(mass, dtype=np.float64), 0.0)
    if groups is None:
        m, groups = m[None], np.zeros(len(X), dtype=np.int64)
    g = m.shape[1]
    m = m + 1e-12 * np.maximum(m.sum(axis=(1, 2)), 1e-300)[:, None, None] / (g * g)
    col = m.sum(axis=2)                                         # (L, G)
    f1 = np.zeros((len(m), g + 1))
    np.cumsum(col, axis=1, out=f1[:, 1:])
    f1 /= col.sum(axis=1)[:, None]
    xs, ys = np.empty(len(X)), np.empty(len(X))
    _grid_map(f1, m / col[:, :, None], np.linspace(0.0, 1.0, g + 1),
              np.ascontiguousarray(groups, dtype=np.int64), np.asarray(X, dtype=np.float64),
              np.asarray(Y, dtype=np.float64), xs, ys, np.empty(g + 1))
    return xs, ys


@njit(cache=True, nogil=True, error_model="numpy")
def _grid_map(f1, prof, knots, groups, X, Y, xs, ys, cum):
    """`grid_area_map` point by point into ``xs``, ``ys``: point i in grid ``groups[i]``,
    cumulative column shares ``f1`` (L, G + 1), row profiles ``prof`` (L, G, G) (each
    column's masses over its sum); ``x*`` as `np.interp` of ``knots`` (G + 1,) evaluates
    it; the conditional's cumulative sums in ``cum`` (G + 1,)."""
    g = prof.shape[1]
    for i in range(X.shape[0]):
        f, x, q = f1[groups[i]], min(max(X[i], 0.0), 1.0), min(max(Y[i], 0.0), 1.0)
        if x >= f[g]:
            xs[i] = knots[g]
        else:
            j = 0
            for b in range(1, g):
                j += f[b] <= x
            xs[i] = (knots[j + 1] - knots[j]) / (f[j + 1] - f[j]) * (x - f[j]) + knots[j]
        c = min(max(xs[i] * g - 0.5, 0.0), g - 1.0)
        a0 = min(int(math.floor(c)), g - 1)
        a1 = min(a0 + 1, g - 1)
        t = c - a0
        p0, p1 = prof[groups[i], a0], prof[groups[i], a1]
        cum[0] = 0.0
        for b in range(g):
            cum[b + 1] = cum[b] + ((1.0 - t) * p0[b] + t * p1[b])
        k = 0
        for b in range(1, g + 1):
            cum[b] = cum[b] / cum[g] if b < g else 1.0
            k += cum[b] < q
        k = min(k, g - 1)
        lo, hi = cum[k], cum[k + 1]
        ys[i] = (k + min(max((q - lo) / max(hi - lo, 1e-300), 0.0), 1.0)) / g


def kr_coordinates(px, py, area, qx, qy, *, samples: int = SAMPLES):
    """The inverse of `knothe_rosenblatt`: unit-square coordinates ``(X, Y)`` of planar
    points ``(qx, qy)`` under the same measure (triangles' projected corners ``px``, ``py``
    and areas), ``X = F1(qx)``, ``Y = F2(qy | qx)`` with the same sampling and conditional
    window, so ``knothe_rosenblatt(..., *kr_coordinates(..., x, y))`` returns ``(x, y)`` up
    to the sampling. Used to carry points of one measure onto another in order (the first
    section's membrane onto an attachment patch: `fibres.slicing.harmonic`)."""
    n = int(np.clip(np.sqrt(samples / max(len(px), 1)), 1, 8))
    sub = _sub_centroids(n)
    sx = (px @ sub.T).reshape(-1)
    sy = (py @ sub.T).reshape(-1)
    sw = np.repeat(np.asarray(area, dtype=np.float64) / len(sub), len(sub))
    order = np.argsort(sx, kind="stable")
    cum = np.cumsum(sw[order])
    mid = (cum - 0.5 * sw[order]) / cum[-1]
    X = np.interp(qx, sx[order], mid)
    h = WINDOW * max(float(sx.max() - sx.min()), 1e-12)
    order = np.argsort(sy, kind="stable")
    sy, sx, sw = sy[order], sx[order], sw[order]
    k = np.clip(np.searchsorted(sy, qy, side="left"), 1, len(sy) - 1)   # #(sy < qy)
    half = np.empty((len(k), 5))                     # (N, 5): `_window`'s sums
    _window(sx, sw, np.asarray(qx, dtype=np.float64), h, np.zeros(len(k)), k, half,
            np.empty(len(sx)))
    m0, m1 = half[:, 0] / half[:, 2], half[:, 1] / half[:, 2]
    f = np.clip((qy - sy[k - 1]) / np.maximum(sy[k] - sy[k - 1], 1e-300), 0.0, 1.0)
    Y = m0 + f * (m1 - m0)
    return np.clip(X, 0.0, 1.0), np.clip(Y, 0.0, 1.0)


def locate(px, py, xs, ys):
    """The triangle (T, 3 projected corners ``px``, ``py``) under each planar point, or the
    nearest by centroid, and the point's barycentric weights there (clipped, normalised).
    Candidates: the `CANDIDATES` triangles with the nearest centroids (all triangles for a
    point none of them holds)."""
    from scipy.spatial import cKDTree

    cx, cy = (px[:, 0] + px[:, 1] + px[:, 2]) / 3.0, (py[:, 0] + py[:, 1] + py[:, 2]) / 3.0
    k = min(CANDIDATES, len(px))
    tree = cKDTree(np.stack([cx, cy], axis=1), leafsize=32, balanced_tree=False,
                   compact_nodes=False)                          # a faster build
    near = tree.query(np.stack([xs, ys], axis=1), k=k)[1]
    pick, bary, ok = _barycentric(px, py, xs, ys, near.reshape(len(xs), k))
    if not ok.all():
        miss = np.flatnonzero(~ok)
        p2, b2, ok2 = _barycentric(px, py, xs[miss], ys[miss], None)
        pick[miss[ok2]], bary[miss[ok2]] = p2[ok2], b2[ok2]
    return pick, bary


def _barycentric(px, py, xs, ys, cand):
    """Among candidate triangles ``cand`` (N, k) of each point (None: all triangles, in
    order): the first holding it (else the first candidate, the nearest), its clipped
    barycentrics, and whether one held it."""
    def corner(c, k):                                # all: broadcast (1, T), no gather
        return c[None, :, k] if cand is None else c[cand, k]

    ax, ay, bx, by, cx, cy = (corner(c, k) for k in range(3) for c in (px, py))
    bx, by = bx - ax, by - ay
    cx, cy = cx - ax, cy - ay
    det = bx * cy - by * cx
    det = np.where(np.abs(det) < 1e-30, 1e-30, det)
    qx, qy = xs[:, None] - ax, ys[:, None] - ay
    l1 = (qx * cy - qy * cx) / det
    l2 = (bx * qy - by * qx) / det
    l0 = 1.0 - l1 - l2
    inside = np.minimum(np.minimum(l0, l1), l2) >= -1e-9
    ok = inside.any(axis=1)
    col = np.where(ok, np.argmax(inside, axis=1), 0)
    rows = np.arange(len(xs))
    bary = np.clip(np.stack([l0[rows, col], l1[rows, col], l2[rows, col]], axis=1), 0.0, None)
    bary /= np.maximum(bary.sum(axis=1, keepdims=True), 1e-300)
    return (col if cand is None else cand[rows, col].copy()), bary, ok


def _areas(tri):
    """(T,) areas of the triangles ``tri`` (T, 3, 3): half the norm of the cross product of
    the edges from the first corner."""
    c = cross_rows(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return 0.5 * np.sqrt(c[:, 0] * c[:, 0] + c[:, 1] * c[:, 1] + c[:, 2] * c[:, 2])


def area_points(vertices, faces, face_mask, centre, e1, e2, X, Y):
    """Template end coordinates ``(X, Y)`` (N,) in [0, 1]^2 onto a patch, by area and
    order-preserving: per point a face (N,) int64 (index into ``faces`` (T, 3)) and the
    barycentric weights (N, 3) of its corners (non-negative, summing to 1).

    The Knothe-Rosenblatt rearrangement (Rosenblatt, Ann. Math. Stat. 23(3):470-472, 1952;
    Villani, "Optimal transport", 2009, ch. 1) of the uniform square onto the patch's area
    (faces ``face_mask`` (T,) bool, at least one; ``vertices`` (V, 3)), in the frame of
    origin ``centre`` and orthonormal axes ``e1``, ``e2`` (`knothe_rosenblatt`), then the
    patch point whose projection is the target (`locate`). Equal areas of the square go to
    about equal areas of the patch, and fibres keep their order across it.
    """
    idx = np.flatnonzero(face_mask)
    tri = np.take(vertices, faces[idx], axis=0) - centre             # (Tp, 3, 3)
    area = _areas(tri)
    px, py = tri @ e1, tri @ e2
    xs, ys = knothe_rosenblatt(px, py, area, X, Y)
    pick, bary = locate(px, py, xs, ys)
    return idx[pick], bary


#: Lloyd iterations of `relax_on_patch`
LLOYD = 3


def relax_on_patch(vertices, faces, face_mask, face, bary, *, iterations: int = LLOYD,
                   samples: int = SAMPLES):
    """Points on a patch (``face``, ``bary``) spread more evenly over it: a few Lloyd steps
    towards a centroidal Voronoi tessellation of the patch's area (Lloyd, IEEE Trans. Inf.
    Theory 28(2), 1982; Du, Faber & Gunzburger, SIAM Review 41(4), 1999).

    The patch's area is sampled at the centroids of each triangle's split into n^2 equal
    parts (about ``samples`` in all); each step gives every sample to its nearest point and
    moves each point to the patch point nearest the area-weighted centroid of its own samples
    (`_lloyd`: a face and barycentric weights, continuous in the centroid). A point
    moves by at most about half its distance to its neighbours per step and keeps its place
    among them (order is kept but for local swaps), while the holes of a quasi-random set
    (Sobol ends leave ~15 % of a patch more than half a spacing from any end) close.

    Every step is a continuous function of the points and of the patch's coordinates, and
    none depends on the frame, the scale or the numbering of the mesh: a rigid motion, a
    uniform scale or a renumbering of the mesh moves the relaxed points alike, up to
    rounding. (Snapping each point to its nearest *sample* instead is not: where the
    centroid lies midway between two samples, as on a symmetric patch, rounding picks one.)
    Returns the points' ``face`` (N,) int64 and ``bary`` (N, 3).
    """
    return relax_on_patches(vertices, faces, [(face_mask, face, bary)], iterations=iterations,
                            samples=samples)[0]


def relax_on_patches(vertices, faces, ends, *, iterations: int = LLOYD,
                     samples: int = SAMPLES):
    """`relax_on_patch` of several patches at once: ``ends`` a sequence of ``(face_mask,
    face, bary)``; a list of ``(face, bary)``, each patch's as `relax_on_patch` makes it.

    The samples and triangles are made in numpy; the steps run in one compiled loop over the
    patches (`_lloyd`), each on its own points, samples and triangles."""
    out = [(np.asarray(f, dtype=np.int64).copy(), np.asarray(b, dtype=np.float64).copy())
           for _, f, b in ends]
    todo = [k for k, (mask, _, _) in enumerate(ends)
            if iterations > 0 and np.any(mask) and len(out[k][0]) >= 2]
    if not todo:
        return out
    parts = []
    for k in todo:
        face, bary = out[k]
        i = np.flatnonzero(ends[k][0])
        t = np.take(vertices, faces[i], axis=0)                        # (Tp, 3, 3)
        area = _areas(t)
        n = int(np.clip(np.sqrt(samples / max(len(i), 1)), 1, 8))
        sub = _sub_centroids(n)                                        # (S, 3)
        cen = (t[:, 0] + t[:, 1] + t[:, 2]) / 3.0
        axis = int(np.argmax(np.ptp(cen, axis=0)))       # the triangles in order along it
        order = np.argsort(cen[:, axis], kind="stable")
        parts.append((i[order], t[order], cen[order], np.einsum("sk,tkd->tsd", sub, t).reshape(
            -1, 3), np.repeat(area / len(sub), len(sub)),
            np.einsum("nk,nkd->nd", bary, vertices[faces[face]]), axis))
    idx, tri, cen, pts, w, p = (np.concatenate([part[j] for part in parts]) for j in range(6))
    starts = [np.cumsum([0] + [len(part[j]) for part in parts]) for j in (0, 3, 5)]
    pick = np.full(len(p), -1, dtype=np.int64)
    _lloyd(tri, cen, np.array([part[6] for part in parts]), pts, w, p, *starts,
           int(iterations), pick)
    moved = np.flatnonzero(pick >= 0)
    face = np.concatenate([out[k][0] for k in todo])
    bary = np.concatenate([out[k][1] for k in todo])
    face[moved] = idx[pick[moved]]
    bary[moved] = _barycentric_3d(tri[pick[moved]], p[moved])
    at = starts[2]
    for slot, k in enumerate(todo):
        out[k] = (face[at[slot]:at[slot + 1]], bary[at[slot]:at[slot + 1]])
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _lloyd(tri, cen, axes, pts, w, p, tstart, sstart, pstart, iterations, pick):
    """The Lloyd steps of `relax_on_patch` on patches g (segments ``tstart``, ``sstart``,
    ``pstart`` of the triangles ``tri`` (T, 3, 3) with centroids ``cen``, in order along
    the axis ``axes[g]``; of the samples ``pts`` with weights ``w``; of the points ``p``,
    moved in place). Per step: each sample to its nearest point of its patch (ties to the
    lower point), each point with samples to the point of the patch nearest their weighted
    centroid c (its triangle into ``pick``). ``d0``, the distance from c to its nearest own
    sample, and then each closest point found bound the patch's distance: only triangles
    whose centroid lies within the bound + their radius (centroid to corner) of c can hold
    a nearer point (those within the bound + the largest radius along the axis are found by
    bisection, then filtered); their closest points are
    `fibres.mesh.closest_point.closest_point`'s, the nearest wins (ties to the first). The
    points (a hundred) are searched one by one. Work space: ``owner`` (S,) (each sample's
    point), ``work`` (N, 5) (per point: centroid, mass, d0), ``radius`` (T,)."""
    owner, work = np.empty(pts.shape[0], np.int64), np.empty((p.shape[0], 5))
    radius, slack = np.zeros(tri.shape[0]), 1.0 + 1e-9
    for e in range(tri.shape[0]):
        for c in range(3):
            radius[e] = max(radius[e], math.sqrt((tri[e, c, 0] - cen[e, 0]) ** 2 + (
                tri[e, c, 1] - cen[e, 1]) ** 2 + (tri[e, c, 2] - cen[e, 2]) ** 2))
    for g in range(len(tstart) - 1):
        p0, p1, t0, t1, ax = pstart[g], pstart[g + 1], tstart[g], tstart[g + 1], axes[g]
        reach = 0.0
        for e in range(t0, t1):
            reach = max(reach, radius[e])
        for _ in range(iterations):
            for j in range(p0, p1):
                for k in range(5):
                    work[j, k] = 0.0 if k < 4 else np.inf
            for s in range(sstart[g], sstart[g + 1]):
                x0, x1, x2 = pts[s, 0], pts[s, 1], pts[s, 2]
                best, o = np.inf, p0
                for j in range(p0, p1):
                    d = (x0 - p[j, 0]) ** 2 + (x1 - p[j, 1]) ** 2 + (x2 - p[j, 2]) ** 2
                    if d < best:
                        best, o = d, j
                owner[s] = o
                work[o, 3] += w[s]
                work[o, 0] += w[s] * x0
                work[o, 1] += w[s] * x1
                work[o, 2] += w[s] * x2
            for j in range(p0, p1):
                for k in range(3):
                    work[j, k] = work[j, k] / work[j, 3]
            for s in range(sstart[g], sstart[g + 1]):
                o = owner[s]
                d = math.sqrt((pts[s, 0] - work[o, 0]) ** 2 + (pts[s, 1] - work[o, 1]) ** 2
                              + (pts[s, 2] - work[o, 2]) ** 2)
                work[o, 4] = min(work[o, 4], d)
            for j in range(p0, p1):
                if not work[j, 3] > 0.0:
                    continue
                y0, y1, y2, d0 = work[j, 0], work[j, 1], work[j, 2], work[j, 4]
                span = (d0 + reach) * slack
                lo, hi = t0, t1                        # the first centroid past y - span
                while lo < hi:
                    mid = (lo + hi) // 2
                    if cen[mid, ax] < work[j, ax] - span:
                        lo = mid + 1
                    else:
                        hi = mid
                best = np.inf
                for e in range(lo, t1):
                    if cen[e, ax] > work[j, ax] + span:
                        break
                    bound = (d0 + radius[e]) * slack
                    if ((cen[e, 0] - y0) ** 2 + (cen[e, 1] - y1) ** 2
                            + (cen[e, 2] - y2) ** 2 > bound * bound):
                        continue
                    q0, q1, q2 = closest_point(y0, y1, y2, tri[e, 0], tri[e, 1], tri[e, 2])
                    d = (q0 - y0) ** 2 + (q1 - y1) ** 2 + (q2 - y2) ** 2
                    if d < best:
                        best, pick[j] = d, e
                        p[j, 0], p[j, 1], p[j, 2] = q0, q1, q2
                        d0 = min(d0, math.sqrt(d))      # the bound from here on
                        span = (d0 + reach) * slack


def _barycentric_3d(tri, q):
    """(M, 3) barycentric weights of the points ``q`` (M, 3) of the triangles ``tri``
    (M, 3, 3) (points of the closed triangle: the weights are clipped at 0 and normalised
    against rounding)."""
    e1, e2, d = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], q - tri[:, 0]
    g11, g12, g22 = (np.einsum("md,md->m", x, y) for x, y in ((e1, e1), (e1, e2), (e2, e2)))
    r1, r2 = np.einsum("md,md->m", d, e1), np.einsum("md,md->m", d, e2)
    det = g11 * g22 - g12 * g12
    ok = det > 0
    det = np.where(ok, det, 1.0)
    l1 = np.where(ok, (g22 * r1 - g12 * r2) / det, 0.0)
    l2 = np.where(ok, (g11 * r2 - g12 * r1) / det, 0.0)
    bary = np.clip(np.stack([1.0 - l1 - l2, l1, l2], axis=1), 0.0, None)
    return bary / np.maximum(bary.sum(axis=1, keepdims=True), 1e-300)
