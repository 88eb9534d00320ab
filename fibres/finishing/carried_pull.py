"""The containment pull of the rest pose, carried to every frame in frames of the walls.

`fibres.decompose` with harmonic slicing maps the plan's fibres onto a frame linearly
(``points = F W V``, `fibres.slicing.harmonic`), and the fairing in that map cuts concave walls
(a tendon bending round a bone), so every frame would pull the same points in again, spread
the pulls along their fibres and pull again (`pull_rounds`). Here that work is done once, on
the plan's rest pose (`carry_rest_pull`: band `REST_MARGIN`, `REST_ROUNDS` spread rounds),
and each displaced point carries its displacement ``e`` to the frames in the frame of a patch
of the surface next to it: of the `CARRY_CANDIDATES` triangles whose centroids are nearest
to the point's place at rest, those whose normals lie within ``acos(FACING)`` of the nearest
one's (so the opposite wall of a thin tendon does not count). With ``n`` the patch's unit
normal (its summed area vectors), ``L^2`` its area and ``t`` the nearest triangle's first
edge projected on the plane normal to ``n``:

    f1 = L t / |t|,   f2 = n x f1,   f3 = L n

an orthogonal frame of three equal sides; ``e = sum_k x_k f_k`` with ``x_k = e . f_k / L^2``
at rest, and on a frame ``e' = sum_k x_k f'_k`` (`CarriedPull.apply`). The frame turns with the
wall next to the point and scales with its local stretch, so a point pulled in from a wall
at rest is pulled in from the same wall in every frame; a rigid motion or a uniform scale of
the mesh moves or scales ``e`` alike, and ``e'`` is a smooth function of the vertices (fixed
coefficients and patches, chosen once; a patch's sums average out the jitter of single
triangles). This is the embedding of points in a deforming mesh by frozen local coordinates
(as in free-form deformation, Sederberg & Parry, SIGGRAPH 1986), applied to the pull's
displacement only.

The frame's own pull (`pull_rounds` with the band `fibres.finishing.containment.CONTAIN_MARGIN`)
follows, for what the deformation itself moves towards a wall: the rest pose's pulled points
end at least ``REST_MARGIN / 2`` deep, deeper than that band, so near the rest pose few points
are measured twice and few fibres spread again.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numba import njit

from ..errors import InputError
from ..mesh.surface_distance import SurfaceGrid
from .containment import CONTAIN_MARGIN, CONTAIN_REACH, contain
from .fairing import PULL_ROUNDS, spread_pull

__all__ = ["CarriedPull", "carry_rest_pull", "planned_pull", "pull_rounds", "REST_MARGIN",
           "REST_ROUNDS", "CARRY_CANDIDATES", "FACING"]

#: band depth (metres) of the rest pose's pull: its points end at least REST_MARGIN / 2 deep
REST_MARGIN = 2.5 * CONTAIN_MARGIN
#: rounds of spreading and pulling again on the rest pose
REST_ROUNDS = 4
#: triangles (nearest centroids) in the patch whose frame carries a point's displacement
CARRY_CANDIDATES = 16
#: a candidate triangle belongs to the patch when its normal is within acos(FACING) of the
#: nearest one's (not the opposite wall of a thin tendon)
FACING = 0.5


def pull_rounds(points, grid: SurfaceGrid, *, margin: float = CONTAIN_MARGIN,
                rounds: int = PULL_ROUNDS):
    """The containment pull (`fibres.finishing.containment.contain`) of fibres ``points``
    (N, P, 3) in the surface of ``grid``, then ``rounds`` rounds of spreading each pulled
    fibre's displacement along it (`fibres.finishing.fairing.spread_pull`) and pulling that
    fibre again; only the fibres pulled in a round take part in the next.

    Returns
    -------
    points : (N, P, 3) float64
        A new array.
    moved : (N,) bool
        Fibres with a point pulled in.
    """
    v, f = grid.vertices, grid.faces
    out, moved = contain(points, v, f, margin=margin, grid=grid)
    todo, before = np.flatnonzero(moved), np.array(points, dtype=np.float64, copy=True)
    for _ in range(int(rounds)):
        if not todo.size:
            break
        spread = spread_pull(before[todo], out[todo])
        again_pts, again = contain(spread, v, f, margin=margin, grid=grid)
        before[todo], out[todo] = spread, again_pts
        todo = todo[np.asarray(again, dtype=bool)]
    return out, moved


def _frames(vertices, faces, patches, first, cross=None):
    """(M, 3, 3) frames ``[f1, f2, f3]`` (module docstring) of M triangle patches and their
    squared side ``L^2`` (M,): ``patches`` (M, F) sparse 0/1 (the rows of ``faces`` (F, 3) in
    each patch), ``first`` (M,) the row whose first edge gives the direction of f1; ``cross``
    (F, 3) the triangles' ``(b - a) x (c - a)`` when at hand."""
    if cross is None:                                               # (F, 3): 2 x area x normal
        a, b, c = np.take(vertices, np.ascontiguousarray(faces.T), axis=0)
        cross = np.cross(b - a, c - a)
    total = patches @ cross
    normal = total / np.maximum(np.linalg.norm(total, axis=1), 1e-300)[:, None]
    side = 0.5 * (patches @ np.linalg.norm(cross, axis=1))          # L^2: the patch's area
    ends = faces[first]
    edge = vertices[ends[:, 1]] - vertices[ends[:, 0]]
    edge -= np.einsum("ij,ij->i", edge, normal)[:, None] * normal
    f1 = edge * np.sqrt(side / np.maximum(np.einsum("ij,ij->i", edge, edge), 1e-300))[:, None]
    f2 = np.cross(normal, f1)
    f3 = np.sqrt(side)[:, None] * normal
    return np.stack([f1, f2, f3], axis=1), side


