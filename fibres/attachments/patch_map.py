"""Fibre ends on an attachment patch: the unit square onto the patch, by area, in order.

`fibres.slicing.harmonic` spreads the fibres' ends over the whole origin and insertion
patches: template end coordinates ``(X, Y)`` in [0, 1]^2 go onto the patch by the
Knothe-Rosenblatt rearrangement of the uniform square onto the patch's area measure
(`area_points`). The result is a face and barycentric weights: a material point that rides
a deformed copy of the surface.
"""
from __future__ import annotations

import numpy as np

__all__ = ["area_points", "relax_on_patch", "relax_on_patches", "LLOYD", "grid_area_map",
           "knothe_rosenblatt", "kr_coordinates", "locate", "WINDOW", "SAMPLES"]


#: nearest triangles tried first when locating a point (`locate`)
CANDIDATES = 12
#: about this many samples of a patch's area measure (each triangle split into n^2 equal parts)
SAMPLES = 1500


def _sub_centroids(n: int) -> np.ndarray:
    """(n^2, 3) barycentric weights of the centroids of a triangle's regular split into n^2
    equal sub-triangles."""
    out = []
    for i in range(n):
        for j in range(n - i):
            out.append(((i + 1 / 3) / n, (j + 1 / 3) / n))
            if i + j <= n - 2:
                out.append(((i + 2 / 3) / n, (j + 2 / 3) / n))
    uv = np.array(out)
    return np.c_[1.0 - uv.sum(axis=1), uv]
#: conditional window width of `area_points`, as a share of the patch's extent along e1
WINDOW = 0.08


def _quantile(values, weights, q):
    """Weighted quantiles (piecewise linear in the mid-point cumulative weights)."""
    order = np.argsort(values, kind="stable")
    v, w = values[order], weights[order]
    cum = np.cumsum(w)
    mid = (cum - 0.5 * w) / cum[-1]
    return np.interp(q, mid, v)


def _window_weights(sx, sw, x, h):
    """(N, S) sample weights ``sw`` times the Gaussian window of width ``h`` about each
    ``x`` (N,) (all ``sw`` for a point no sample's window reaches) and their cumulative sums
    along S."""
    d = (sx[None] - np.asarray(x, dtype=np.float64)[:, None]) / h
    w = np.exp(-0.5 * (d * d))
    w *= sw[None]
    cum = np.cumsum(w, axis=1)
    empty = ~(cum[:, -1] > 0)                   # the weights are >= 0: the sum is the last
    if empty.any():
        w[empty] = sw[None]
        cum[empty] = np.cumsum(sw)[None]
    return w, cum


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
    w, cum = _window_weights(sx, sw, xs, h)                              # (N, S)
    # the mid-point cumulative weights, normalised only where they are used (the count of
    # those below q compares before the division: the same up to rounding)
    total = cum[:, -1].copy()
    half = cum
    half -= 0.5 * w
    q = np.clip(Y, 0.0, 1.0)
    k = np.clip(np.count_nonzero(half < (q * total)[:, None], axis=1), 1, len(sy) - 1)
    at = k + len(sy) * np.arange(len(xs))
    m0, m1 = half.reshape(-1)[at - 1] / total, half.reshape(-1)[at] / total
    f = np.clip((q - m0) / np.maximum(m1 - m0, 1e-300), 0.0, 1.0)
    ys = sy[k - 1] + f * (sy[k] - sy[k - 1])
    below, above = q <= half[:, 0] / total, q >= half[:, -1] / total
    ys = np.where(below, sy[0], np.where(above, sy[-1], ys))
    return xs, ys


