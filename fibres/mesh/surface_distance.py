"""Signed distance to a closed triangle surface, soft-blended over the nearest triangles.

For `fibres.finishing.containment` (and tests): exact point-triangle distances (Ericson, Real-Time
Collision Detection 2005, §5.1.5, closest point on a triangle by its Voronoi regions), blended
over the nearest triangles with soft-min weights ``w_t = exp(-(d_t - d_min) / tau)``, which
keeps distance and direction continuous where two walls are equally near (the medial surface
of a concave valley, where the single closest triangle jumps from one wall to the other):

- distance ``D = sum w d / sum w``;
- sign of ``sum w (x - c_t) . n_t`` (c_t the closest point of triangle t, n_t its unit outward
  normal): the pseudo-normal test of Baerentzen & Aanaes (IEEE TVCG 11(3), 2005) with unit
  face weights -- at an edge or a vertex all faces sharing it tie and vote together;
- outward direction ``n = normalise(sign sum w (x - c_t) + tau sum w n_t)`` (the shortest
  path's direction, the face normal for a point on the surface).

Weights fade to exactly 0 between ``delta = (KAPPA - 1) tau`` and ``KAPPA tau`` (smoothstep),
so only triangles within ``d_min + KAPPA tau`` count.

Search (numpy and scipy, no compiled code). The triangles' centroids go into a k-d tree
(``scipy.spatial.cKDTree``) with each triangle's bounding radius r_t about its centroid
(R = max r_t): a triangle within distance d of a point has its centroid within d + R of it.
For each point: the exact distance d0 to the triangle of its nearest centroid bounds the
nearest distance from above, so the centroids within ``min(d0, reach) + R`` hold every nearest
triangle; their exact distances give d_min and the tie set. Every point is first classified
by ray parity (`SurfaceGrid.inside`: a uniform 2-d grid of the triangles seen along the ray;
the unit-weight vote of the nearest triangles can be wrong at a mesh vertex). An inside point
deeper than ``watch`` gets ``s = -inf`` and is not measured further (deeper by the centroid
bound ``dc - R > watch`` before any search, else by d_min); every other point within `reach`
gathers the centroids within
``min(d_min + KAPPA tau, reach) + R`` and is blended over them. The candidate pairs are
flattened (point, triangle) and measured at once by
`fibres.mesh.closest_point.closest_points_on_triangles`; the per-point sums of the blend are
``np.bincount`` over the point index. A point whose nearest centroid is farther than
``reach + R`` has no triangle within `reach`: ``s = -inf`` at the cost of one tree query.
"""
from __future__ import annotations

from itertools import chain

import numpy as np
from scipy.spatial import cKDTree

from .closest_point import closest_points_on_triangles

__all__ = ["SurfaceGrid", "surface_distance", "KAPPA"]

#: triangles farther than d_min + KAPPA tau get no weight in the blend
KAPPA = 8.0
#: ``offset`` mode: the normal offset within OFFSET_NEAR tau of the surface, the signed
#: distance beyond OFFSET_FAR tau, smoothstep between (the blend's vote, which signs the
#: distance, and the exact inside test disagree only within ~0.9 tau: tests)
OFFSET_NEAR, OFFSET_FAR = 2.0, 4.0


def _unit_rows(x):
    norm = np.sqrt(np.einsum("ij,ij->i", x, x))[:, None]
    return np.where(norm > 0, x / np.where(norm > 0, norm, 1.0), x)


#: the direction of the parity rays of `SurfaceGrid.inside` (generic: no mesh edge is parallel
#: to it by construction of a muscle scan)
RAY = np.array([0.8660254037844386, 0.3535533905932738, 0.3535533905932738])


def _ray_basis():
    """Rows: RAY and two unit vectors completing it to a right-handed orthonormal frame."""
    u = RAY / np.linalg.norm(RAY)
    v = np.cross(u, [0.0, 0.0, 1.0])
    v /= np.linalg.norm(v)
    return np.stack([u, v, np.cross(u, v)])


