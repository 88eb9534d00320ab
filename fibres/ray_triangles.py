"""Closest points between rays and a set of triangles, for the attachment filter's new
fibre ends (Kohout 2012 §3.4: the point of the attachment area's surface closest to the ray
that continues a fibre's last kept segment; `fibres.filtering`).

Ray/triangle hit: Moeller & Trumbore, "Fast, minimum storage ray-triangle intersection",
J. Graphics Tools 2(1), 1997. Closest points of a ray and a segment: Ericson, Real-Time
Collision Detection (2005), §5.1.9 (clamped segment-segment closest points), with the ray's
upper bound removed. Vectorised over rays x triangles in numpy; a numba-compiled twin of the
same formulas is used when numba is installed, which skips the pairs that exact lower bounds
(bounding sphere, bounding box and line distance seen along the ray) show cannot win and
evaluates the rest nearest bound first -- the same answers, ~2x faster on the bench areas.
A search restricted to rays that come within a distance (``within``) first looks for a
separating axis between the ray and the grown bounding boxes of blocks of triangles and of
the triangles in them (the separating axis theorem for a box and a line, e.g. Ericson 2005,
§5.3.3): a ray apart from all of them is -1 without its bounds and pairs (the filter's
template-direction rays that miss the area: ~2x faster on the bench areas).
"""
from __future__ import annotations

import numpy as np

from .attachment_area import region_triangles, regions_triangles   # the area's triangles

__all__ = ["region_triangles", "regions_triangles", "closest_on_triangles"]

_KERNELS = []


def _kernels():
    """(closest triangle point to each ray, corner bounds) compiled with numba, or None
    (then numpy)."""
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)


#: the compiled `_pair_loop` and `_across_distance_loop` (set by `_kernels`), called by
#: `_triangles_loop`
_pair = None
_across_distance = None
_apart = None

#: restricted searches (``within``): triangles per box of the separating-axis pre-test,
#: coarse and fine level (`_triangles_loop`); 0 turns the pre-test off
_HIT_BLOCKS = (32, 8)


def _apart_loop(w0, w1, w2, h0, h1, h2, d0, d1, d2, mrg):  # pragma: no cover - compiled
    """Whether the ray ``s + t d`` (t >= 0) and the box of centre ``c`` and half extents
    ``h`` are separated by more than ``mrg`` along an axis (``w = s - c``): one of the box's
    axes (the ray projects to [s, inf), (-inf, s] or s), the three axes ``d x e`` across the
    ray's line, or the ray's direction (the box behind the start). A separating axis proves
    the two apart (the converse is not needed: the caller then measures)."""
    if (d0 >= 0 and w0 > h0 + mrg) or (d0 <= 0 and w0 < -h0 - mrg):
        return True
    if (d1 >= 0 and w1 > h1 + mrg) or (d1 <= 0 and w1 < -h1 - mrg):
        return True
    if (d2 >= 0 and w2 > h2 + mrg) or (d2 <= 0 and w2 < -h2 - mrg):
        return True
    a0, a1, a2 = abs(d0), abs(d1), abs(d2)
    if abs(w1 * d2 - w2 * d1) > h1 * a2 + h2 * a1 + mrg:
        return True
    if abs(w2 * d0 - w0 * d2) > h0 * a2 + h2 * a0 + mrg:
        return True
    if abs(w0 * d1 - w1 * d0) > h0 * a1 + h1 * a0 + mrg:
        return True
    return (h0 * a0 + h1 * a1 + h2 * a2) - (w0 * d0 + w1 * d1 + w2 * d2) < -mrg


