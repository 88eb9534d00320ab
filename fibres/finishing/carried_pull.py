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

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

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
    # the centroids (a + b + c) / 3 of the grid's binning; an unbalanced tree (sliding
    # midpoint) builds in half the time, compact nodes and larger leaves answer these queries
    # faster; its queries are exact
    k = min(CARRY_CANDIDATES, len(f))
    tree = cKDTree(grid.cells[5][:, :3], leafsize=32, balanced_tree=False, compact_nodes=True)
    near = np.asarray(tree.query(out.reshape(-1, 3)[rows], k=k)[1]).reshape(len(rows), k)
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