def _ray_grid(a, b, c):
    """The triangles (a, b, c) in the ray frame (`_ray_basis`) and binned by their (y, z)
    bounding boxes: (basis, corners (T, 3, 3), grid origin (2,), cell, dims (2,), CSR start
    (cells + 1,), triangle items). Cells about twice the median (y, z) extent of a triangle,
    at most ~4 cells per triangle in all."""
    basis = _ray_basis()
    corners = np.stack([a, b, c], 1) @ basis.T                         # (T, 3, 3)
    yz = corners[..., 1:]
    tlo, thi = yz.min(axis=1), yz.max(axis=1)                            # (T, 2)
    lo, hi = tlo.min(axis=0), thi.max(axis=0)
    span = np.maximum(hi - lo, 1e-300)
    cell = max(2.0 * float(np.median((thi - tlo).max(axis=1))) if len(yz) else 1.0,
               float(np.sqrt(span[0] * span[1] / (4.0 * len(yz) + 1.0))), 1e-300)
    dims = (np.floor(span / cell).astype(np.int64) + 1)
    i0 = np.clip(((tlo - lo) / cell).astype(np.int64), 0, dims - 1)
    i1 = np.clip(((thi - lo) / cell).astype(np.int64), 0, dims - 1)
    ni, nj = i1[:, 0] - i0[:, 0] + 1, i1[:, 1] - i0[:, 1] + 1
    n = ni * nj
    tri = np.repeat(np.arange(len(yz)), n)
    k = np.arange(len(tri)) - np.repeat(np.cumsum(n) - n, n)
    ci = i0[tri, 0] + k // nj[tri]
    cj = i0[tri, 1] + k % nj[tri]
    key = ci * dims[1] + cj
    order = np.argsort(key, kind="stable")
    start = np.zeros(int(dims[0] * dims[1]) + 1, np.int64)
    np.cumsum(np.bincount(key, minlength=int(dims[0] * dims[1])), out=start[1:])
    return basis, corners, lo, cell, dims, start, tri[order]


def _pairs(tree, x, radius):
    """(point index, triangle index) of every centroid within radius[i] of x[i], grouped by
    point in increasing order."""
    if len(x) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    lists = tree.query_ball_point(x, radius, return_sorted=False)
    counts = np.fromiter(map(len, lists), np.int64, len(lists))
    tri = np.fromiter(chain.from_iterable(lists), np.int64, int(counts.sum()))
    return np.repeat(np.arange(len(x)), counts), tri