def _across_distance_loop(uv):  # pragma: no cover - compiled by numba
    """Distance from the origin to the 2D triangle ``uv`` (3, 2) (either orientation; 0
    inside): the distance from a line to a triangle, both seen along the line."""
    o0 = uv[0, 0] * uv[1, 1] - uv[0, 1] * uv[1, 0]     # orientations of (o, a, b) etc.
    o1 = uv[1, 0] * uv[2, 1] - uv[1, 1] * uv[2, 0]
    o2 = uv[2, 0] * uv[0, 1] - uv[2, 1] * uv[0, 0]
    if (o0 >= 0 and o1 >= 0 and o2 >= 0) or (o0 <= 0 and o1 <= 0 and o2 <= 0):
        return 0.0
    best = np.inf
    for i in range(3):  # the three edges
        j = i + 1 if i < 2 else 0
        pu, pv = uv[i, 0], uv[i, 1]
        eu, ev = uv[j, 0] - pu, uv[j, 1] - pv
        ee = eu * eu + ev * ev
        w = 0.0
        if ee > 0:
            w = min(max(-(pu * eu + pv * ev) / ee, 0.0), 1.0)
        x, y = pu + w * eu, pv + w * ev
        best = min(best, x * x + y * y)
    return np.sqrt(best)


def _pair_loop(k, s, d, tv, te1, te2, tnrm, tnn, tthr, tedge, tcc, bb3):  # pragma: no cover
    """Squared distance and ray parameter (d2, t) of the closest pair between the ray
    ``s + t d`` and triangle ``k``, its barycentric coordinates into ``bb3`` (3,): the
    formulas of `_ray_triangle_pairs` for one pair, with the triangle's constants (edges,
    normal, |n|^2, hit threshold, edge vectors and their squared lengths) precomputed."""
    e1x, e1y, e1z = te1[k, 0], te1[k, 1], te1[k, 2]
    e2x, e2y, e2z = te2[k, 0], te2[k, 1], te2[k, 2]
    nx, ny, nz = tnrm[k, 0], tnrm[k, 1], tnrm[k, 2]
    wx, wy, wz = s[0] - tv[k, 0, 0], s[1] - tv[k, 0, 1], s[2] - tv[k, 0, 2]
    nn = tnn[k]
    # hit (Moeller-Trumbore)
    px, py, pz = d[1] * e2z - d[2] * e2y, d[2] * e2x - d[0] * e2z, d[0] * e2y - d[1] * e2x
    det = e1x * px + e1y * py + e1z * pz
    d2, t = np.inf, 0.0
    if abs(det) > tthr[k]:
        inv = 1.0 / det
        u = (wx * px + wy * py + wz * pz) * inv
        qx, qy, qz = wy * e1z - wz * e1y, wz * e1x - wx * e1z, wx * e1y - wy * e1x
        v = (d[0] * qx + d[1] * qy + d[2] * qz) * inv
        th = (e2x * qx + e2y * qy + e2z * qz) * inv
        if u >= 0 and v >= 0 and u + v <= 1 and th >= 0:
            d2, t = 0.0, th
            bb3[0], bb3[1], bb3[2] = 1.0 - u - v, u, v
    # ray start against the interior
    if nn > 0:
        cx, cy, cz = wy * e2z - wz * e2y, wz * e2x - wx * e2z, wx * e2y - wy * e2x
        beta = (cx * nx + cy * ny + cz * nz) / nn
        cx, cy, cz = e1y * wz - e1z * wy, e1z * wx - e1x * wz, e1x * wy - e1y * wx
        gamma = (cx * nx + cy * ny + cz * nz) / nn
        height = wx * nx + wy * ny + wz * nz
        dp = height * height / nn
        if beta >= 0 and gamma >= 0 and beta + gamma <= 1 and dp < d2:
            d2, t = dp, 0.0
            bb3[0], bb3[1], bb3[2] = 1.0 - beta - gamma, beta, gamma
    # ray against the edges
    for i in range(3):
        j = (i + 1) % 3
        ex, ey, ez = tedge[k, i, 0], tedge[k, i, 1], tedge[k, i, 2]
        rx, ry, rz = s[0] - tv[k, i, 0], s[1] - tv[k, i, 1], s[2] - tv[k, i, 2]
        bb = d[0] * ex + d[1] * ey + d[2] * ez
        cc = tcc[k, i]
        dd = d[0] * rx + d[1] * ry + d[2] * rz
        ff = ex * rx + ey * ry + ez * rz
        den = cc - bb * bb
        wq = (ff - bb * dd) / den if den > 1e-12 * cc else 0.0
        wq = min(max(wq, 0.0), 1.0)
        te = wq * bb - dd
        if te < 0:
            te = 0.0
            wq = min(max(ff / cc, 0.0), 1.0) if cc > 0 else 0.0
        fx = rx + te * d[0] - wq * ex
        fy = ry + te * d[1] - wq * ey
        fz = rz + te * d[2] - wq * ez
        de = fx * fx + fy * fy + fz * fz
        if de < d2:
            d2, t = de, te
            bb3[0], bb3[1], bb3[2] = 0.0, 0.0, 0.0
            bb3[i], bb3[j] = 1.0 - wq, wq
    return d2, t


