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

Compiled: the grids' binning passes (`_bin_cells`), the parity test (`_parity`) and the search
with the blend's per-point sums (`_blend_sums`) are loops over triangles and points in numba
(module level, ``cache=True``: compiled once per environment); what is one vectorised step
per point or per grid (the grid's size, each point's frame coordinates and start cell, the
outputs and work arrays) is numpy around them, so that the kernels allocate nothing and stay
short (numba's compile time grows with every statement); the blend is finished in numpy
(`_blend`). `tests/fibres/distance_oracle.py` is the brute-force numpy oracle they are tested
against.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

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
    the first ``n_axes`` (2 or 3) rows of ``frame`` (3, 3) (a further axis: one cell), of about
    ``density`` cells per triangle over the vertices' bounding box (a side thinner than 1e-3
    of the widest counts as 1e-3 of it). Returns (the vertices in the frame (V, 3),
    origin (3,), cell, dims (3,), start, items):
    cell (i, j, k) spans ``origin + cell * [i, i + 1)`` etc. along the frame's axes; the
    triangles meeting it are ``items[start[q]:start[q + 1]]``, ``q = (i * dims[1] + j) *
    dims[2] + k``, in increasing order (CSR; counted, then placed by `_bin_cells`)."""
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
    span = np.zeros((faces.shape[0], 6), np.int64)
    start = np.zeros(int(dims.prod()) + 1, np.int64)
    _bin_cells(pv, faces, origin, cell, dims, n_axes, span, start, start[:0], False)
    items = np.empty(start[-1], np.int64)
    _bin_cells(pv, faces, origin, cell, dims, n_axes, span, start, items, True)
    return pv, origin, cell, dims, start, items


@njit(cache=True, nogil=True, error_model="numpy")
def _bin_cells(pv, faces, origin, cell, dims, n_axes, span, start, items, fill):
    """`_bin_triangles`' two passes over the triangles (faces of the vertices pv (V, 3) in
    the grid's frame): without ``fill``, each triangle's cell box into ``span`` (T, 6) (first
    and last cell per axis; zeros: a further axis has one cell) and ``start`` (zeros) the
    offsets of each cell's triangles;
    with ``fill``, the triangles into ``items`` (start[-1],) at those offsets."""
    if not fill:
        for t in range(faces.shape[0]):
            a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
            for k in range(n_axes):   # int() truncates towards 0: the same after clamping
                ya, yb, yc = pv[a, k], pv[b, k], pv[c, k]
                span[t, k] = min(max(int((min(ya, yb, yc) - origin[k]) / cell), 0), dims[k] - 1)
                span[t, k + 3] = min(max(int((max(ya, yb, yc) - origin[k]) / cell), 0),
                                     dims[k] - 1)
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
def _parity(yzx, column, pv, faces, start, items, inside):
    """Whether each point is inside by ray parity (module docstring), into ``inside`` (n,)
    bool: ``yzx`` (3, n) the points in the frame of rows (y, z, ray), ``column`` (n,) their
    cells of the 2-d grid (start, items) of `_bin_triangles` (the triangles binned by their
    (y, z) bounding boxes), pv (V, 3) the vertices in the frame."""
    for i in range(column.shape[0]):
        py, pz, px = yzx[0, i], yzx[1, i], yzx[2, i]
        q = column[i]
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
def _blend_sums(x, limits, cells, vertices, faces, origin, cell, dims, start, items, tau,
                reach, sums, seen, found, box):
    """The sums of the soft-min blend (module docstring) of points x (n, 3) over the triangles
    (vertices, faces) of the 3-d grid (origin, cell, dims, start, items) of
    `_bin_triangles`, added into ``sums`` (n, 9) (zeros): rows ``[sum w, sum w d,
    sum w (x - c) . n, sum w (x - c) (3), sum w n (3)]``, left zero where no triangle lies
    within ``limits[i]``. ``cells`` (n, 4) int64: each point's cell and how many rings to
    search (`_start_cells`). Work space: ``seen`` (T,) int64 all -1, ``found`` (T, 7) (per
    triangle measured: d, x - c, unit normal), ``box`` (6,) int64. The closest point c of a
    triangle to x: the projection of x on its plane when inside it, else the nearest of the
    three edges' closest points (the closest point of a convex set is unique: Ericson 2005
    §5.1.5 finds the same)."""
    keep = KAPPA * tau
    slack = 1e-9 * cell               # for rounding in the cell indices of a triangle's box
    for i in range(x.shape[0]):
        p = x[i]
        home = cells[i]               # the point's cell
        m = np.int64(0)               # not a literal 0: one pass of type inference
        dmin = np.inf
        bound = limits[i]             # the triangles farther than bound are not needed
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
                            ia, ib, ic = faces[t, 0], faces[t, 1], faces[t, 2]
                            a0, a1, a2 = vertices[ia, 0], vertices[ia, 1], vertices[ia, 2]
                            ab0, ab1, ab2 = (vertices[ib, 0] - a0, vertices[ib, 1] - a1,
                                             vertices[ib, 2] - a2)
                            ac0, ac1, ac2 = (vertices[ic, 0] - a0, vertices[ic, 1] - a1,
                                             vertices[ic, 2] - a2)
                            ap0, ap1, ap2 = p[0] - a0, p[1] - a1, p[2] - a2
                            d00 = ab0 * ab0 + ab1 * ab1 + ab2 * ab2
                            d01 = ab0 * ac0 + ab1 * ac1 + ab2 * ac2
                            d11 = ac0 * ac0 + ac1 * ac1 + ac2 * ac2
                            d1 = ab0 * ap0 + ab1 * ap1 + ab2 * ap2
                            d2 = ac0 * ap0 + ac1 * ap1 + ac2 * ap2
                            den = d00 * d11 - d01 * d01
                            u = w = -1.0
                            if den > 0.0:
                                u = (d11 * d1 - d01 * d2) / den
                                w = (d00 * d2 - d01 * d1) / den
                            if u >= 0.0 and w >= 0.0 and u + w <= 1.0:
                                found[m, 1] = ap0 - u * ab0 - w * ac0
                                found[m, 2] = ap1 - u * ab1 - w * ac1
                                found[m, 3] = ap2 - u * ab2 - w * ac2
                                d = math.sqrt(found[m, 1] ** 2 + found[m, 2] ** 2
                                              + found[m, 3] ** 2)
                            else:
                                d = np.inf
                                for j in range(3):            # edge (corner j, corner j + 1)
                                    e0 = vertices[faces[t, j]]
                                    e1 = vertices[faces[t, (j + 1) % 3]]
                                    num = 0.0
                                    length = 0.0
                                    for k in range(3):
                                        num += (p[k] - e0[k]) * (e1[k] - e0[k])
                                        length += (e1[k] - e0[k]) ** 2
                                    f = min(max(num / length, 0.0), 1.0) if length > 0.0 else 0.0
                                    r = 0.0                   # x - c into found[m, 4:7]
                                    for k in range(3):
                                        found[m, 4 + k] = p[k] - e0[k] - f * (e1[k] - e0[k])
                                        r += found[m, 4 + k] ** 2
                                    r = math.sqrt(r)
                                    if r < d:
                                        d = r
                                        for k in range(1, 4):
                                            found[m, k] = found[m, 3 + k]
                            # the unit normal (0 without area: +-0 / inf)
                            n0 = ab1 * ac2 - ab2 * ac1
                            n1 = ab2 * ac0 - ab0 * ac2
                            n2 = ab0 * ac1 - ab1 * ac0
                            size = math.sqrt(n0 ** 2 + n1 ** 2 + n2 ** 2)
                            if not size > 0.0:
                                size = np.inf
                            found[m, 4] = n0 / size
                            found[m, 5] = n1 / size
                            found[m, 6] = n2 / size
                            found[m, 0] = d
                            m += 1
                            if d < dmin:
                                dmin = d
                                if dmin <= limits[i]:
                                    bound = min(dmin + keep, reach)
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
        if not dmin <= limits[i]:
            m = 0
        for j in range(m):
            delta = found[j, 0] - dmin
            if found[j, 0] <= reach and delta <= keep:
                f = (keep - delta) / tau
                w = math.exp(-delta / tau) * (f * f * (3.0 - 2.0 * f) if f < 1.0 else 1.0)
                sums[i, 0] += w
                sums[i, 1] += w * found[j, 0]
                for k in range(3):
                    sums[i, 2] += w * found[j, 1 + k] * found[j, 4 + k]
                    sums[i, 3 + k] += w * found[j, 1 + k]
                    sums[i, 6 + k] += w * found[j, 4 + k]
    return sums


def _start_cells(x, limits, origin, cell, dims):
    """(n, 4) int64 for `_blend_sums`: the cell of each point x (n, 3) (clamped into the grid
    (origin, cell, dims); int() truncates towards 0: the same after clamping) and the rings
    of cells to search about it: every ring (max(dims)) if the grid's box lies within
    ``limits`` of the point, else none."""
    out = np.empty((len(x), 4), np.int64)
    d = x - origin
    np.minimum(np.maximum((d / cell).astype(np.int64), 0), dims - 1, out=out[:, :3])
    y = np.maximum(np.maximum(-d, d - dims * cell), 0.0)
    gap = y[:, 0] * y[:, 0] + y[:, 1] * y[:, 1] + y[:, 2] * y[:, 2]
    out[:, 3] = np.where(gap <= limits * limits, dims.max(), 0)
    return out


def _unit_rows(x):
    norm = np.sqrt(np.einsum("ij,ij->i", x, x))[:, None]
    return np.where(norm > 0, x / np.where(norm > 0, norm, 1.0), x)


def _blend(sums, tau, offset):
    """(s (n,), direction (n, 3)) from the blend's sums (`_blend_sums`; module docstring)."""
    sw = sums[:, 0]
    ok = sw > 0.0
    safe = np.where(ok, sw, 1.0)
    dist, vote = sums[:, 1] / safe, sums[:, 2]
    v, nn = sums[:, 3:6] / safe[:, None], sums[:, 6:9] / safe[:, None]
    sign = np.sign(vote)
    g = _unit_rows(sign[:, None] * v + tau * nn)
    s = sign * dist
    if offset:   # near the surface the normal offset and normal, far out the distance
        lam = np.clip((dist - OFFSET_NEAR * tau) / ((OFFSET_FAR - OFFSET_NEAR) * tau), 0, 1)
        lam = lam * lam * (3.0 - 2.0 * lam)
        s = (1.0 - lam) * vote / safe + lam * s
        g = _unit_rows((1.0 - lam)[:, None] * _unit_rows(nn) + lam[:, None] * g)
    return np.where(ok, s, -np.inf), np.where(ok[:, None], g, 0.0)


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
        self._grid = _bin_triangles(self.vertices, self.faces, np.eye(3), 3,
                                    _search_density(self.vertices, self.faces))[1:] \
            if len(self.faces) else None
        self._ray = None

    def inside(self, points):
        """Whether each point (n, 3) is inside the closed surface, by ray parity along `RAY`
        (module docstring; ties on edges have measure zero)."""
        x = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        if len(self.faces) == 0:
            return np.zeros(len(x), bool)
        if self._ray is None:
            self._ray = _bin_triangles(self.vertices, self.faces, _RAY_FRAME, 2,
                                       PARITY_DENSITY)
        pv, origin, cell, dims, start, items = self._ray
        f = _RAY_FRAME
        yzx = np.empty((3, len(x)))
        for k in range(3):
            yzx[k] = f[k, 0] * x[:, 0] + f[k, 1] * x[:, 1] + f[k, 2] * x[:, 2]
        # the (y, z) cell: int() truncates towards 0, the same after clamping
        cy, cz = np.maximum(((yzx[:2] - origin[:2, None]) / cell).astype(np.int64), 0)
        column = np.minimum(cy, dims[0] - 1) * dims[1] + np.minimum(cz, dims[1] - 1)
        return _parity(yzx, column, pv, self.faces, start, items, np.empty(len(x), bool))

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
        inside = self.inside(x)
        limits = np.where(inside, min(watch, self.reach), self.reach)
        t = len(self.faces)
        sums = _blend_sums(x, limits, _start_cells(x, limits, *self._grid[:3]), self.vertices,
                           self.faces, *self._grid, float(tau), self.reach,
                           np.zeros((len(x), 9)), np.full(t, -1, np.int64), np.empty((t, 7)),
                           np.empty(6, np.int64))
        s, g = _blend(sums, float(tau), bool(offset))
        if not offset:   # inside by parity: negative whatever the blend's vote
            s = np.where(inside & np.isfinite(s), -np.abs(s), s)
        return s, g


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