def grid_area_map(mass, X, Y):
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

    Returns
    -------
    xs, ys : (N,) float in [0, 1]
    """
    m = np.maximum(np.asarray(mass, dtype=np.float64), 0.0)
    g = m.shape[0]
    m = m + 1e-12 * max(float(m.sum()), 1e-300) / m.size        # no empty cell
    knots = np.linspace(0.0, 1.0, g + 1)
    col = m.sum(axis=1)
    f1 = np.concatenate([[0.0], np.cumsum(col)]) / col.sum()
    xs = np.interp(np.clip(X, 0.0, 1.0), f1, knots)
    c = np.clip(xs * g - 0.5, 0.0, g - 1.0)
    a0 = np.minimum(np.floor(c).astype(np.int64), g - 1)
    a1 = np.minimum(a0 + 1, g - 1)
    t = (c - a0)[:, None]
    prof = m / col[:, None]                                     # (G, G) rows sum to 1
    p = (1.0 - t) * prof[a0] + t * prof[a1]                     # (N, G)
    cum = np.concatenate([np.zeros((len(xs), 1)), np.cumsum(p, axis=1)], axis=1)
    cum /= cum[:, -1:]
    q = np.clip(Y, 0.0, 1.0)[:, None]
    k = np.clip(np.count_nonzero(cum[:, 1:] < q, axis=1), 0, g - 1)
    at = k + (g + 1) * np.arange(len(xs))
    lo, hi = cum.reshape(-1)[at], cum.reshape(-1)[at + 1]
    f = np.clip((q[:, 0] - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)
    return xs, (k + f) / g


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
    w, cum = _window_weights(sx, sw, qx, h)
    k = np.clip(np.searchsorted(sy, qy, side="left"), 1, len(sy) - 1)   # #(sy < qy)
    at = k + len(sy) * np.arange(len(k))
    # the mid-point cumulative weights only where they are used
    m0 = (cum.reshape(-1)[at - 1] - 0.5 * w.reshape(-1)[at - 1]) / cum[:, -1]
    m1 = (cum.reshape(-1)[at] - 0.5 * w.reshape(-1)[at]) / cum[:, -1]
    f = np.clip((qy - sy[k - 1]) / np.maximum(sy[k] - sy[k - 1], 1e-300), 0.0, 1.0)
    Y = m0 + f * (m1 - m0)
    return np.clip(X, 0.0, 1.0), np.clip(Y, 0.0, 1.0)


def locate(px, py, xs, ys):
    """The triangle (T, 3 projected corners ``px``, ``py``) under each planar point, or the
    nearest by centroid, and the point's barycentric weights there (clipped, normalised).
    Candidates: the `CANDIDATES` triangles with the nearest centroids (all triangles for a
    point none of them holds)."""
    from scipy.spatial import cKDTree

    cx, cy = px.mean(axis=1), py.mean(axis=1)
    k = min(CANDIDATES, len(px))
    near = cKDTree(np.c_[cx, cy]).query(np.c_[xs, ys], k=k)[1].reshape(len(xs), k)
    pick, bary, ok = _barycentric(px, py, xs, ys, near)
    if not ok.all():
        miss = np.flatnonzero(~ok)
        every = np.broadcast_to(np.arange(len(px)), (miss.size, len(px)))
        p2, b2, ok2 = _barycentric(px, py, xs[miss], ys[miss], every)
        pick[miss[ok2]], bary[miss[ok2]] = p2[ok2], b2[ok2]
    return pick, bary


def _barycentric(px, py, xs, ys, cand):
    """Among candidate triangles ``cand`` (N, k) of each point: the first holding it (else the
    first candidate, the nearest), its clipped barycentrics, and whether one held it."""
    ax, ay = px[cand, 0], py[cand, 0]
    bx, by = px[cand, 1] - ax, py[cand, 1] - ay
    cx, cy = px[cand, 2] - ax, py[cand, 2] - ay
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
    return cand[rows, col].copy(), bary, ok


def area_points(vertices, faces, face_mask, centre, e1, e2, X, Y):
    """Template end coordinates ``(X, Y)`` in [0, 1]^2 onto a patch, by area and order-preserving.

    The Knothe-Rosenblatt rearrangement (Rosenblatt, Ann. Math. Stat. 23(3):470-472, 1952;
    Villani, "Optimal transport", 2009, ch. 1) of the uniform square onto the patch's area,
    in the frame ``(e1, e2)`` (`knothe_rosenblatt`), then the patch point whose projection is
    the target (`locate`). Equal areas of the square go to about equal areas of the patch,
    and fibres keep their order across it.

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (T, 3) int
    face_mask : (T,) bool
        The patch's faces (at least one).
    centre, e1, e2 : (3,) float
        The frame: origin and two orthonormal axes.
    X, Y : (N,) float in [0, 1]

    Returns
    -------
    face : (N,) int64
        Index into ``faces``.
    bary : (N, 3) float
        Barycentric weights of the face's corners (non-negative, summing to 1).
    """
    idx = np.flatnonzero(face_mask)
    tri = np.take(vertices, faces[idx], axis=0)                    # (Tp, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    px = (tri - centre) @ e1
    py = (tri - centre) @ e2
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
    (`_onto_patch`: a face and barycentric weights, continuous in the centroid). A point
    moves by at most about half its distance to its neighbours per step and keeps its place
    among them (order is kept but for local swaps), while the holes of a quasi-random set
    (Sobol ends leave ~15 % of a patch more than half a spacing from any end) close.

    Every step is a continuous function of the points and of the patch's coordinates, and
    none depends on the frame, the scale or the numbering of the mesh: a rigid motion, a
    uniform scale or a renumbering of the mesh moves the relaxed points alike, up to
    rounding. (Snapping each point to its nearest *sample* instead is not: where the
    centroid lies midway between two samples, as on a symmetric patch, rounding picks one.)

    Returns
    -------
    face : (N,) int64
    bary : (N, 3) float
    """
    return relax_on_patches(vertices, faces, [(face_mask, face, bary)], iterations=iterations,
                            samples=samples)[0]