def _triangles_loop(tv, start, dn, eps2, slack, within2, vid, coarse,
                    fine):  # pragma: no cover - compiled by numba
    """`closest_on_triangles` for triangles (T, 3, 3), starts (N, 3), unit directions
    (N, 3): `_pair_loop` for the pairs that can matter, and the selection of the array
    version (the first touching pair along the ray, else the nearest).

    The selection is the lexicographic minimum of (t, rank) over the touching pairs, else of
    (d2, rank), where rank orders the triangles as the plain loop visits them (the most
    promising one first, then all in index order) -- so it does not depend on which pairs
    are evaluated, as long as every pair that could win is. Three exact lower bounds of a
    pair's distance skip the others (farther than the best pair so far and than the
    touching tolerance, with a 1e-9 relative margin): the distance from the ray to the
    triangle's bounding sphere (centre = corner mean, radius = farthest corner); the
    distance from the ray to the triangle's bounding box in a frame along the ray
    (``sqrt(du^2 + dv^2 + max(0, -t_max)^2)``); and the distance from the ray's line to the
    triangle, both projected along the ray (`_across_distance_loop`) -- the last two less
    ``slack`` for the rounding of the frame coordinates. The remaining triangles are
    evaluated in increasing order of the box bound, until the next bound exceeds the best
    distance. ``within2`` (squared; inf for none) caps the best distance of the pruning: a
    ray farther than that from every triangle is returned as index -1 (at once when the
    nearest sphere bound already shows it). ``vid`` (T, 3)
    numbers the distinct corners (equal ids: equal points): each is projected into a
    ray's frame once for the box bounds (the triangles of a surface share them).

    A restricted search (``within2`` finite) first tries to show the ray apart from every
    triangle: the bounding boxes of blocks of ``coarse`` consecutive triangles, of
    ``fine`` ones within them and of each triangle within those, grown by the search
    radius ``max(within, touching tolerance)`` (1e-6 relative margin), are tested for a
    separating axis (`_apart_loop`, by more than the sphere test's rounding margin
    ``100 slack``); when every triangle's box is apart, every triangle is farther than the
    radius, so the ray is -1 -- the answer of the bounds and pairs below, without them
    (and without the triangles' constants when that holds for every ray; ``coarse`` 0: no
    pre-test)."""
    n_rays, n_tri = start.shape[0], tv.shape[0]
    index = np.zeros(n_rays, np.int64)
    bary = np.zeros((n_rays, 3))
    s, d, bb3 = np.empty(3), np.empty(3), np.empty(3)
    p1, p2 = np.empty(3), np.empty(3)
    lower = np.empty(n_tri)
    cand_k = np.empty(n_tri, np.int64)
    cand_lb = np.empty(n_tri)
    uv = np.empty((3, 2))                                   # corners across the ray
    # restricted search: the boxes (centre, half extents grown by the search radius) of
    # the coarse blocks, the fine blocks and the triangles
    n_box = n_tri if within2 < np.inf and coarse > 0 else 0
    grow = np.sqrt(max(within2, eps2)) * (1.0 + 1e-6)
    box_c, box_h = np.empty((3, n_box, 3)), np.empty((3, n_box, 3))
    for level in range(3 if n_box else 0):
        size = coarse if level == 0 else (fine if level == 1 else 1)
        for b in range((n_tri + size - 1) // size):
            for c in range(3):
                lo, hi = np.inf, -np.inf
                for k in range(b * size, min(b * size + size, n_tri)):
                    for i in range(3):
                        lo, hi = min(lo, tv[k, i, c]), max(hi, tv[k, i, c])
                box_c[level, b, c] = (lo + hi) * 0.5
                box_h[level, b, c] = (hi - lo) * 0.5 + grow
    apart = np.zeros(n_rays, np.bool_)
    n_apart = 0
    for n in range(n_rays if n_box else 0):  # every triangle's box apart: -1 (docstring)
        s0, s1, s2 = start[n, 0], start[n, 1], start[n, 2]
        d0, d1, d2_ = dn[n, 0], dn[n, 1], dn[n, 2]
        mrg = 100.0 * slack[n]
        near = False
        for b0 in range((n_tri + coarse - 1) // coarse):
            if _apart(s0 - box_c[0, b0, 0], s1 - box_c[0, b0, 1], s2 - box_c[0, b0, 2],
                      box_h[0, b0, 0], box_h[0, b0, 1], box_h[0, b0, 2], d0, d1, d2_, mrg):
                continue
            k_end = min(b0 * coarse + coarse, n_tri)
            for b1 in range(b0 * coarse // fine, (k_end + fine - 1) // fine):
                if _apart(s0 - box_c[1, b1, 0], s1 - box_c[1, b1, 1],
                          s2 - box_c[1, b1, 2], box_h[1, b1, 0], box_h[1, b1, 1],
                          box_h[1, b1, 2], d0, d1, d2_, mrg):
                    continue
                for k in range(b1 * fine, min(b1 * fine + fine, k_end)):
                    if not _apart(s0 - box_c[2, k, 0], s1 - box_c[2, k, 1],
                                  s2 - box_c[2, k, 2], box_h[2, k, 0], box_h[2, k, 1],
                                  box_h[2, k, 2], d0, d1, d2_, mrg):
                        near = True
                        break
                if near:
                    break
            if near:
                break
        if not near:
            index[n] = -1
            apart[n] = True
            n_apart += 1
    if n_apart == n_rays:  # every ray: no triangle constants needed
        return index, bary
    cs = np.empty((3, 3, n_tri))                 # corner, coordinate, triangle
    for k in range(n_tri):
        for i in range(3):
            for c in range(3):
                cs[i, c, k] = tv[k, i, c]
    n_id = 0
    for k in range(n_tri):
        for i in range(3):
            n_id = max(n_id, vid[k, i] + 1)
    # the distinct corners (equal ids: equal points), numbered compactly: each ray
    # projects all of them into its frame in one vectorised pass for the box bounds
    cmap = np.full(n_id, -1, np.int64)
    cidx = np.empty((n_tri, 3), np.int64)
    n_u = 0
    for k in range(n_tri):
        for i in range(3):
            q = vid[k, i]
            if cmap[q] < 0:
                cmap[q] = n_u
                n_u += 1
            cidx[k, i] = cmap[q]
    ux, uy, uz = np.empty(n_u), np.empty(n_u), np.empty(n_u)
    for k in range(n_tri):
        for i in range(3):
            ux[cidx[k, i]], uy[cidx[k, i]], uz[cidx[k, i]] = tv[k, i, 0], tv[k, i, 1], tv[k, i, 2]
    pu_all, pv_all, pt_all = np.empty(n_u), np.empty(n_u), np.empty(n_u)
    # per-triangle constants of the tests, computed once (the same operations as per pair)
    te1, te2, tnrm = np.empty((n_tri, 3)), np.empty((n_tri, 3)), np.empty((n_tri, 3))
    tnn, tthr = np.empty(n_tri), np.empty(n_tri)
    tedge, tcc = np.empty((n_tri, 3, 3)), np.empty((n_tri, 3))
    ox, oy, oz, radius = np.empty(n_tri), np.empty(n_tri), np.empty(n_tri), np.empty(n_tri)
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
        # bounding sphere (numpy's mean over the corners and norm over x, y, z)
        ox[k] = (tv[k, 0, 0] + tv[k, 1, 0] + tv[k, 2, 0]) / 3.0
        oy[k] = (tv[k, 0, 1] + tv[k, 1, 1] + tv[k, 2, 1]) / 3.0
        oz[k] = (tv[k, 0, 2] + tv[k, 1, 2] + tv[k, 2, 2]) / 3.0
        far = 0.0
        for i in range(3):
            qx, qy, qz = tv[k, i, 0] - ox[k], tv[k, i, 1] - oy[k], tv[k, i, 2] - oz[k]
            far = max(far, np.sqrt(qx * qx + qy * qy + qz * qz))
        radius[k] = far * (1 + 1e-12)
    for n in range(n_rays):
        if apart[n]:
            continue
        for c in range(3):
            s[c], d[c] = start[n, c], dn[n, c]
        s0, s1, s2, d0, d1, d2_ = s[0], s[1], s[2], d[0], d[1], d[2]
        for k in range(n_tri):  # lower bounds: the sphere's distance from the ray
            rx, ry, rz = ox[k] - s0, oy[k] - s1, oz[k] - s2
            ta = max(rx * d0 + ry * d1 + rz * d2_, 0.0)
            rx, ry, rz = rx - ta * d0, ry - ta * d1, rz - ta * d2_
            lower[k] = np.sqrt(rx * rx + ry * ry + rz * rz) - radius[k]
        # k0 = np.argmin(lower) (finite: the first minimum), its value from four
        # independent running minima (a single chain of compares is latency-bound)
        m0 = m1 = m2 = m3 = np.inf
        k = 0
        while k + 4 <= n_tri:
            m0, m1 = min(m0, lower[k]), min(m1, lower[k + 1])
            m2, m3 = min(m2, lower[k + 2]), min(m3, lower[k + 3])
            k += 4
        while k < n_tri:
            m0 = min(m0, lower[k])
            k += 1
        m0 = min(min(m0, m1), min(m2, m3))
        k0 = 0
        while k0 < n_tri and lower[k0] != m0:
            k0 += 1
        if k0 == n_tri:                               # not finite: argmin's NaN rule
            k0 = np.argmin(lower)
        # every triangle farther than ``within`` (and the touching tolerance) by its sphere
        # bound, less 1e-12 of the coordinates' size for rounding: index -1, as the
        # evaluation of k0 and the pruning of the others would find
        far = m0 - 100.0 * slack[n]
        if far > 0 and far * far > max(within2, eps2) * (1.0 + 1e-9):
            index[n] = -1
            continue
        # (p1, p2, d): an orthonormal frame along the ray
        ax = 0 if abs(d0) <= abs(d1) and abs(d0) <= abs(d2_) else (
            1 if abs(d1) <= abs(d2_) else 2)
        for c in range(3):
            p1[c] = -d[ax] * d[c]
        p1[ax] += 1.0
        norm = np.sqrt(p1[0] * p1[0] + p1[1] * p1[1] + p1[2] * p1[2])
        for c in range(3):
            p1[c] /= norm
        p2[0] = d1 * p1[2] - d2_ * p1[1]
        p2[1] = d2_ * p1[0] - d0 * p1[2]
        p2[2] = d0 * p1[1] - d1 * p1[0]
        # the most promising triangle first (rank -1)
        d2, t = _pair(k0, s, d, tv, te1, te2, tnrm, tnn, tthr, tedge, tcc, bb3)
        best_d2, k_near, r_near = d2, k0, -1
        b_near = bb3.copy()
        best_touch, k_touch, r_touch = np.inf, -1, n_tri
        b_touch = np.zeros(3)
        if d2 <= eps2:
            best_touch, k_touch, r_touch = t, k0, -1
            b_touch[:] = bb3
        # candidates: the triangles neither bound rules out (rank = index)
        thr = max(min(best_d2, within2), eps2) * (1.0 + 1e-9)
        e0, e1, e2 = p1[0], p1[1], p1[2]
        f0, f1, f2 = p2[0], p2[1], p2[2]
        for q in range(n_u):  # every corner in the ray's frame (u, v, t)
            qx, qy, qz = ux[q] - s0, uy[q] - s1, uz[q] - s2
            pu_all[q] = qx * e0 + qy * e1 + qz * e2
            pv_all[q] = qx * f0 + qy * f1 + qz * f2
            pt_all[q] = qx * d0 + qy * d1 + qz * d2_
        n_c = 0
        for k in range(n_tri):
            lb = lower[k]
            if k == k0 or (lb > 0 and lb * lb > thr):
                continue
            u_lo, u_hi, v_lo, v_hi, t_hi = np.inf, -np.inf, np.inf, -np.inf, -np.inf
            for i in range(3):
                q = cidx[k, i]
                pu, pv = pu_all[q], pv_all[q]
                u_lo, u_hi = min(u_lo, pu), max(u_hi, pu)
                v_lo, v_hi = min(v_lo, pv), max(v_hi, pv)
                t_hi = max(t_hi, pt_all[q])
            gu = max(max(u_lo, -u_hi), 0.0)
            gv = max(max(v_lo, -v_hi), 0.0)
            gt = max(-t_hi, 0.0)
            box = np.sqrt(gu * gu + gv * gv + gt * gt) - slack[n]
            if box > 0 and box * box > thr:
                continue
            cand_k[n_c] = k
            cand_lb[n_c] = box * box if box > 0 else 0.0
            n_c += 1
        # evaluate by increasing box bound while it can beat the best
        while n_c > 0:
            m = 0
            for c in range(1, n_c):
                if cand_lb[c] < cand_lb[m]:
                    m = c
            k = cand_k[m]
            if cand_lb[m] > max(min(best_d2, within2), eps2) * (1.0 + 1e-9):
                break
            n_c -= 1
            cand_k[m], cand_lb[m] = cand_k[n_c], cand_lb[n_c]
            # the line's distance to the triangle: the origin's to the corners across it
            for i in range(3):
                qx, qy, qz = cs[i, 0, k] - s0, cs[i, 1, k] - s1, cs[i, 2, k] - s2
                uv[i, 0] = qx * p1[0] + qy * p1[1] + qz * p1[2]
                uv[i, 1] = qx * p2[0] + qy * p2[1] + qz * p2[2]
            lb = _across_distance(uv) - slack[n]
            if lb > 0 and lb * lb > max(min(best_d2, within2), eps2) * (1.0 + 1e-9):
                continue
            d2, t = _pair(k, s, d, tv, te1, te2, tnrm, tnn, tthr, tedge, tcc, bb3)
            if d2 <= eps2 and (t < best_touch or (t == best_touch and k < r_touch)):
                best_touch, k_touch, r_touch = t, k, k
                b_touch[:] = bb3
            if d2 < best_d2 or (d2 == best_d2 and k < r_near):
                best_d2, k_near, r_near = d2, k, k
                b_near[:] = bb3
        if k_touch >= 0:
            index[n] = k_touch
            bary[n] = b_touch
        elif best_d2 <= within2:
            index[n] = k_near
            bary[n] = b_near
        else:
            index[n] = -1
    return index, bary


def _bounds_loop(tv):  # pragma: no cover - compiled by numba
    """Per-coordinate minimum and maximum (3,) of the corners of (T, 3, 3) triangles."""
    lo = tv[0, 0].copy()
    hi = tv[0, 0].copy()
    for k in range(tv.shape[0]):
        for i in range(3):
            for c in range(3):
                lo[c] = min(lo[c], tv[k, i, c])
                hi[c] = max(hi[c], tv[k, i, c])
    return lo, hi


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
    kernels = _kernels()
    if kernels is not None:
        tv = np.ascontiguousarray(tv)
        lo, hi = kernels[1](tv)                       # flat.min(axis=0), flat.max(axis=0)
        eps2 = (1e-12 * float(np.linalg.norm(hi - lo))) ** 2
        start = np.ascontiguousarray(start, dtype=float)
        # rounding bound of the ray-frame coordinates: 1e-14 of the coordinates' size
        slack = 1e-14 * (np.abs(start).max(axis=1) + max(np.abs(lo).max(), np.abs(hi).max()))
        vid = (np.arange(3 * len(tv), dtype=np.int64).reshape(-1, 3) if corner_ids is None
               else np.ascontiguousarray(corner_ids, dtype=np.int64))
        coarse, fine = _HIT_BLOCKS if _HIT_BLOCKS[0] > 0 else (0, 1)
        return kernels[0](tv, start, np.ascontiguousarray(dn, dtype=float), eps2, slack,
                          np.inf if within is None else float(within) ** 2, vid, coarse, fine)
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
