"""Closest points between rays and a set of triangles, for the attachment filter's new
fibre ends (Kohout 2012 §3.4: the point of the attachment area's surface closest to the ray
that continues a fibre's last kept segment; `fibres.attachments.filtering`).

Ray/triangle hit: Moeller & Trumbore, "Fast, minimum storage ray-triangle intersection",
J. Graphics Tools 2(1), 1997. Closest points of a ray and a segment: Ericson, Real-Time
Collision Detection (2005), §5.1.9 (clamped segment-segment closest points), with the ray's
upper bound removed. Vectorised over rays x triangles in numpy (blocks of rays).
"""
from __future__ import annotations

import numpy as np

from .area import region_triangles, regions_triangles   # the area's triangles

__all__ = ["region_triangles", "regions_triangles", "closest_on_triangles"]


def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _ray_triangle_pairs(tv, s, d):
    """Closest pair between rays s + t d (t >= 0, |d| = 1) and triangles, for every ray
    (n, 1, 3) x triangle (1, T, 3, 3) pair (broadcast).

    The minimum distance between a ray and a triangle (two convex sets) is attained by a hit
    (distance 0; Moeller & Trumbore 1997 ray/triangle test), else by the ray start against
    the triangle's interior (its projection on the plane, when inside), or by the ray
    against one of the three edges (closest points of two clamped segments, Ericson 2005,
    Real-Time Collision Detection §5.1.9, with the ray's upper bound removed).

    Returns (d2 (n, T) squared distance (0 for a hit), t (n, T) ray parameter of the pair,
    bary (n, T, 3) barycentric coordinates of the triangle point)."""
    a, b, c = tv[..., 0, :], tv[..., 1, :], tv[..., 2, :]
    e1, e2 = b - a, c - a
    nrm = np.cross(e1, e2)
    nn = _dot(nrm, nrm)
    w = s - a                                                       # (n, T, 3)
    # hit (Moeller-Trumbore): s + t d = a + u e1 + v e2
    pvec = np.cross(d, e2)
    det = _dot(e1, pvec)
    ok = np.abs(det) > 1e-12 * np.sqrt(nn)
    inv = 1.0 / np.where(ok, det, 1.0)
    u = _dot(w, pvec) * inv
    qvec = np.cross(w, e1)
    v = _dot(d, qvec) * inv
    t_hit = _dot(e2, qvec) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t_hit >= 0)
    d2 = np.where(hit, 0.0, np.inf)
    t = np.where(hit, t_hit, 0.0)
    bary = np.stack([1.0 - u - v, u, v], axis=-1)
    # ray start against the interior
    safe = np.where(nn > 0, nn, 1.0)
    beta = _dot(np.cross(w, e2), nrm) / safe
    gamma = _dot(np.cross(e1, w), nrm) / safe
    height = _dot(w, nrm)
    dp = height * height / safe
    take = (nn > 0) & (beta >= 0) & (gamma >= 0) & (beta + gamma <= 1) & (dp < d2)
    d2 = np.where(take, dp, d2)
    t = np.where(take, 0.0, t)
    bary = np.where(take[..., None], np.stack([1.0 - beta - gamma, beta, gamma], -1), bary)
    # ray against the edges (p, q) = corners (i, j)
    corners = (a, b, c)
    for i, j in ((0, 1), (1, 2), (2, 0)):  # the three edges
        p, e = corners[i], corners[j] - corners[i]
        r = s - p
        bb, cc, dd, ff = _dot(d, e), _dot(e, e), _dot(d, r), _dot(e, r)
        den = cc - bb * bb
        par = den > 1e-12 * cc
        wq = np.clip(np.where(par, (ff - bb * dd) / np.where(par, den, 1.0), 0.0), 0.0, 1.0)
        te = wq * bb - dd
        back = te < 0
        te = np.maximum(te, 0.0)
        wq = np.where(back, np.clip(ff / np.where(cc > 0, cc, 1.0), 0.0, 1.0) * (cc > 0), wq)
        diff = r + te[..., None] * d - wq[..., None] * e
        de = _dot(diff, diff)
        take = de < d2
        d2 = np.where(take, de, d2)
        t = np.where(take, te, t)
        be = np.zeros(de.shape + (3,))
        be[..., i], be[..., j] = 1.0 - wq, wq
        bary = np.where(take[..., None], be, bary)
    return d2, t, bary


def closest_on_triangles(tv, start, direction, *, within: float | None = None,
                         chunk: int = 1 << 16, corner_ids=None):
    """For each ray the point of the triangles closest to it (module docstring).

    The first hit where the ray hits them, else the closest point (their edges, vertices or
    interiors). Pairs closer than 1e-12 x the triangles' extent count as hits (a ray through
    a shared edge); the first of them along the ray wins.

    Parameters
    ----------
    tv : (T, 3, 3) float
        Triangle corners (degenerate triangles -- segments, points -- are allowed).
    start, direction : (N, 3) float
        Rays ``start + t direction``, t >= 0 (direction need not be unit).
    within : float, optional, keyword-only
        Only the rays that come at least this close to the triangles are wanted: a ray whose
        closest pair (and no touching pair) is farther gets index -1 and zero barycentric
        coordinates -- its search stops as soon as that is certain -- and every other ray
        gets exactly its result without ``within``. To decide "hit within a tolerance" on
        the returned points, pass a slightly larger value (e.g. ``2 * tol``) so that the
        rounding of the caller's own distance cannot matter.
    chunk : int, keyword-only
        numpy path: rays are processed in blocks of about ``chunk`` ray-triangle pairs.
    corner_ids : (T, 3) int >= 0, optional, keyword-only
        Equal ids for equal corners (e.g. the mesh's vertex indices of ``tv``): shared
        corners are then projected once per ray (speed only; the answers are the same).

    Returns
    -------
    index : (N,) int
        The triangle holding the closest point (-1: farther than ``within``).
    bary : (N, 3) float
        Its barycentric coordinates in that triangle (corner order of ``tv``).
    """
    tv = np.asarray(tv, dtype=np.float64)
    dn = direction / np.linalg.norm(direction, axis=1, keepdims=True)
    n = len(start)
    index, bary = np.zeros(n, np.int64), np.zeros((n, 3))
    if n == 0 or len(tv) == 0:
        return index, bary
    flat = tv.reshape(-1, 3)
    eps2 = (1e-12 * float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))) ** 2
    step = max(1, chunk // len(tv))
    for lo in range(0, n, step):  # blocks of fibres, not single fibres
        sl = slice(lo, lo + step)
        d2, t, b = _ray_triangle_pairs(tv[None], start[sl, None], dn[sl, None])
        touch = d2 <= eps2
        first = np.argmin(np.where(touch, t, np.inf), axis=1)
        near = np.argmin(d2, axis=1)
        k = np.where(touch.any(axis=1), first, near)
        rows = np.arange(len(k))
        index[sl] = k
        bary[sl] = b[rows, k]
        if within is not None:
            far = ~touch.any(axis=1) & (d2[rows, near] > float(within) ** 2)
            index[sl][far] = -1
            bary[sl][far] = 0.0
    return index, bary