def relax_on_patches(vertices, faces, ends, *, iterations: int = LLOYD,
                     samples: int = SAMPLES):
    """`relax_on_patch` of several patches at once: ``ends`` a sequence of ``(face_mask,
    face, bary)``; a list of ``(face, bary)``, each patch's as `relax_on_patch` makes it.

    The patches share the k-d trees of each step: every point, sample and triangle centroid
    gets a fourth coordinate, its patch's number times a length (`_apart`) beyond any
    distance the steps look, so nothing sees another patch's samples or triangles, and the
    distances within a patch are the three-dimensional ones (the fourth differences are 0)."""
    from scipy.spatial import cKDTree

    out = [(np.asarray(f, dtype=np.int64).copy(), np.asarray(b, dtype=np.float64).copy())
           for _, f, b in ends]
    todo = [k for k, (mask, _, _) in enumerate(ends)
            if iterations > 0 and np.any(mask) and len(out[k][0]) >= 2]
    if not todo:
        return out
    apart = _apart(vertices)
    parts = []
    for slot, k in enumerate(todo):
        face, bary = out[k]
        i = np.flatnonzero(ends[k][0])
        t = np.take(vertices, faces[i], axis=0)                        # (Tp, 3, 3)
        area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
        n = int(np.clip(np.sqrt(samples / max(len(i), 1)), 1, 8))
        sub = _sub_centroids(n)                                        # (S, 3)
        s = np.einsum("sk,tkd->tsd", sub, t).reshape(-1, 3)
        p = np.einsum("nk,nkd->nd", bary, vertices[faces[face]])
        parts.append((i, t, s, np.repeat(area / len(sub), len(sub)), p, face, bary,
                      np.full(len(i), slot * apart), np.full(len(s), slot * apart),
                      np.full(len(p), slot * apart), np.full(len(p), slot)))
    idx, tri, pts, w, p, face, bary, tag, sample_tag, point_tag, point_slot = (
        np.concatenate(x) for x in zip(*parts))
    pts4 = np.c_[pts, sample_tag]
    patch = _Patch(tri, pts4, tag)
    # each patch's own largest triangle radius bounds its points' searches
    reach = np.array([patch.radius[tag == slot * apart].max() for slot in range(len(todo))])
    point_reach = reach[point_slot]
    for _ in range(int(iterations)):
        owner = cKDTree(np.c_[p, point_tag]).query(pts4)[1]
        mass = np.bincount(owner, w, len(p))
        has = mass > 0
        c = np.stack([np.bincount(owner, w * pts[:, d], len(p)) for d in range(3)], axis=1)
        sel = np.flatnonzero(has)
        pick, b, q = _onto_patch(patch, c[sel] / mass[sel, None], point_tag[sel],
                                 point_reach[sel])
        face[sel], bary[sel], p[sel] = idx[pick], b, q
    at = np.cumsum([0] + [len(part[4]) for part in parts])
    for slot, k in enumerate(todo):
        out[k] = (face[at[slot]:at[slot + 1]], bary[at[slot]:at[slot + 1]])
    return out


