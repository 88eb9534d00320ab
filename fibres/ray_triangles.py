"""Closest points between rays and a set of triangles, for the attachment filter's new
fibre ends (Kohout 2012 §3.4: the point of the attachment area's surface closest to the ray
that continues a fibre's last kept segment; `fibres.filtering`).

Ray/triangle hit: Moeller & Trumbore, "Fast, minimum storage ray-triangle intersection",
J. Graphics Tools 2(1), 1997. Closest points of a ray and a segment: Ericson, Real-Time
Collision Detection (2005), §5.1.9 (clamped segment-segment closest points), with the ray's
upper bound removed. Vectorised over rays x triangles in numpy; a numba-compiled twin of the
same formulas (with bounding-sphere pruning) is used when numba is installed.
"""
from __future__ import annotations

import numpy as np

__all__ = ["region_triangles", "closest_on_triangles"]

_KERNELS = []


def _kernels():
    """(closest triangle point to each ray, faces with all corners marked) compiled with
    numba, or None (then numpy)."""
    if not _KERNELS:
        try:
            import numba
        except ImportError:                                     # pragma: no cover - optional
            _KERNELS.append(None)
        else:
            jit = numba.njit(cache=True, nogil=True)
            _KERNELS.append((jit(_triangles_loop), jit(_full_faces_loop)))
    return _KERNELS[0]


def _triangles_loop(tv, centre, radius, start, dn, eps2):  # pragma: no cover - numba
    """`closest_on_triangles` for triangles (T, 3, 3), starts (N, 3), unit directions
    (N, 3): the formulas of `_ray_triangle_pairs`, one pair at a time, and the same
    selection (first touching pair along the ray, else the nearest). A triangle whose
    bounding sphere (centre (T, 3), radius (T,)) is farther from the ray than the best
    distance so far (and than the touching tolerance) is skipped: it can neither touch
    the ray nor be nearer."""
    n_rays, n_tri = start.shape[0], tv.shape[0]
    index = np.zeros(n_rays, np.int64)
    bary = np.zeros((n_rays, 3))
    s, d, w, e1, e2, nrm = (np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3),
                            np.empty(3))
    r, e, diff, bb3 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    lower = np.empty(n_tri)
    # per-triangle constants of the tests, computed once (the same operations as per pair)
    te1, te2, tnrm = np.empty((n_tri, 3)), np.empty((n_tri, 3)), np.empty((n_tri, 3))
    tnn, tthr = np.empty(n_tri), np.empty(n_tri)
    tedge, tcc = np.empty((n_tri, 3, 3)), np.empty((n_tri, 3))
    for k in range(n_tri):
        for c in range(3):
            te1[k, c] = tv[k, 1, c] - tv[k, 0, c]
            te2[k, c] = tv[k, 2, c] - tv[k, 0, c]
        tnrm[k, 0] = te1[k, 1] * te2[k, 2] - te1[k, 2] * te2[k, 1]
        tnrm[k, 1] = te1[k, 2] * te2[k, 0] - te1[k, 0] * te2[k, 2]
        tnrm[k, 2] = te1[k, 0] * te2[k, 1] - te1[k, 1] * te2[k, 0]
        tnn[k] = tnrm[k, 0] * tnrm[k, 0] + tnrm[k, 1] * tnrm[k, 1] + tnrm[k, 2] * tnrm[k, 2]
        tthr[k] = 1e-12 * np.sqrt(tnn[k])
        for i in range(3):
            j = (i + 1) % 3
            for c in range(3):
                tedge[k, i, c] = tv[k, j, c] - tv[k, i, c]
            tcc[k, i] = (tedge[k, i, 0] * tedge[k, i, 0] + tedge[k, i, 1] * tedge[k, i, 1]
                         + tedge[k, i, 2] * tedge[k, i, 2])
    for n in range(n_rays):
        for c in range(3):
            s[c], d[c] = start[n, c], dn[n, c]
        best_touch, best_d2 = np.inf, np.inf
        k_touch, k_near = -1, 0
        b_touch, b_near = np.zeros(3), np.zeros(3)
        for k in range(n_tri):  # lower bounds: the sphere's distance from the ray
            rx, ry, rz = centre[k, 0] - s[0], centre[k, 1] - s[1], centre[k, 2] - s[2]
            ta = max(rx * d[0] + ry * d[1] + rz * d[2], 0.0)
            rx, ry, rz = rx - ta * d[0], ry - ta * d[1], rz - ta * d[2]
            lower[k] = np.sqrt(rx * rx + ry * ry + rz * rz) - radius[k]
        k0 = np.argmin(lower)
        for m in range(n_tri + 1):  # the most promising triangle first, then all in order
            k = k0 if m == 0 else m - 1
            if m > 0 and k == k0:
                continue
            lb = lower[k]
            if lb > 0 and lb * lb > max(best_d2, eps2) * (1.0 + 1e-9):
                continue
            for c in range(3):
                e1[c], e2[c], nrm[c] = te1[k, c], te2[k, c], tnrm[k, c]
                w[c] = s[c] - tv[k, 0, c]
            nn = tnn[k]
            # hit (Moeller-Trumbore)
            px, py, pz = d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], \
                d[0] * e2[1] - d[1] * e2[0]
            det = e1[0] * px + e1[1] * py + e1[2] * pz
            d2, t = np.inf, 0.0
            if abs(det) > tthr[k]:
                inv = 1.0 / det
                u = (w[0] * px + w[1] * py + w[2] * pz) * inv
                qx, qy, qz = w[1] * e1[2] - w[2] * e1[1], w[2] * e1[0] - w[0] * e1[2], \
                    w[0] * e1[1] - w[1] * e1[0]
                v = (d[0] * qx + d[1] * qy + d[2] * qz) * inv
                th = (e2[0] * qx + e2[1] * qy + e2[2] * qz) * inv
                if u >= 0 and v >= 0 and u + v <= 1 and th >= 0:
                    d2, t = 0.0, th
                    bb3[0], bb3[1], bb3[2] = 1.0 - u - v, u, v
            # ray start against the interior
            if nn > 0:
                cx, cy, cz = w[1] * e2[2] - w[2] * e2[1], w[2] * e2[0] - w[0] * e2[2], \
                    w[0] * e2[1] - w[1] * e2[0]
                beta = (cx * nrm[0] + cy * nrm[1] + cz * nrm[2]) / nn
                cx, cy, cz = e1[1] * w[2] - e1[2] * w[1], e1[2] * w[0] - e1[0] * w[2], \
                    e1[0] * w[1] - e1[1] * w[0]
                gamma = (cx * nrm[0] + cy * nrm[1] + cz * nrm[2]) / nn
                height = w[0] * nrm[0] + w[1] * nrm[1] + w[2] * nrm[2]
                dp = height * height / nn
                if beta >= 0 and gamma >= 0 and beta + gamma <= 1 and dp < d2:
                    d2, t = dp, 0.0
                    bb3[0], bb3[1], bb3[2] = 1.0 - beta - gamma, beta, gamma
            # ray against the edges
            for i in range(3):
                j = (i + 1) % 3
                for c in range(3):
                    e[c] = tedge[k, i, c]
                    r[c] = s[c] - tv[k, i, c]
                bb = d[0] * e[0] + d[1] * e[1] + d[2] * e[2]
                cc = tcc[k, i]
                dd = d[0] * r[0] + d[1] * r[1] + d[2] * r[2]
                ff = e[0] * r[0] + e[1] * r[1] + e[2] * r[2]
                den = cc - bb * bb
                wq = (ff - bb * dd) / den if den > 1e-12 * cc else 0.0
                wq = min(max(wq, 0.0), 1.0)
                te = wq * bb - dd
                if te < 0:
                    te = 0.0
                    wq = min(max(ff / cc, 0.0), 1.0) if cc > 0 else 0.0
                de = 0.0
                for c in range(3):
                    diff[c] = r[c] + te * d[c] - wq * e[c]
                    de += diff[c] * diff[c]
                if de < d2:
                    d2, t = de, te
                    bb3[0], bb3[1], bb3[2] = 0.0, 0.0, 0.0
                    bb3[i], bb3[j] = 1.0 - wq, wq
            if d2 <= eps2 and t < best_touch:
                best_touch, k_touch = t, k
                b_touch[:] = bb3
            if d2 < best_d2:
                best_d2, k_near = d2, k
                b_near[:] = bb3
        if k_touch >= 0:
            index[n] = k_touch
            bary[n] = b_touch
        else:
            index[n] = k_near
            bary[n] = b_near
    return index, bary


