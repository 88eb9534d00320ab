"""Signed distance to a closed triangle surface, soft-blended over the nearest triangles.

For `fibres.finishing.containment` (and tests): exact point-triangle distances (the closest
point of a triangle, Ericson, Real-Time Collision Detection 2005, §5.1.5), blended over the
nearest triangles with soft-min weights ``w_t = exp(-(d_t - d_min) / tau)``, which keeps
distance and direction continuous where two walls are equally near (the medial surface of a
concave valley, where the single closest triangle jumps from one wall to the other):

- distance ``D = sum w d / sum w``;
- sign of ``sum w (x - c_t) . n_t`` (c_t the closest point of triangle t, n_t its unit outward
  normal): the pseudo-normal test of Baerentzen & Aanaes (IEEE TVCG 11(3), 2005) with unit
  face weights -- at an edge or a vertex all faces sharing it tie and vote together;
- outward direction ``n = normalise(sign sum w (x - c_t) + tau sum w n_t)`` (the shortest
  path's direction, the face normal for a point on the surface).

Weights fade to exactly 0 between ``delta = (KAPPA - 1) tau`` and ``KAPPA tau`` (smoothstep),
so only triangles within ``d_min + KAPPA tau`` count.

Inside or outside: every point is classified by ray parity (the ray from the point along a
fixed generic direction `RAY` crosses the surface an odd number of times; the unit-weight vote
of the nearest triangles can be wrong at a mesh vertex). In the frame whose x axis is the ray,
the triangles are binned by their (y, z) bounding boxes in a uniform 2-d grid; a point meets
the triangles of its own column, each crossed when the point's (y, z) lies in its projection
(three edge functions of one sign) beyond the point along x.

Search: the triangles are binned by their bounding boxes in a uniform 3-d grid (CSR arrays:
cell start, triangle items; about `SEARCH_DENSITY` cells per triangle over the vertices'
bounding box). Per point, the cells are visited ring by ring about the point's own cell (ring r:
the cells at Chebyshev distance r); a cell farther from the point than the current bound is
passed over, every other triangle is measured once, exactly. The bound starts at ``limit``
and becomes ``min(d + KAPPA tau, reach)`` once a triangle at d <= limit is found; the search
stops when the ring's box is farther than the bound on every side (a triangle not met lies
beyond a face of that box, or beyond the grid, where there are none), so every triangle of
the blend has been measured. ``limit`` is ``reach`` for a point outside and ``min(watch,
reach)`` for one inside: a point with no triangle within its limit gets ``s = -inf`` (no
triangle in reach, or inside deeper than ``watch``).

Compiled: the grids' binning passes (`_bin_cells`, with each triangle's bounding ball), the
parity test (`_parity`) and the search with the blend (`_blend`: each point's start cell, the
search, the sums and their finish into ``s`` and the direction) are loops over triangles and
points in numba (module level, ``cache=True``: compiled once per environment), one call per
query, so that a query of a few hundred points costs no string of small numpy steps; what is
one vectorised step per grid (its size, the outputs and work arrays) is numpy around them, and
the kernels allocate nothing. `tests/fibres/distance_oracle.py` is the brute-force numpy oracle
they are tested against.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .closest_point import closest_point

__all__ = ["SurfaceGrid", "surface_distance", "KAPPA"]

#: triangles farther than d_min + KAPPA tau get no weight in the blend
KAPPA = 8.0
#: ``offset`` mode: the normal offset within OFFSET_NEAR tau of the surface, the signed
#: distance beyond OFFSET_FAR tau, smoothstep between (the blend's vote, which signs the
#: distance, and the exact inside test disagree only within ~0.9 tau: tests)
OFFSET_NEAR, OFFSET_FAR = 2.0, 4.0
#: the direction of the parity rays (generic: no mesh edge is parallel to it by construction
#: of a muscle scan)
RAY = np.array([0.8660254037844386, 0.3535533905932738, 0.3535533905932738])


def _ray_basis():
    """Rows: RAY and two unit vectors completing it to a right-handed orthonormal frame."""
    u = RAY / np.linalg.norm(RAY)
    v = np.cross(u, [0.0, 0.0, 1.0])
    v /= np.linalg.norm(v)
    return np.stack([u, v, np.cross(u, v)])


#: rows y, z and the ray of the parity test's frame
_RAY_FRAME = np.ascontiguousarray(_ray_basis()[[1, 2, 0]])


def _bin_triangles(vertices, faces, frame, n_axes, density):
    """The triangles (vertices, faces) binned by their bounding boxes in a uniform grid along
    the first ``n_axes`` (2 or 3) rows of ``frame`` (3, 3) (None: the world axes; a further
    axis: one cell), of about ``density`` cells per triangle over the vertices' bounding box
    (a side thinner than 1e-3 of the widest counts as 1e-3 of it). Returns (the vertices in
    the frame (V, 3), origin (3,), cell, dims (3,), start, items):
    cell (i, j, k) spans ``origin + cell * [i, i + 1)`` etc. along the frame's axes; the
    triangles meeting it are ``items[start[q]:start[q + 1]]``, ``q = (i * dims[1] + j) *
    dims[2] + k``, in increasing order (CSR; counted, then placed by `_bin_cells`)."""
    if frame is None:                           # the world frame: the vertices as they are
        pv = np.array(vertices, dtype=np.float64)   # writable: the kernels' one array type
        rows = np.ascontiguousarray(pv.T)
    else:
        rows = np.empty((3, vertices.shape[0]))     # the vertices in the frame, by axis
        for k in range(3):
            rows[k] = frame[k, 0] * vertices[:, 0] + frame[k, 1] * vertices[:, 1] \
                + frame[k, 2] * vertices[:, 2]
        pv = np.ascontiguousarray(rows.T)
    origin = np.zeros(3)
    top = np.zeros(3)
    if rows.shape[1]:
        origin[:n_axes] = rows[:n_axes].min(axis=1)
        top[:n_axes] = rows[:n_axes].max(axis=1)
    side = (top - origin).tolist()
    widest = max([0.0] + side[:n_axes])
    volume = 1.0
    for k in range(n_axes):
        volume *= max(side[k], 1e-3 * widest)
    cell = (volume / (density * faces.shape[0])) ** (1.0 / n_axes)
    if not cell > 0.0:
        cell = 1.0                   # every vertex at one point
    dims = np.array([int(s / cell) + 1 for s in side], np.int64)
    span = np.empty((faces.shape[0], 6), np.int32)
    start = np.zeros(int(dims.prod()) + 1, np.int64)
    ball = np.empty((faces.shape[0] if n_axes == 3 else 0, 4))
    _bin_cells(pv, faces, origin, cell, dims, n_axes, span, start, start[:0], ball, False)
    items = np.empty(start[-1], np.int64)
    _bin_cells(pv, faces, origin, cell, dims, n_axes, span, start, items, ball, True)
    return pv, origin, cell, dims, start, items, ball


@njit(cache=True, nogil=True, error_model="numpy")
def _bin_cells(pv, faces, origin, cell, dims, n_axes, span, start, items, ball, fill):
    """`_bin_triangles`' two passes over the triangles (faces of the vertices pv (V, 3) in
    the grid's frame): without ``fill``, each triangle's cell box into ``span`` (T, 6) (first
    and last cell per axis; zeros: a further axis has one cell), ``start`` (zeros) the
    offsets of each cell's triangles and, if ``ball`` is (T, 4) (not (0, 4)), each
    triangle's bounding ball (centroid, largest distance of a corner from it);
    with ``fill``, the triangles into ``items`` (start[-1],) at those offsets."""
    if not fill:
        for t in range(faces.shape[0]):
            a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
            if ball.shape[0]:
                r = 0.0
                for k in range(3):
                    ball[t, k] = (pv[a, k] + pv[b, k] + pv[c, k]) / 3.0
                for j in (a, b, c):
                    r = max(r, (pv[j, 0] - ball[t, 0]) ** 2 + (pv[j, 1] - ball[t, 1]) ** 2
                            + (pv[j, 2] - ball[t, 2]) ** 2)
                ball[t, 3] = math.sqrt(r)
            for k in range(3):        # int() truncates towards 0: the same after clamping
                ya, yb, yc = pv[a, k], pv[b, k], pv[c, k]
                span[t, k] = min(max(int((min(ya, yb, yc) - origin[k]) / cell), 0),
                                 dims[k] - 1) if k < n_axes else 0
                span[t, k + 3] = min(max(int((max(ya, yb, yc) - origin[k]) / cell), 0),
                                     dims[k] - 1) if k < n_axes else 0
    for t in range(faces.shape[0]):  # count the triangles of each cell, or place them
        for i in range(span[t, 0], span[t, 3] + 1):
            for j in range(span[t, 1], span[t, 4] + 1):
                for k in range(span[t, 2], span[t, 5] + 1):
                    q = (i * dims[1] + j) * dims[2] + k
                    if fill:
                        items[start[q]] = t
                        start[q] += 1
                    else:
                        start[q + 1] += 1
    if fill:                         # the fill advanced start[q] to start[q + 1]
        for q in range(start.shape[0] - 1, 0, -1):
            start[q] = start[q - 1]
        start[0] = 0
    else:
        for q in range(1, start.shape[0]):
            start[q] += start[q - 1]


@njit(cache=True, nogil=True, error_model="numpy")
def _parity(x, frame, pv, origin, cell, dims, faces, start, items, inside):
    """Whether each point x (n, 3) is inside by ray parity (module docstring), into
    ``inside`` (n,) bool: (py, pz, px) the point in ``frame`` (rows y, z, ray), its column
    the cell of (py, pz) in the 2-d grid (origin, cell, dims, start, items) of
    `_bin_triangles` (the triangles binned by their (y, z) bounding boxes), pv (V, 3) the
    vertices in the frame."""
    for i in range(x.shape[0]):
        x0, x1, x2 = x[i, 0], x[i, 1], x[i, 2]
        py = frame[0, 0] * x0 + frame[0, 1] * x1 + frame[0, 2] * x2
        pz = frame[1, 0] * x0 + frame[1, 1] * x1 + frame[1, 2] * x2
        px = frame[2, 0] * x0 + frame[2, 1] * x1 + frame[2, 2] * x2
        # int() truncates towards 0: the same after clamping
        q = min(max(int((py - origin[0]) / cell), 0), dims[0] - 1) * dims[1] \
            + min(max(int((pz - origin[1]) / cell), 0), dims[1] - 1)
        hits = np.int64(0)            # not a literal 0: one pass of type inference
        for m in range(start[q], start[q + 1]):
            t = items[m]
            a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
            ay, az, by, bz, cy, cz = pv[a, 0], pv[a, 1], pv[b, 0], pv[b, 1], pv[c, 0], pv[c, 1]
            e0 = (by - ay) * (pz - az) - (bz - az) * (py - ay)
            e1 = (cy - by) * (pz - bz) - (cz - bz) * (py - by)
            e2 = (ay - cy) * (pz - cz) - (az - cz) * (py - cy)
            if (e0 > 0.0 and e1 > 0.0 and e2 > 0.0) or (e0 < 0.0 and e1 < 0.0 and e2 < 0.0):
                # the crossing's ray coordinate: barycentric in the (y, z) edge functions
                if (e1 * pv[a, 2] + e2 * pv[b, 2] + e0 * pv[c, 2]) / (e0 + e1 + e2) > px:
                    hits += 1
        inside[i] = hits % 2 == 1
    return inside


@njit(cache=True, nogil=True, error_model="numpy")
def _blend(x, inside, watch, vertices, faces, grid, tau, reach, offset):
    """The soft-min blend (module docstring) of points x (n, 3) over the triangles (vertices,
    faces) of the 3-d grid ``grid`` = (origin, cell, dims, start, items, ball) of
    `_bin_triangles`: ``s`` (n,) and ``g`` (n, 3) of `SurfaceGrid.signed_distance`
    (``inside`` (n,) by parity), ``-inf`` and 0 where no triangle lies within the point's
    limit (``reach``, or ``min(watch, reach)`` inside). Work space: ``seen`` (T,) (the last
    point that met each triangle), ``found`` (T, 7) (per triangle measured: d, x - c, unit
    normal), ``box`` (6,) and ``home`` (4,) (the ring's cell range; the point's cell (clamped
    into the grid) and how many rings to search: every ring if the grid's box lies within the
    limit, else none), ``vec`` (3, 3) (sum w (x - c), sum w n, the direction). The closest
    point c of a triangle to x: `fibres.mesh.closest_point.closest_point`. A triangle whose bounding ball or plane is farther than ``cut``
    is passed over unmeasured: ``cut`` is ``min(limit + KAPPA tau, reach)`` until a
    triangle within the limit is found, then the bound (it only decreases), so such a
    triangle would get no weight and is never the nearest that counts."""
    origin, cell, dims, start, items, ball = grid
    n, t_all = x.shape[0], faces.shape[0]
    s, g = np.empty(n), np.empty((n, 3))
    seen, found = np.full(t_all, -1, np.int64), np.empty((t_all, 7))
    box, home, vec = np.empty(6, np.int64), np.empty(4, np.int64), np.empty((3, 3))
    keep = KAPPA * tau
    slack = 1e-9 * cell               # for rounding in the cell indices of a triangle's box
    for i in range(x.shape[0]):
        p = x[i]
        limit = min(watch, reach) if inside[i] else reach
        gap = 0.0
        for k in range(3):            # int() truncates towards 0: the same after clamping
            y = p[k] - origin[k]
            home[k] = min(max(int(y / cell), 0), dims[k] - 1)
            y = max(-y, y - dims[k] * cell, 0.0)
            gap += y * y
        home[3] = max(dims[0], dims[1], dims[2]) if gap <= limit * limit else 0
        m = np.int64(0)               # not a literal 0: one pass of type inference
        dmin = np.inf
        bound = limit                 # the triangles farther than bound are not needed
        cut = min(bound + keep, reach) + slack
        for ring in range(home[3]):   # the cells at Chebyshev distance ring from home
            for k in range(3):        # box[:3], box[3:]: the ring's cell range
                box[k] = max(home[k] - ring, 0)
                box[3 + k] = min(home[k] + ring, dims[k] - 1)
            for ci in range(box[0], box[3] + 1):
                y = origin[0] + ci * cell - p[0]      # squared distance from the point to
                gi = max(y, -y - cell, 0.0)           # the cell: per axis, past either side
                for cj in range(box[1], box[4] + 1):
                    y = origin[1] + cj * cell - p[1]
                    gj = max(y, -y - cell, 0.0)
                    face = abs(ci - home[0]) == ring or abs(cj - home[1]) == ring
                    for ck in range(box[2], box[5] + 1):
                        if not face and abs(ck - home[2]) != ring:
                            continue
                        y = origin[2] + ck * cell - p[2]
                        gk = max(y, -y - cell, 0.0)
                        if 0.0 + gi * gi + gj * gj + gk * gk > (bound + slack) * (bound + slack):
                            continue
                        q = (ci * dims[1] + cj) * dims[2] + ck
                        for e in range(start[q], start[q + 1]):
                            t = items[e]
                            if seen[t] == i:
                                continue
                            seen[t] = i
                            if (p[0] - ball[t, 0]) ** 2 + (p[1] - ball[t, 1]) ** 2 \
                                    + (p[2] - ball[t, 2]) ** 2 > (ball[t, 3] + cut) ** 2:
                                continue
                            ia, ib, ic = faces[t, 0], faces[t, 1], faces[t, 2]
                            a0, a1, a2 = vertices[ia, 0], vertices[ia, 1], vertices[ia, 2]
                            ab0, ab1, ab2 = (vertices[ib, 0] - a0, vertices[ib, 1] - a1,
                                             vertices[ib, 2] - a2)
                            ac0, ac1, ac2 = (vertices[ic, 0] - a0, vertices[ic, 1] - a1,
                                             vertices[ic, 2] - a2)
                            ap0, ap1, ap2 = p[0] - a0, p[1] - a1, p[2] - a2
                            n0 = ab1 * ac2 - ab2 * ac1        # the normal, 2 x area long
                            n1 = ab2 * ac0 - ab0 * ac2
                            n2 = ab0 * ac1 - ab1 * ac0
                            size = math.sqrt(n0 ** 2 + n1 ** 2 + n2 ** 2)
                            if abs(ap0 * n0 + ap1 * n1 + ap2 * n2) > cut * size:
                                continue                      # its plane is farther
                            c0, c1, c2 = closest_point(p[0], p[1], p[2], vertices[ia],
                                                       vertices[ib], vertices[ic])
                            found[m, 1], found[m, 2], found[m, 3] = p[0] - c0, p[1] - c1, p[2] - c2
                            d = math.sqrt(found[m, 1] ** 2 + found[m, 2] ** 2 + found[m, 3] ** 2)
                            # the unit normal (0 without area: +-0 / inf)
                            if not size > 0.0:
                                size = np.inf
                            found[m, 4] = n0 / size
                            found[m, 5] = n1 / size
                            found[m, 6] = n2 / size
                            found[m, 0] = d
                            m += 1
                            if d < dmin:
                                dmin = d
                                if dmin <= limit:
                                    bound = min(dmin + keep, reach)
                                    cut = bound + slack
            # every triangle not met is beyond the faces of the ring's box (none beyond the
            # grid's border): stop once they are all farther than bound
            beyond = np.inf
            for k in range(3):
                if home[k] - ring > 0:
                    beyond = min(beyond, p[k] - (origin[k] + (home[k] - ring) * cell))
                if home[k] + ring < dims[k] - 1:
                    beyond = min(beyond, origin[k] + (home[k] + ring + 1) * cell - p[k])
            if beyond > bound + slack:
                break
        if not dmin <= limit:
            m = 0
        sw = sd = vote = 0.0
        for k in range(6):
            vec[k // 3, k % 3] = 0.0
        for j in range(m):
            delta = found[j, 0] - dmin
            if found[j, 0] <= reach and delta <= keep:
                f = (keep - delta) / tau
                w = math.exp(-delta / tau) * (f * f * (3.0 - 2.0 * f) if f < 1.0 else 1.0)
                sw += w
                sd += w * found[j, 0]
                for k in range(3):
                    vote += w * found[j, 1 + k] * found[j, 4 + k]
                    vec[0, k] += w * found[j, 1 + k]
                    vec[1, k] += w * found[j, 4 + k]
        if not sw > 0.0:
            s[i] = -np.inf
            for k in range(3):
                g[i, k] = 0.0
            continue
        dist = sd / sw
        sign = 1.0 if vote > 0.0 else (-1.0 if vote < 0.0 else 0.0)
        for k in range(3):
            vec[1, k] /= sw
            vec[2, k] = sign * (vec[0, k] / sw) + tau * vec[1, k]
        s[i] = sign * dist
        # near the surface the normal offset and normal, far out the distance
        lam = min(max((dist - OFFSET_NEAR * tau) / ((OFFSET_FAR - OFFSET_NEAR) * tau), 0.0),
                  1.0)
        lam = lam * lam * (3.0 - 2.0 * lam)
        for step in range(3 if offset else 1):   # unit rows: the direction (2), then the
            r = 1 if step == 1 else 2            # normal (1) and the blend of both (2)
            if step == 2:
                s[i] = (1.0 - lam) * vote / sw + lam * s[i]
                for k in range(3):
                    vec[2, k] = (1.0 - lam) * vec[1, k] + lam * vec[2, k]
            size = math.sqrt(vec[r, 0] * vec[r, 0] + vec[r, 1] * vec[r, 1]
                             + vec[r, 2] * vec[r, 2])
            if size > 0.0:
                for k in range(3):
                    vec[r, k] /= size
        for k in range(3):
            g[i, k] = vec[2, k]
        if inside[i] and not offset:          # inside by parity: negative, whatever the vote
            s[i] = -abs(s[i])
    return s, g


#: cells per triangle of the search grid (at least; `SEARCH_DENSITY_MAX` at most) and of the
#: parity grid
SEARCH_DENSITY, PARITY_DENSITY = 4.0, 0.5
#: the search grid's cells are cubes of about the triangles' mean edge, within these bounds
SEARCH_DENSITY_MAX = 64.0
#: triangles whose first edge measures the mean edge (`_search_density`)
EDGE_SAMPLES = 256


def _search_density(vertices, faces):
    """Cells per triangle of the search grid: cubes whose side is the mean length of the
    triangles' first edges (measured on `EDGE_SAMPLES` evenly strided triangles), so that a
    cell holds a few triangles however much of the vertices' bounding box the surface leaves
    empty (a long muscle lying or bent across its box); bounded to [`SEARCH_DENSITY`,
    `SEARCH_DENSITY_MAX`]; the box's volume as `_bin_triangles` measures it."""
    rows = np.ascontiguousarray(vertices.T)          # (3, V): reductions over contiguous rows
    ext = rows.max(axis=1) - rows.min(axis=1)
    volume = float(np.prod(np.maximum(ext, 1e-3 * ext.max())))
    some = faces[::max(1, len(faces) // EDGE_SAMPLES)]           # an evenly strided sample
    step = vertices[some[:, 1]] - vertices[some[:, 0]]
    edge = float(np.mean(np.sqrt(np.einsum("ij,ij->i", step, step))))
    if not (volume > 0.0 and edge > 0.0):
        return SEARCH_DENSITY
    return min(max(volume / (len(faces) * edge ** 3), SEARCH_DENSITY), SEARCH_DENSITY_MAX)


class SurfaceGrid:
    """A closed surface prepared for signed-distance queries (module docstring): its
    triangles binned in a uniform 3-d grid and (at the first query) in the 2-d grid of the
    parity test.

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (T, 3) int
        Closed, consistently and outward wound.
    reach : float
        Points with no triangle within this distance get ``s = -inf``.

    The grids are sized by the vertices' bounding box, the number of triangles and (the search
    grid) their mean edge (`_search_density`).
    """

    def __init__(self, vertices, faces, *, reach: float):
        self.vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.reach = float(reach)
        self._grid = _bin_triangles(self.vertices, self.faces, None, 3,
                                    _search_density(self.vertices, self.faces))[1:] \
            if len(self.faces) else None
        self._ray = None

    @property
    def cells(self):
        """The search grid (origin, cell, dims, start, items, ball) of `_bin_triangles`
        (None without triangles): ``ball[:, :3]`` are the triangles' centroids
        ``(a + b + c) / 3``."""
        return self._grid

    def inside(self, points):
        """Whether each point (n, 3) is inside the closed surface, by ray parity along `RAY`
        (module docstring; ties on edges have measure zero)."""
        x = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        if len(self.faces) == 0:
            return np.zeros(len(x), bool)
        if self._ray is None:
            self._ray = _bin_triangles(self.vertices, self.faces, _RAY_FRAME, 2,
                                       PARITY_DENSITY)
        pv, origin, cell, dims, start, items, _ = self._ray
        return _parity(x, _RAY_FRAME, pv, origin, cell, dims, self.faces, start, items,
                       np.empty(len(x), bool))

    def signed_distance(self, points, *, tau: float, watch: float | None = None,
                        offset: bool = False):
        """(s (n,), outward direction (n, 3)) of points (n, 3) (module docstring).

        ``watch``: how far a point inside looks (default `reach`): a point inside by parity
        with no triangle within ``watch`` gets ``-inf`` (``watch = 0``: every inside point
        not on the surface). Without ``offset`` an inside point's distance is negative.

        ``offset``: instead of the signed blended distance and the shortest path's
        direction, the blended signed normal offset ``sum w (x - c_t) . n_t / sum w`` and the
        blended face normal ``sum w n_t`` (normalised), smoothstepped into the signed distance
        between OFFSET_NEAR tau and OFFSET_FAR tau. Both are continuous everywhere, through
        the surface too; on a flat piece of surface the offset is the exact signed distance."""
        x = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        watch = self.reach if watch is None else float(watch)
        if len(x) == 0 or len(self.faces) == 0:
            return np.full(len(x), -np.inf), np.zeros((len(x), 3))
        return _blend(x, self.inside(x), watch, self.vertices, self.faces, self._grid,
                      float(tau), self.reach, bool(offset))


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
