"""Harmonic-field slicing: template slices mapped onto the isolines of a harmonic field.

The decomposition of Modenese & Kohout (Ann. Biomed. Eng. 48:1793-1804, 2020; Kohout's
later LHPBuilder pipeline) replaces the parallel planes of Kohout et al. (GRAPP 2012) by the
isolines of a harmonic scalar field between the attachment areas (Dong, Kircher & Garland,
CAGD 22, 2005). Here, step by step:

1. **Patches and field** (rest pose, once): the landmarks become surface patches
   (`fibres.attachments.patch`); the field is 0 on the origin patch, 1 on the insertion patch
   and harmonic elsewhere (`fibres.slicing.harmonic_field`). The field is a material property: it
   is kept per vertex in the `HarmonicPlan`, so a deformed frame needs no new solve and its
   isolines are the same material curves (`fibres.slicing.isolines`).
   Steps 2-5 are in `fibres.slicing.harmonic_sections`.
2. **Levels** (`_levels`): the R - 1 inner slices of a fibre of resolution R sit at field
   levels whose isolines' centroids are evenly spaced along the muscle (a harmonic field is
   not proportional to length: it changes fast where a fan narrows); the fibre's two ends
   lie on the patches.
3. **One loop per level**: where an isoline has several loops (a saddle of the field: a
   patch in several pieces), the longest is kept and a note says so.
4. **Cross-section frame**: each loop's centroid ``c`` and unit normal ``n`` (its vector
   area; loops of a field turn the same way round it, so all normals point towards the
   insertion). The axis ``e1`` is the major axis of the middle loop (its sign by the
   muscle's shape, `fibres.fit.box.shape_sign`, so that neither the frame nor the mesh's
   numbering changes it; the plan keeps it), carried to the other loops by parallel
   transport (projection onto each next loop's plane); ``e2 = n x e1``.
5. **Square <-> loop**: each loop is sampled at `SAMPLES` points of equal arc length from a
   *seam*: on the middle loop, its point towards the square's corner (0, 0) in the frame
   ``(e1, e2)``; on every other loop, the cyclic shift whose samples best match the previous
   loop's in the least-squares sense (`fibres.slicing.harmonic_sections`: a seam carried by one
   nearest point let the samples slide back and forth between loops). Sample k
   corresponds to the point at k / SAMPLES of the perimeter of a rectangle with the loop's
   aspect (its extents along e1 and e2), counter-clockwise from (0, 0), scaled to the unit
   square: the square's sides go to the loop's sides, also for a flat muscle. A template
   point ``(x, y)`` of the slice is first spread by area over the membrane (below), to
   ``(x*, y*)``, and goes to ``sum_k lambda_k(x*, y*) S_k``: its mean value coordinates (Hormann & Floater, ACM TOG 25(4), 2006) with respect
   to the square's samples applied to the loop's -- a 3D generalisation of Kohout 2012
   §3.3 without planarisation: the map spans the loop like a membrane. The spreading by
   area is a Knothe-Rosenblatt map in the square's own coordinates, the mass of each cell
   of a 16 x 16 grid being the area of its image on the membrane
   (`fibres.attachments.patch_map.grid_area_map`): one-to-one whatever the membrane's shape. Seam and arc
   lengths change continuously from loop to loop, so fibres do not jump between slices.
6. **Fibre ends spread over the patches** (`fibres.attachments.patch_map`): each fibre's place on the
   first (last) inner membrane, projected on that loop's frame, is carried onto the whole
   patch by area and in order: its Knothe-Rosenblatt coordinates under the membrane's
   projected area (`kr_coordinates`) go through the patch's Knothe-Rosenblatt map in the
   same frame (`area_points`). On a straight cylinder the membranes and the caps have the
   same projected measure, so fibres stay straight; on a muscle every part of the patch
   gets ends. The ends are then spread more evenly by a few Lloyd steps on the patch
   (`fibres.attachments.patch_map.relax_on_patch`: a quasi-random set of 100 ends left 15 % of a
   gluteus medius origin more than 5 mm from an end), and each end's shift is carried along
   its fibre, fading linearly to the other end (where both ends shift alike, as on a
   straight cylinder, the fibre stays straight). The end's offset from the fibre's own course (its first inner segment
   continued) is spread over the fibre's first (last) `END_BEND`, so fibres turn towards
   their place on the patch without hooking (`_bend_to_ends`). The points are then put at
   equal arc-length steps of each rest fibre (`_even`): a slice that hugs a patch leaves
   no stub segment.
7. The template's cross-section coordinates are first normalised by the extent of its whole
   family at the same curve parameter (a grid of `_ENVELOPE` x `_ENVELOPE` fibres): the
   field already follows the muscle's fans and bends, so the template gives the fibres'
   arrangement across the section (their order and relative places), not their course; a
   fan, curved or pennate template is not fanned, bent or slanted a second time (pennation
   then comes from the patches: aponeurosis landmarks). Template heights below the first or
   above the last inner slice are clamped onto it.

8. **Fairing** (`fibres.finishing.fairing`): Taubin's lambda|mu smoothing, a cubic spline
   through the smoothed points and P points on it at equal steps of arc length plus turning
   (a bend gets points in proportion to how much it turns), a (P, P) matrix per fibre
   measured at rest.

Every fibre point is then a fixed linear combination of the vertices (loop samples are
edge points, ends are points of patch triangles, bending, smoothing and resampling are fixed
blends), frozen in the plan: ``points = F W V`` on any deformed copy. The containment pull
(`fibres.finishing.containment`) follows, its displacement spread along each fibre
(`fibres.finishing.fairing.spread_pull`) and pulled again.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
import threading

import numpy as np
import scipy.sparse as sp

from ..attachments.patch import attachment_patches, face_normals
from ..errors import InputError
from .harmonic_field import harmonic_field, mesh_edges
from .harmonic_sections import SAMPLES, _Slices, _levels, _slices  # noqa: F401
from .mvc import mean_value_coordinates
from ..attachments.patch_map import area_points, grid_area_map, kr_coordinates, relax_on_patches
from ..finishing.fairing import fairing_operator, taubin_pairs

__all__ = ["HarmonicPlan", "make_harmonic_plan", "harmonic_points", "maps_key", "SAMPLES"]

#: template fibres per side of the grid that measures the family's extent (step 7)
_ENVELOPE = 11
#: grid cells per side of the square that triangulate a membrane for its area measure
_MEMBRANE = 16
#: share of a fibre over which it bends towards its ends (`_bend_to_ends`)
END_BEND = 0.2


@dataclass(frozen=True)
class _Faces:
    faces: np.ndarray
    n_vertices: int


@dataclass(frozen=True, eq=False)
class HarmonicPlan:
    """The rest-pose choices of a harmonic-field decomposition (module docstring).

    Attributes
    ----------
    faces : (T, 3) int64
    rest_vertices : (V, 3) float
    field : (V,) float
        The harmonic field, 0 on the origin patch, 1 on the insertion patch.
    origin, insertion : (V,) bool
        The patches.
    origin_faces, insertion_faces : (T,) bool
    rest_origin, rest_insertion : (K, 3) float
        The rest landmarks (metres).
    notes : tuple of str
        What the patches and the field did (far landmarks, pieces).
    """

    faces: np.ndarray
    rest_vertices: np.ndarray
    field: np.ndarray
    origin: np.ndarray
    insertion: np.ndarray
    origin_faces: np.ndarray
    insertion_faces: np.ndarray
    rest_origin: np.ndarray
    rest_insertion: np.ndarray
    edges: np.ndarray = field(repr=False)
    face_edges: np.ndarray = field(repr=False)
    notes: tuple = ()
    _cache: dict = field(default_factory=dict, repr=False, compare=False)
    _lock: object = field(default_factory=threading.RLock, repr=False, compare=False)

    slicing = "harmonic"

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_cache"], state["_lock"] = {}, None
        return state

    def __setstate__(self, state):
        state["_lock"] = threading.RLock()
        self.__dict__.update(state)

    def cached(self, key, make):
        """The value kept under ``key`` (hashable) with this plan, ``make()`` the first time:
        what a plan derives for one set of fibres (their maps, the rest pose's pull) is made
        once, by one thread (the others wait), and lives as long as the plan; a pickled plan
        leaves it behind."""
        with self._lock:
            hit = self._cache.get(key)
            if hit is None:
                hit = self._cache[key] = make()
            return hit

    def face_normals(self):
        """(T, 3) face normals of the rest surface scaled by twice the face areas
        (`fibres.attachments.patch.face_normals`), kept with the plan."""
        return self.cached(("face normals",), lambda: face_normals(self.rest_vertices,
                                                                   self.faces))

    @property
    def topology(self):
        """The faces and vertex count (what `fibres.decompose` checks a frame against)."""
        return _Faces(self.faces, len(self.rest_vertices))

    def check_mesh(self, vertices, faces) -> None:
        """Refuse a mesh that is not a deformed copy of the plan's."""
        if (np.shape(vertices) != self.rest_vertices.shape
                or np.shape(faces) != self.faces.shape
                or not np.array_equal(faces, self.faces)):
            raise InputError("the mesh does not match the plan's (same faces, same number of "
                             "vertices)", where="mesh", fix="Pass a deformed copy of the mesh "
                             "the plan was made on.")


def make_harmonic_plan(vertices, faces, origin, insertion, *, topology=None) -> HarmonicPlan:
    """Patches and harmonic field of a rest-pose surface (metres); ``topology``: the faces'
    `fibres.slicing.planes.MeshTopology` when at hand (its edges are `mesh_edges`' own)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if topology is not None and (topology.faces is f or np.array_equal(topology.faces, f)):
        edges, face_edges = topology.edges.copy(), topology.face_edges.copy()   # writeable
    else:
        edges, face_edges = mesh_edges(f, len(v))
    normals = face_normals(v, f)
    patches = attachment_patches(v, f, origin, insertion, edges, normals=normals)
    u = harmonic_field(v, f, patches.origin, patches.insertion, edges=edges,
                       face_edges=face_edges)
    plan = HarmonicPlan(f, v, u, patches.origin, patches.insertion, patches.origin_faces,
                        patches.insertion_faces, np.asarray(origin, float),
                        np.asarray(insertion, float), edges, face_edges, patches.notes)
    plan.cached(("face normals",), lambda: normals)
    return plan


# -- template points to the muscle ----------------------------------------------------------

def _normalised(tmpl, unit, t):
    """Template cross-section coordinates normalised by the family's extent at each curve
    parameter (module docstring, step 7); (N, P) X, Y and heights z."""
    g = np.linspace(0.0, 1.0, _ENVELOPE)
    grid = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    family = tmpl._points(grid, t)                                   # (G, P, 3)
    lo = family[..., :2].min(axis=0)                                 # (P, 2)
    hi = family[..., :2].max(axis=0)
    xy = (unit[..., :2] - lo) / np.maximum(hi - lo, 1e-12)
    xy = np.clip(xy, 1e-4, 1.0 - 1e-4)
    return xy[..., 0], xy[..., 1], np.clip(unit[..., 2], 0.0, 1.0)


def _membrane_grid():
    """The grid of the square that triangulates a membrane: nodes ((G + 1)^2, 2), node
    ``(a, b)`` at ``(a, b) / G`` the ``a (G + 1) + b``-th, and cell triangles (2 G^2, 3):
    cell ``(a, b)``'s halves ``(a, b), (a + 1, b), (a + 1, b + 1)`` (the first G^2, cells
    in order) and ``(a, b), (a + 1, b + 1), (a, b + 1)``."""
    g = np.linspace(0.0, 1.0, _MEMBRANE + 1)
    nodes = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    a_, b_ = np.meshgrid(np.arange(_MEMBRANE), np.arange(_MEMBRANE), indexing="ij")
    n00 = (a_ * (_MEMBRANE + 1) + b_).reshape(-1)
    cells = np.concatenate([np.stack([n00, n00 + _MEMBRANE + 1, n00 + _MEMBRANE + 2], 1),
                            np.stack([n00, n00 + _MEMBRANE + 2, n00 + 1], 1)])
    return nodes, cells


_NODES, _CELLS = _membrane_grid()


def _rectangles(k: int, shares) -> np.ndarray:
    """(L, k, 2) square samples of the loops (module docstring, step 5): for each loop's
    share, the k points of the unit square's boundary, counter-clockwise from (0, 0), evenly
    spaced on the perimeter of a rectangle whose sides along x take that share of its
    perimeter (clipped to [0.02, 0.98])."""
    w = np.clip(np.asarray(shares, dtype=np.float64), 0.02, 0.98)[:, None]
    phi = np.arange(k) / k
    # the four sides' starts along the perimeter, and each sample's side
    bounds = np.stack(np.broadcast_arrays(0.0, w / 2, 0.5, 0.5 + w / 2, 1.0), axis=-1)
    side = np.sum(bounds[:, :, :4] <= phi[:, None], axis=-1) - 1            # (L, k)
    start = np.take_along_axis(bounds[:, 0], side, axis=1)
    f = (phi - start) / (np.take_along_axis(bounds[:, 0, 1:], side, axis=1) - start)
    out = np.empty(side.shape + (2,))
    out[..., 0] = np.choose(side, [f, 1.0, 1.0 - f, 0.0])
    out[..., 1] = np.choose(side, [0.0, f, 1.0, 1.0 - f])
    return out


def _membranes(polygons, rest):
    """The loops' membranes at rest (step 5's area measure): the grid's nodes mapped by
    each loop's mean value coordinates (w.r.t. ``polygons`` (L, K, 2), applied to the loop
    samples ``rest`` (L, K, 3)), (L, (G + 1)^2, 3), and the areas of the images of the
    cell triangles (`_membrane_grid`), (L, 2 G^2)."""
    n_loops, m, g = len(polygons), len(_NODES), _MEMBRANE
    lam = mean_value_coordinates(np.tile(_NODES, (n_loops, 1)), polygons,
                                 np.repeat(np.arange(n_loops), m))
    nodes = lam.reshape(n_loops, m, -1) @ rest
    grid = nodes.reshape(n_loops, g + 1, g + 1, 3)
    p00, p10, p11, p01 = grid[:, :-1, :-1], grid[:, 1:, :-1], grid[:, 1:, 1:], grid[:, :-1, 1:]
    area = np.empty((n_loops, 2, g, g))
    for half, (d1, d2) in enumerate(((p10 - p00, p11 - p00), (p11 - p00, p01 - p00))):
        (ax, ay, az), (bx, by, bz) = np.moveaxis(d1, -1, 0), np.moveaxis(d2, -1, 0)
        area[:, half] = 0.5 * np.sqrt((ay * bz - az * by) ** 2 + (az * bx - ax * bz) ** 2
                                      + (ax * by - ay * bx) ** 2)
    return nodes, area.reshape(n_loops, -1)


def _spread(polygons, area, loop, pts):
    """MVC weights (M, K) of the points of the square that spread ``pts`` (M, 2) evenly by
    area over the membranes of their loops ``loop`` (M,): Knothe-Rosenblatt in the square's
    own coordinates with the area of each grid cell's image as its mass
    (`fibres.attachments.patch_map.grid_area_map`, all loops in one call; the map in a
    projection of the membrane jumped between the sheets of a folded projection:
    docs/decisions.md)."""
    half = _MEMBRANE * _MEMBRANE
    mass = (area[:, :half] + area[:, half:]).reshape(-1, _MEMBRANE, _MEMBRANE)
    square = np.stack(grid_area_map(mass, pts[:, 0], pts[:, 1], loop), axis=1)
    return mean_value_coordinates(np.clip(square, 1e-6, 1.0 - 1e-6), polygons, loop)


def _fibre_matrix(plan: HarmonicPlan, slices: _Slices, tmpl, rs, resolution):
    """The fibre points' linear map at rest, before bending and even steps: sparse
    ``loops`` (N * P, L * SAMPLES) of the loop samples and ``verts`` (N * P, V) of the
    vertices; sparse ``post`` (N * P, N * P) of the bending and even steps (`_bend_to_ends`,
    `_even`); and ``y`` (N * P, 3) = ``loops @ samples + verts @ vertices`` at rest: the
    rest points are ``post @ y``."""
    n = len(rs)
    p = resolution + 1
    t = np.linspace(0.0, 1.0, p)
    unit = tmpl._points(rs, t)                                       # (N, P, 3)
    X, Y, z = _normalised(tmpl, unit, t)
    z[:, 0], z[:, -1] = 0.0, 1.0
    k = SAMPLES
    n_loops = slices.centres.shape[0]
    xy = np.stack([X, Y], axis=-1)                                   # (N, P, 2)
    polygons = _rectangles(k, slices.shares)
    samples = slices.samples @ plan.rest_vertices
    rest = samples.reshape(n_loops, k, 3)
    memb, area = _membranes(polygons, rest)

    # inner points: the membranes of the two loops around their height, blended (heights
    # before the first or after the last inner slice are clamped onto it); each point on
    # its two loops (weights 1 - a and a; zero weights left out), in row order
    pos = np.clip(z[:, 1:-1] * resolution - 1.0, 0.0, n_loops - 1.0).reshape(-1)
    j0 = np.clip(np.floor(pos).astype(np.int64), 0, max(n_loops - 2, 0))
    a = pos - j0
    wpair = np.stack([1.0 - a, a], axis=1)                          # (n_in, 2)
    use = np.flatnonzero(wpair.reshape(-1) > 0)
    pt = use // 2
    jj = np.stack([j0, np.minimum(j0 + 1, n_loops - 1)], axis=1).reshape(-1)[use]
    # the spread of all of them and of the fibre ends on the first / last inner membrane
    lam = _spread(polygons, area,
                  np.concatenate([jj, np.zeros(n, np.int64), np.full(n, n_loops - 1)]),
                  np.concatenate([xy[:, 1:-1].reshape(-1, 2)[pt], xy[:, 0], xy[:, -1]]))
    m = len(jj)
    per_row = np.zeros((n, p), dtype=np.int64)
    per_row[:, 1:-1] = np.bincount(pt, minlength=a.size).reshape(n, p - 2) * k
    loops = _csr((lam[:m] * wpair.reshape(-1)[use, None]).reshape(-1),
                 (jj.astype(_INDEX)[:, None] * k + np.arange(k, dtype=_INDEX)).reshape(-1),
                 per_row, (n * p, n_loops * k))
    # ends: the fibres' places on the first / last inner membrane, projected on its frame,
    # carried onto the whole patch by area and in order (the membrane's projected area
    # measure onto the patch's, Knothe-Rosenblatt both ways: fibres.attachments.patch_map); the
    # fibres then bend towards them (_bend_to_ends)
    ends = []
    for e, (mask, patch, j) in enumerate(((plan.origin_faces, plan.origin, 0),
                                          (plan.insertion_faces, plan.insertion, n_loops - 1))):
        if not mask.any():
            mask = patch[plan.faces].any(axis=1)
        e1 = slices.axes[j]
        e2 = np.cross(slices.normals[j], e1)
        c = slices.centres[j]
        on = lam[m + e * n:m + (e + 1) * n] @ rest[j] - c
        tri = memb[j][_CELLS] - c
        px, py = tri @ e1, tri @ e2
        ex, ey = kr_coordinates(px, py, area[j], on @ e1, on @ e2, samples=area.shape[1])
        ends.append((mask, *area_points(plan.rest_vertices, plan.faces, mask, c, e1, e2,
                                        ex, ey)))
    relaxed = relax_on_patches(plan.rest_vertices, plan.faces, ends)   # both at once
    verts = _end_rows(plan.faces, len(plan.rest_vertices), n, p, ends, relaxed)
    # bending and even steps: (N P, N P) maps of the points, composed (small)
    bend = _bend_to_ends(n, p)
    y = loops @ samples + verts @ plan.rest_vertices
    return loops, verts, (_even((bend @ y).reshape(n, p, 3)) @ bend).tocsr(), y


#: index type of the sparse maps (their sizes are far below 2^31): scipy's own choice, made
#: here so that it need not scan the indices to find it
_INDEX = np.int32


def _csr(data, indices, lengths, shape):
    """CSR matrix of ``shape`` from its rows' entries back to back (``data``, column
    ``indices`` of type `_INDEX`, in order within each row) and the rows' entry counts
    ``lengths`` (any shape, rows in C order)."""
    indptr = np.zeros(lengths.size + 1, dtype=_INDEX)
    np.cumsum(lengths.reshape(-1), out=indptr[1:])
    return sp.csr_matrix((data, indices, indptr), shape=shape)


def _end_rows(faces, n_vertices, n, p, ends, relaxed):
    """Sparse (N P, V) vertex weights of the fibre points: each end the corners of its
    relaxed patch triangle (``relaxed``), each inner point the ends' relaxation shifts
    (relaxed minus first place, ``ends``), carried along the whole fibre and fading linearly
    to the other end: where both ends move alike (a straight cylinder) fibres stay straight.
    Rows in order: an end's 3 entries, an inner point's 12 (four triangles' corners)."""
    per = 6 + 12 * (p - 2)
    data, index = np.empty((n, per)), np.empty((n, per), dtype=_INDEX)
    # views of the inner points' entries (splitting the last axis: no copies)
    inner_v = data[:, 3:per - 3].reshape(n, p - 2, 12)
    inner_i = index[:, 3:per - 3].reshape(n, p - 2, 12)
    fades = np.linspace(1.0, 0.0, p)[1:-1], np.linspace(0.0, 1.0, p)[1:-1]
    for e, ((_, face, bary), (moved, mbary)) in enumerate(zip(ends, relaxed)):
        at = slice(0, 3) if e == 0 else slice(per - 3, per)
        data[:, at], index[:, at] = mbary, faces[moved]
        for s, (fc, bc, sign) in enumerate(((moved, mbary, 1.0), (face, bary, -1.0))):
            at = slice(6 * e + 3 * s, 6 * e + 3 * s + 3)
            inner_v[:, :, at] = (sign * bc)[:, None, :] * fades[e][None, :, None]
            inner_i[:, :, at] = faces[fc][:, None, :]
    lengths = np.full((n, p), 12)
    lengths[:, 0] = lengths[:, -1] = 3
    return _csr(data.reshape(-1), index.reshape(-1), lengths, (n * p, n_vertices))


@lru_cache(maxsize=8)
def _bend_to_ends(n, p):
    """Sparse (N P, N P) matrix bending each fibre gradually towards its ends: the offset
    ``delta = E - (2 P_1 - P_2)`` of the end E from the fibre's own course continued one
    segment is added to the inner points at ``q`` segments from that end with weight
    ``(1 - q / B)^2`` (B = `END_BEND` of the points, at least 3): where an attachment patch
    lies to the side of the fibres' course (a strip along the muscle's edge), the fibres
    turn towards it over several segments instead of hooking in the last one. One matrix
    per (N, P), shared: not to be changed in place."""
    bend = max(3.0, END_BEND * (p - 1))
    block = np.eye(p)                                              # one fibre's (P, P)
    for end, one, two, sign in ((0, 1, 2, 1), (p - 1, p - 2, p - 3, -1)):
        if p < 3:
            break
        for q in range(1, p - 1):
            g = (1.0 - q / bend) ** 2 if q < bend else 0.0
            if g <= 0.0:
                break
            r = q if sign > 0 else p - 1 - q
            for c, w in ((end, g), (one, -2.0 * g), (two, g)):
                block[r, c] += w
    rr, cc = np.nonzero(block)
    return _csr(np.tile(block[rr, cc], n), (np.arange(n)[:, None] * p + cc).reshape(-1).astype(
        _INDEX), np.tile(np.bincount(rr, minlength=p), n), (n * p, n * p))


def _even(points):
    """Sparse (N P, N P) matrix putting each fibre's points at equal arc-length steps of its
    rest polyline (each new point a fixed blend of two consecutive old ones, so the result
    stays a linear map of the vertices): a slice that lies very near a patch leaves no stub
    segment at the fibre's end."""
    n, p, _ = points.shape
    seg = np.linalg.norm(np.diff(points, axis=1), axis=2)            # (N, P - 1)
    cum = np.concatenate([np.zeros((n, 1)), np.cumsum(seg, axis=1)], axis=1)
    total = np.maximum(cum[:, -1:], 1e-300)
    target = np.linspace(0.0, 1.0, p)[None] * total                  # (N, P)
    c = cum + 1e-15 * total * np.arange(p)[None]                      # strictly increasing
    k = np.clip((target[:, :, None] >= c[:, None, :]).sum(axis=2) - 1, 0, p - 2)   # (N, P)
    lo = np.take_along_axis(c, k, axis=1)
    hi = np.take_along_axis(c, k + 1, axis=1)
    w = np.clip((target - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)
    first = np.arange(n)[:, None, None] * p + k[:, :, None] + np.arange(2)   # (N, P, 2)
    return _csr(np.stack([1.0 - w, w], axis=-1).reshape(-1), first.reshape(-1).astype(_INDEX),
                np.full(n * p, 2), (n * p, n * p))


def maps_key(tmpl, n_fibres, resolution, seed, smoothing) -> tuple:
    """The fibres a plan's cached maps are for (`HarmonicPlan.cached`): template (name and
    parameters), count, resolution, seed and smoothing."""
    from ..plan import template_spec
    spec = template_spec(tmpl)
    return (spec[0], repr(sorted(dict(spec[1]).items())), int(n_fibres), int(resolution),
            int(seed), int(smoothing))


def _maps(plan: HarmonicPlan, tmpl, n_fibres, resolution, seed, smoothing):
    """(slices, loops, verts, post, fair, rs, rest points) for these fibres, made once per
    plan and cached: the points of vertices V are ``fair @ (post @ (loops @ samples V +
    verts @ V))`` (`_fibre_matrix`'s maps before bending, then bending and even steps, then
    the fairing, both (N P, N P)); the rest points (N, P, 3) are the rest pose's."""
    from ..template.sampling import sobol_rs

    def make():
        slices = plan.cached(("slices", int(resolution)), lambda: _slices(plan, int(resolution)))
        rs = sobol_rs(int(n_fibres), seed=seed)
        loops, verts, post, y = _fibre_matrix(plan, slices, tmpl, rs, int(resolution))
        bent = post @ y
        fair = fairing_operator(bent.reshape(len(rs), -1, 3),
                                iterations=taubin_pairs(smoothing))
        return slices, loops, verts, post, fair, rs, (fair @ bent).reshape(len(rs), -1, 3)
    return plan.cached(maps_key(tmpl, n_fibres, resolution, seed, smoothing), make)


def harmonic_points(plan: HarmonicPlan, vertices, tmpl, n_fibres, resolution, seed,
                    smoothing=0):
    """Fibre points (N, R + 1, 3) of the surface ``vertices`` (the plan's rest pose or a
    deformed copy), faired (step 8: Taubin smoothing, `fibres.finishing.fairing.taubin_pairs`
    of ``smoothing``, then
    the turn-aware resampling of `fibres.finishing.fairing`, frozen at rest) but not yet
    contained; also returns rs (N, 2) and notes."""
    slices, loops, verts, post, fair, rs, rest = _maps(plan, tmpl, n_fibres, resolution, seed,
                                                       smoothing)
    v = np.asarray(vertices, dtype=np.float64)
    if v is plan.rest_vertices or np.array_equal(v, plan.rest_vertices):
        return rest.copy(), rs, slices.notes
    pts = fair @ (post @ (loops @ (slices.samples @ v) + verts @ v))
    return pts.reshape(len(rs), int(resolution) + 1, 3), rs, slices.notes