class SurfaceGrid:
    """A closed surface prepared for signed-distance queries (module docstring): a k-d tree of
    its triangles' centroids, their bounding radii and unit outward normals.

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (T, 3) int
        Closed, consistently and outward wound.
    reach : float
        Points with no triangle within this distance get ``s = -inf``.
    cell, labelled, mean_edge, bounds
        Accepted for the callers of the earlier grid search; unused (the k-d tree needs no
        cell size). ``cell`` is None.
    """

    def __init__(self, vertices, faces, *, reach: float, cell: float | None = None,
                 labelled: bool = True, mean_edge: float | None = None, bounds=None):
        self.vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.reach = float(reach)
        self.cell = None
        tri = self.vertices[self.faces]                                       # (T, 3, 3)
        self.a, self.b, self.c = (np.ascontiguousarray(tri[:, k]) for k in range(3))
        self.centre = tri.mean(axis=1)
        self.radius_max = float(np.sqrt(((tri - self.centre[:, None]) ** 2).sum(-1)).max()) \
            if len(tri) else 0.0
        self.nrm = _unit_rows(np.cross(self.b - self.a, self.c - self.a))
        self.tree = cKDTree(self.centre)
        self._ray = None

    def inside(self, points):
        """Whether each point (n, 3) is inside the closed surface, by ray parity: the ray from
        the point along a fixed generic direction (`RAY`; ties on edges have measure zero)
        crosses the surface an odd number of times. In the frame whose x axis is the ray, the
        triangles are binned by their (y, z) bounding boxes in a uniform 2-d grid (CSR arrays);
        a point meets the triangles of its own cell, and each is crossed when the point's
        (y, z) lies in its projection (three edge functions of one sign) beyond the point
        along x."""
        x = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        if self._ray is None:
            self._ray = _ray_grid(self.a, self.b, self.c)
        basis, corners, lo, cell, dims, start, items = self._ray
        p = x @ basis.T
        cy = np.clip(((p[:, 1] - lo[0]) / cell).astype(np.int64), 0, dims[0] - 1)
        cz = np.clip(((p[:, 2] - lo[1]) / cell).astype(np.int64), 0, dims[1] - 1)
        key = cy * dims[1] + cz
        first, counts = start[key], start[key + 1] - start[key]
        pi = np.repeat(np.arange(len(p)), counts)
        local = np.arange(len(pi)) - np.repeat(np.cumsum(counts) - counts, counts)
        ti = items[first[pi] + local]
        c = corners[ti]
        py, pz = p[pi, 1], p[pi, 2]
        y, z = c[..., 1], c[..., 2]
        # edge functions of the projected triangle at the point (signed double areas)
        e = [(y[:, (k + 1) % 3] - y[:, k]) * (pz - z[:, k])
             - (z[:, (k + 1) % 3] - z[:, k]) * (py - y[:, k]) for k in range(3)]
        area = e[0] + e[1] + e[2]
        hit = ((e[0] > 0) & (e[1] > 0) & (e[2] > 0)) | ((e[0] < 0) & (e[1] < 0) & (e[2] < 0))
        with np.errstate(divide="ignore", invalid="ignore"):
            xs = (e[1] * c[:, 0, 0] + e[2] * c[:, 1, 0] + e[0] * c[:, 2, 0]) / area
        hit &= xs > p[pi, 0]
        return np.bincount(pi[hit], minlength=len(p)) % 2 == 1

    def _measure(self, x, radius):
        """Every (point, triangle) pair with the centroid within radius of the point: point
        index, triangle index, exact distance, point minus closest point."""
        pi, ti = _pairs(self.tree, x, radius)
        diff = x[pi] - closest_points_on_triangles(x[pi], self.a[ti], self.b[ti], self.c[ti])
        return pi, ti, np.sqrt(np.einsum("ij,ij->i", diff, diff)), diff

    def signed_distance(self, points, *, tau: float, watch: float | None = None,
                        offset: bool = False, lazy: bool | None = None):
        """(s (n,), outward direction (n, 3)) of points (n, 3) (module docstring).

        ``watch``: how far a point inside looks (default `reach`): a point farther than
        ``watch`` from every triangle whose nearest triangles vote "inside" gets ``-inf``
        (``watch = 0``: every inside point not on the surface).

        ``offset``: instead of the signed blended distance and the shortest path's
        direction, the blended signed normal offset ``sum w (x - c_t) . n_t / sum w`` and the
        blended face normal ``sum w n_t`` (normalised), smoothstepped into the signed distance
        between OFFSET_NEAR tau and OFFSET_FAR tau. Both are continuous everywhere, through
        the surface too; on a flat piece of surface the offset is the exact signed distance.

        ``lazy`` is accepted for the earlier grid search's callers and ignored."""
        x = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        tau = float(tau)
        watch = self.reach if watch is None else float(watch)
        n_pts = len(x)
        s, g = np.full(n_pts, -np.inf), np.zeros((n_pts, 3))
        if n_pts == 0 or len(self.faces) == 0:
            return s, g
        keep = KAPPA * tau
        big_r = self.radius_max
        dc, t0 = self.tree.query(x)
        near = np.flatnonzero(dc - big_r <= self.reach)      # others: no triangle in reach
        if len(near) == 0:
            return s, g
        xn, dcn = x[near], dc[near]
        enclosed = self.inside(xn)
        # the nearest centroid bounds the nearest distance from below (d >= dc - R): a point
        # with dc - R > watch is deeper than watch if inside (-inf, no search) and measured
        # in full if outside
        deep = enclosed & (dcn - big_r > watch)
        look = np.flatnonzero(~deep)
        dmin = np.full(len(xn), np.inf)
        if len(look):
            xl, tl = xn[look], t0[near[look]]
            q0 = closest_points_on_triangles(xl, self.a[tl], self.b[tl], self.c[tl])
            d0 = np.sqrt(((xl - q0) ** 2).sum(1))
            # pass 1: the nearest triangles (every triangle within d0 >= the nearest distance)
            pi, ti, d, diff = self._measure(xl, np.minimum(d0, self.reach) + big_r)
            dl = np.full(len(xl), np.inf)
            np.minimum.at(dl, pi, d)
            dmin[look] = dl
        deep |= (dmin > watch) & enclosed
        go = np.flatnonzero((dmin <= self.reach) & ~deep)
        if len(go) == 0:
            return s, g
        # pass 2: every triangle of the blend (within d_min + KAPPA tau)
        xg = xn[go]
        pi, ti, d, diff = self._measure(xg, np.minimum(dmin[go] + keep, self.reach) + big_r)
        ok = d <= self.reach
        pi, ti, d, diff = pi[ok], ti[ok], d[ok], diff[ok]
        sg, gg = _blend(pi, ti, d, diff, self.nrm, len(xg), tau, offset)
        if not offset:   # inside by parity: negative whatever the blend's vote
            sg = np.where(enclosed[go] & np.isfinite(sg), -np.abs(sg), sg)
        s[near[go]], g[near[go]] = sg, gg
        return s, g