def _apart(vertices) -> float:
    """A length beyond every distance `relax_on_patches` looks within one patch: 4 times the
    largest extent of the vertices, at least 1."""
    v = np.asarray(vertices, dtype=np.float64)
    return 4.0 * max(float(np.ptp(v, axis=0).max()) if len(v) else 0.0, 1.0)


class _Patch:
    """Patches' triangles ``tri`` (Tp, 3, 3) and area samples (points of the patches with
    their fourth coordinate, `relax_on_patches`) with the k-d trees and bound that
    `_onto_patch` needs, built once for all Lloyd steps; ``tag`` (Tp,) the triangles' fourth
    coordinate."""

    def __init__(self, tri, samples, tag):
        from scipy.spatial import cKDTree

        self.tri = tri
        cen = tri.mean(axis=1)
        self.cen = cen
        self.radius = np.sqrt(((tri - cen[:, None]) ** 2).sum(axis=2).max(axis=1))   # (Tp,)
        self.reach = float(self.radius.max())
        self.samples = cKDTree(samples)
        self.centroids = cKDTree(np.c_[cen, tag])


def _onto_patch(patch: _Patch, c, tag, reach=None):
    """The point of the patch's triangles nearest each point ``c`` (M, 3) (with its fourth
    coordinate ``tag`` (M,): among its own patch's triangles): its triangle (index into
    ``patch.tri``), barycentric weights and position. ``reach`` (M,): the largest
    centroid-to-corner distance of each point's own patch's triangles (default: of all).

    Exact among all triangles: a sample (a point of the patch) at distance ``d0`` from c
    bounds the distance to the patch, so only triangles whose centroid lies within ``d0``
    plus their centroid-to-corner distance can hold a nearer point (those within ``d0`` plus
    the largest such distance are found by a k-d tree, then filtered); the nearest point of
    each is found by `fibres.mesh.closest_point.closest_points_on_triangles`. Where two
    triangles hold the same nearest point (their shared edge or corner), either gives the
    same position on any deformed copy."""
    from itertools import chain

    from ..mesh.closest_point import closest_points_on_triangles

    tri = patch.tri
    c4 = np.c_[c, tag]
    d0 = patch.samples.query(c4)[0]
    reach = patch.reach if reach is None else reach
    near = patch.centroids.query_ball_point(c4, (d0 + reach) * (1.0 + 1e-9),
                                            return_sorted=False)
    count = np.fromiter(map(len, near), dtype=np.int64, count=len(c))
    cand = np.fromiter(chain.from_iterable(near), dtype=np.int64, count=int(count.sum()))
    who = np.repeat(np.arange(len(c)), count)                          # (pairs,)
    # a triangle's points lie within its own radius of its centroid
    p = np.take(c, who, axis=0)
    gap = np.take(patch.cen, cand, axis=0) - p
    bound = (d0[who] + patch.radius[cand]) * (1.0 + 1e-9)
    keep = np.einsum("kd,kd->k", gap, gap) <= bound * bound
    cand, who = cand[keep], who[keep]
    count = np.bincount(who, minlength=len(c))
    t = np.take(tri, cand, axis=0)
    p = p[keep]
    q = closest_points_on_triangles(p, t[:, 0], t[:, 1], t[:, 2])
    d2 = np.einsum("kd,kd->k", q - p, q - p)
    best = np.lexsort((d2, who))[np.concatenate([[0], np.cumsum(count)[:-1]])]
    pick, out = cand[best], q[best]
    return pick, _barycentric_3d(tri[pick], out), out


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