def _full_faces_loop(faces, inside):  # pragma: no cover - compiled by numba
    """Whether all three corners of each face (T, 3) are marked in ``inside`` (V,)."""
    out = np.zeros(faces.shape[0], np.bool_)
    for t in range(faces.shape[0]):
        out[t] = inside[faces[t, 0]] and inside[faces[t, 1]] and inside[faces[t, 2]]
    return out


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
    inside = np.zeros(n_vertices, bool)
    inside[region] = True
    f0, f1, f2 = faces[:, 0], faces[:, 1], faces[:, 2]
    kernels = _kernels()
    if kernels is not None:
        full = np.flatnonzero(kernels[1](faces, inside))
    else:  # column by column (faces may be a strided view; a (T, 3) gather is ~6x slower)
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


def closest_on_triangles(tv, start, direction, *, chunk: int = 1 << 16):
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
    chunk : int, keyword-only
        numpy path: rays are processed in blocks of about ``chunk`` ray-triangle pairs.

    Returns
    -------
    index : (N,) int
        The triangle holding the closest point.
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
    kernels = _kernels()
    if kernels is not None:
        centre = tv.mean(axis=1)
        radius = np.linalg.norm(tv - centre[:, None], axis=2).max(axis=1) * (1 + 1e-12)
        return kernels[0](np.ascontiguousarray(tv), centre, radius,
                          np.ascontiguousarray(start, dtype=float),
                          np.ascontiguousarray(dn, dtype=float), eps2)
    step = max(1, chunk // len(tv))
    for lo in range(0, n, step):  # blocks of fibres, not single fibres
        sl = slice(lo, lo + step)
        d2, t, b = _ray_triangle_pairs(tv[None], start[sl, None], dn[sl, None])
        touch = d2 <= eps2
        first = np.argmin(np.where(touch, t, np.inf), axis=1)
        near = np.argmin(d2, axis=1)
        k = np.where(touch.any(axis=1), first, near)
        index[sl] = k
        bary[sl] = b[np.arange(len(k)), k]
    return index, bary