def _blend(pi, ti, d, diff, nrm, n_pts, tau, offset):
    """Soft-min blend (module docstring) of the measured pairs (point pi, triangle ti, distance
    d, point minus closest point diff) into (s (n_pts,), direction (n_pts, 3))."""
    best = np.full(n_pts, np.inf)
    np.minimum.at(best, pi, d)
    delta = d - best[pi]
    use = delta <= KAPPA * tau
    f = (KAPPA * tau - delta) / tau
    w = np.where(use, np.exp(-np.where(use, delta, 0.0) / tau)
                 * np.where(f < 1.0, f * f * (3.0 - 2.0 * f), 1.0), 0.0)
    nt = nrm[ti]

    def total(values):
        return np.bincount(pi, values, n_pts)

    sw = total(w)
    ok = sw > 0.0
    safe = np.where(ok, sw, 1.0)
    dist = total(w * d) / safe
    v = np.stack([total(w * diff[:, k]) for k in range(3)], 1) / safe[:, None]
    nn = np.stack([total(w * nt[:, k]) for k in range(3)], 1) / safe[:, None]
    vote = total(w * np.einsum("ij,ij->i", diff, nt))
    sign = np.sign(vote)
    g = _unit_rows(sign[:, None] * v + tau * nn)
    s = sign * dist
    if offset:   # near the surface the normal offset and normal, far out the distance
        lam = np.clip((dist - OFFSET_NEAR * tau) / ((OFFSET_FAR - OFFSET_NEAR) * tau), 0, 1)
        lam = lam * lam * (3.0 - 2.0 * lam)
        s = (1.0 - lam) * vote / safe + lam * s
        g = _unit_rows((1.0 - lam)[:, None] * _unit_rows(nn) + lam[:, None] * g)
    return np.where(ok, s, -np.inf), np.where(ok[:, None], g, 0.0)


def surface_distance(points, vertices, faces, *, reach: float, softness: float):
    """Signed distance of points to a closed surface (positive outside) and the outward
    direction of the shortest path, soft-blended over the nearest triangles (module
    docstring; Ericson 2005 §5.1.5, Baerentzen & Aanaes 2005).

    Parameters
    ----------
    points : (..., 3) float
    vertices : (V, 3) float
    faces : (T, 3) int
        Closed, consistently and outward wound.
    reach : float, keyword-only
        Points with no triangle within this distance get ``-inf`` (taken as inside).
    softness : float, keyword-only
        Soft-min width tau of the blend.

    Returns
    -------
    s : (...) float
        Signed distance (``-inf``: no triangle within `reach`).
    n : (..., 3) float
        Unit outward direction (0 where ``s = -inf``).
    """
    for name, value in (("reach", reach), ("softness", softness)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive number, got {value!r}")
    pts = np.asarray(points, dtype=np.float64)
    s, n = SurfaceGrid(vertices, faces, reach=reach).signed_distance(pts, tau=softness)
    return s.reshape(pts.shape[:-1]), n.reshape(pts.shape)