@dataclass(frozen=True)
class CarriedPull:
    """Displacements of fibre points fixed in the frames of surface triangles (module
    docstring).

    Attributes
    ----------
    shape : (N, P)
        The fibres it applies to.
    rows : (M,) int64
        Flat indices (fibre * P + point) of the displaced points.
    faces : (F, 3) int64
        Vertex indices of the triangles the points' frames are made of.
    patches : (M, F) scipy.sparse.csr_matrix
        1 where a row of ``faces`` belongs to a point's patch: of its `CARRY_CANDIDATES`
        nearest triangles, those facing the nearest one's way.
    first : (M,) int64
        The row of ``faces`` of each point's nearest triangle.
    coefficients : (M, 3) float
        ``x_k``: the displacement is ``sum_k x_k f_k``.
    rest : (vertices (V, 3), displacements (M, 3)) or None
        The surface the pull was made on and ``sum_k x_k f_k`` there: `apply` on those
        vertices adds them instead of rebuilding the same frames.
    """

    shape: tuple
    rows: np.ndarray
    faces: np.ndarray
    patches: sp.csr_matrix
    first: np.ndarray
    coefficients: np.ndarray
    rest: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def fibres(self):
        """(N,) bool: the fibres with a displaced point."""
        out = np.zeros(self.shape[0], bool)
        out[self.rows // self.shape[1]] = True
        return out

    def apply(self, points, vertices):
        """Fibres ``points`` (N, P, 3) of a frame with its surface ``vertices`` (V, 3)
        (same faces as at rest), displaced: a new array."""
        out = np.array(points, dtype=np.float64, copy=True)
        if tuple(out.shape[:2]) != tuple(self.shape):
            raise ValueError(f"points must be {self.shape} fibres x points, got {out.shape[:2]}")
        if self.rows.size:
            out.reshape(-1, 3)[self.rows] += self._shift(vertices)
        return out

    def _shift(self, vertices):
        """(M, 3) displacements ``sum_k x_k f_k`` in the frames on ``vertices``."""
        if self.rest is not None and (vertices is self.rest[0]
                                      or np.array_equal(vertices, self.rest[0])):
            return self.rest[1]
        frames, _ = _frames(np.asarray(vertices, dtype=np.float64), self.faces, self.patches,
                            self.first)
        return np.einsum("mk,mkd->md", self.coefficients, frames)


@njit(cache=True, nogil=True, error_model="numpy")
def _nearest_centroids(x, centroids, grid, k):
    """(n, k) int64: the ``k`` of ``centroids`` (T, 3) nearest to each point x (n, 3), nearest
    first (equal distances: the one met first), ``k <= T``. ``grid`` = (origin, side, dims)
    of a uniform grid of cubes over the centroids' box (`_centroid_grid`): the centroids are
    sorted into its cells (counting sort: cell start, items), then each point visits the
    cells ring by ring about its own (clamped) cell, passes over a cell farther than the
    k-th distance so far and stops once the ring's box is farther than that on every side
    within the grid (no centroid not met lies nearer)."""
    lo, side, dims = grid
    t_all = centroids.shape[0]
    start = np.zeros(dims[0] * dims[1] * dims[2] + 1, np.int64)
    cell_of, items = np.empty(t_all, np.int64), np.empty(t_all, np.int64)
    for t in range(t_all):
        q = np.int64(0)               # not a literal 0: one pass of type inference
        for a in range(3):
            q = q * dims[a] + min(max(int((centroids[t, a] - lo[a]) / side), 0), dims[a] - 1)
        cell_of[t] = q
        start[q + 1] += 1
    for q in range(1, start.shape[0]):
        start[q] += start[q - 1]
    for t in range(t_all):           # placed in increasing order; start[q] advances
        items[start[cell_of[t]]] = t
        start[cell_of[t]] += 1
    for q in range(start.shape[0] - 1, 0, -1):
        start[q] = start[q - 1]
    start[0] = 0
    near, best = np.empty((x.shape[0], k), np.int64), np.empty(k)
    home, box = np.empty(3, np.int64), np.empty(6, np.int64)
    slack = 1e-9 * side               # for rounding in the cell indices
    for i in range(x.shape[0]):
        p = x[i]
        for a in range(3):            # int() truncates towards 0: the same after clamping
            home[a] = min(max(int((p[a] - lo[a]) / side), 0), dims[a] - 1)
        m = np.int64(0)               # not a literal 0: one pass of type inference
        reach = np.inf                # the k-th distance so far, plus slack
        for ring in range(max(dims[0], dims[1], dims[2])):
            for a in range(3):
                box[a] = max(home[a] - ring, 0)
                box[3 + a] = min(home[a] + ring, dims[a] - 1)
            for ci in range(box[0], box[3] + 1):
                for cj in range(box[1], box[4] + 1):
                    for ck in range(box[2], box[5] + 1):
                        q = (ci * dims[1] + cj) * dims[2] + ck
                        if start[q] == start[q + 1] or max(abs(ci - home[0]), abs(cj - home[1]),
                                                           abs(ck - home[2])) != ring:
                            continue  # empty, or a cell of an earlier ring
                        cell, g2 = (ci, cj, ck), 0.0
                        for a in range(3):  # the squared distance from the point to the cell
                            y = lo[a] + cell[a] * side - p[a]
                            y = max(y, -y - side, 0.0)
                            g2 += y * y
                        if g2 > reach * reach:
                            continue
                        for e in range(start[q], start[q + 1]):
                            t = items[e]
                            d2 = (p[0] - centroids[t, 0]) ** 2 + (p[1] - centroids[t, 1]) ** 2 \
                                + (p[2] - centroids[t, 2]) ** 2
                            if m == k and not d2 < best[k - 1]:
                                continue
                            j = m if m < k else k - 1          # insert, nearest first
                            while j > 0 and best[j - 1] > d2:
                                best[j], near[i, j] = best[j - 1], near[i, j - 1]
                                j -= 1
                            best[j], near[i, j] = d2, t
                            m = min(m + 1, k)
                            if m == k:
                                reach = math.sqrt(best[k - 1]) + slack
            beyond = np.inf           # how far the ring's box reaches on its inner sides
            for a in range(3):
                if home[a] - ring > 0:
                    beyond = min(beyond, p[a] - (lo[a] + (home[a] - ring) * side))
                if home[a] + ring < dims[a] - 1:
                    beyond = min(beyond, lo[a] + (home[a] + ring + 1) * side - p[a])
            if beyond > reach:
                break
    return near


def _centroid_grid(centroids, k, area):
    """(origin (3,), side, dims (3,) int64) of `_nearest_centroids`' grid over the box of
    ``centroids`` (T, 3): cubes of about twice the radius that holds ``k`` triangles of mean
    ``area`` on a flat piece of surface (measured: smaller cubes are no faster), at most two
    per centroid (the cell starts are memory to clear)."""
    rows = np.ascontiguousarray(centroids.T)     # reductions over contiguous rows
    lo = rows.min(axis=1)
    ext = rows.max(axis=1) - lo
    side = max(2.0 * math.sqrt(k * area / math.pi), 1e-3 * float(ext.max()), 1e-300)
    while True:
        dims = (ext / side).astype(np.int64) + 1
        if int(np.prod(dims)) <= 2 * len(centroids) + 64:
            return lo, side, dims
        side *= 1.25


def carry_rest_pull(points, vertices, faces, *, margin: float = REST_MARGIN,
                    rounds: int = REST_ROUNDS, reach: float = CONTAIN_REACH,
                    grid: SurfaceGrid | None = None, normals=None):
    """The rest pose's pull (`pull_rounds` with band ``margin``) of fibres ``points``
    (N, P, 3) in the surface (vertices, faces), as a `CarriedPull` (module docstring):
    ``carry_rest_pull(...).apply(points, vertices)`` are the pulled fibres (to rounding).
    ``grid``: the surface already prepared with this ``reach`` (its vertices and faces must
    be these); ``normals``: its face normals scaled by twice the areas
    (`fibres.attachments.patch.face_normals`), when at hand."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    pts = np.asarray(points, dtype=np.float64)
    n, p = pts.shape[:2]
    if grid is None:
        grid = SurfaceGrid(v, f, reach=reach)
    elif grid.reach != float(reach):
        raise ValueError(f"the grid's reach {grid.reach} is not the pull's {reach}")
    out, _ = pull_rounds(pts, grid, margin=margin, rounds=rounds)
    e = (out - pts).reshape(-1, 3)
    rows = np.flatnonzero(np.any(e != 0.0, axis=1))
    if not rows.size:
        return CarriedPull((n, p), rows, np.zeros((0, 3), np.int64),
                           sp.csr_matrix((0, 0)), np.zeros(0, np.int64), np.zeros((0, 3)))
    if normals is None:
        a, b, c = np.take(v, np.ascontiguousarray(f.T), axis=0)
        normals = np.cross(b - a, c - a)
    # the centroids (a + b + c) / 3 of the grid's binning, in cubes of twice the radius that
    # holds CARRY_CANDIDATES triangles of the mean area on a flat piece of surface (measured:
    # smaller cubes are slower)
    k = min(CARRY_CANDIDATES, len(f))
    area = 0.5 * np.sqrt(np.einsum("ij,ij->i", normals, normals)).mean()
    near = _nearest_centroids(out.reshape(-1, 3)[rows], grid.cells[5][:, :3],
                              _centroid_grid(grid.cells[5][:, :3], k, area), k)
    # each patch's triangles in increasing order (canonical CSR: the rows' sums in _frames
    # run in that order), the nearest one's place among them
    first = near[:, 0]
    near = np.sort(near, axis=1)
    nearest = np.argmax(near == first[:, None], axis=1)
    vec = np.take(normals, near, axis=0)                                    # (M, k, 3)
    size = np.sqrt(np.einsum("mkd,mkd->mk", vec, vec))
    unit = vec / np.maximum(size, 1e-300)[..., None]
    pick = np.arange(len(rows))
    facing = np.einsum("mkd,md->mk", unit, unit[pick, nearest]) > FACING
    if not (size[pick, nearest] > 0).all():
        raise InputError("a triangle of the surface near a pulled fibre point has no area",
                         where="mesh", fix="Repair the mesh (degenerate triangles).")
    # the triangles in any patch, in order, and each patch's columns among them
    mark = np.zeros(len(f), bool)
    mark[near] = True
    used = np.flatnonzero(mark)
    index = np.cumsum(mark) - 1
    counts = np.zeros(len(rows) + 1, np.int64)
    np.cumsum(facing.sum(axis=1), out=counts[1:])
    patches = sp.csr_matrix((np.ones(counts[-1]), index[near[facing]], counts),
                            shape=(len(rows), len(used)))
    frames, side = _frames(v, f[used], patches, index[first], normals[used])
    coefficients = np.einsum("md,mkd->mk", e[rows], frames) / side[:, None]
    return CarriedPull((n, p), rows, f[used], patches, index[first], coefficients,
                       (v, np.einsum("mk,mkd->md", coefficients, frames)))


def planned_pull(plan, key, rest_points, grid: SurfaceGrid | None = None) -> CarriedPull:
    """The `CarriedPull` of the rest pose of ``plan`` (a `fibres.slicing.harmonic.HarmonicPlan`)
    for the fibres named by ``key`` (`fibres.slicing.harmonic.maps_key`), made once
    (``rest_points()``: those fibres mapped onto the plan's rest vertices) and kept with the
    plan (`HarmonicPlan.cached`). ``grid``: the plan's rest surface already prepared with
    `CONTAIN_REACH`, if at hand."""
    return plan.cached(("carried pull",) + tuple(key),
                       lambda: carry_rest_pull(rest_points(), plan.rest_vertices, plan.faces,
                                               grid=grid, normals=plan.face_normals()))
