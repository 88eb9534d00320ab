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
import threading

import numpy as np
import scipy.sparse as sp

from ..attachments.patch import attachment_patches, face_normals
from ..errors import InputError
from .harmonic_field import harmonic_field, mesh_edges
from .harmonic_sections import SAMPLES, _Slices, _levels, _rectangle_samples, _slices  # noqa: F401
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


def _fibre_matrix(plan: HarmonicPlan, slices: _Slices, tmpl, rs, resolution):
    """Sparse (N * P, L * SAMPLES + V) matrix: fibre points from [loop samples; vertices]."""
    n = len(rs)
    p = resolution + 1
    t = np.linspace(0.0, 1.0, p)
    unit = tmpl._points(rs, t)                                       # (N, P, 3)
    X, Y, z = _normalised(tmpl, unit, t)
    z[:, 0], z[:, -1] = 0.0, 1.0
    k = SAMPLES
    n_loops = slices.centres.shape[0]
    base = n_loops * k
    xy = np.stack([X, Y], axis=-1)                                   # (N, P, 2)
    polygons = [_rectangle_samples(k, share) for share in slices.shares]

    rest = (slices.samples @ plan.rest_vertices).reshape(n_loops, k, 3)
    # the membranes at rest, triangulated on a grid of the square (step 5's area measure)
    g = np.linspace(0.0, 1.0, _MEMBRANE + 1)
    nodes = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    a_, b_ = np.meshgrid(np.arange(_MEMBRANE), np.arange(_MEMBRANE), indexing="ij")
    n00 = (a_ * (_MEMBRANE + 1) + b_).reshape(-1)
    cells = np.concatenate([np.stack([n00, n00 + _MEMBRANE + 1, n00 + _MEMBRANE + 2], 1),
                            np.stack([n00, n00 + _MEMBRANE + 2, n00 + 1], 1)])

    membranes = {}

    def membrane(j):
        """Loop j's membrane at rest: its grid nodes (3D) and cell triangles' areas."""
        if j not in membranes:
            memb = mean_value_coordinates(nodes, polygons[j]) @ rest[j]    # (G+1)^2 x 3
            tri = memb[cells]
            (ax, ay, az), (bx, by, bz) = (tri[:, 1] - tri[:, 0]).T, (tri[:, 2] - tri[:, 0]).T
            area = 0.5 * np.sqrt((ay * bz - az * by) ** 2 + (az * bx - ax * bz) ** 2
                                 + (ax * by - ay * bx) ** 2)
            membranes[j] = (tri, area)
        return membranes[j]

    def lam(j, pts):
        """MVC weights of the points of the square that spread ``pts`` evenly by area over
        loop j's membrane: Knothe-Rosenblatt in the square's own coordinates with the area
        of each grid cell's image as its mass (`fibres.attachments.patch_map.grid_area_map`; the map in
        a projection of the membrane jumped between the sheets of a folded projection:
        docs/decisions.md)."""
        pts = pts.reshape(-1, 2)
        area = membrane(j)[1]
        half = _MEMBRANE * _MEMBRANE
        xs, ys = grid_area_map((area[:half] + area[half:]).reshape(_MEMBRANE, _MEMBRANE),
                               pts[:, 0], pts[:, 1])
        square = np.stack([xs, ys], axis=1)
        return mean_value_coordinates(np.clip(square, 1e-6, 1.0 - 1e-6), polygons[j])

    rows, cols, vals = [], [], []
    rid = np.arange(n * p).reshape(n, p)
    kk = np.arange(k)
    n_cols = base + len(plan.rest_vertices)
    inner = sp.csr_matrix((n * p, n_cols))
    # inner points: the membranes of the two loops around their height, blended (heights
    # before the first or after the last inner slice are clamped onto it)
    if p > 2:
        pos = np.clip(z[:, 1:-1] * resolution - 1.0, 0.0, n_loops - 1.0).reshape(-1)
        j0 = np.clip(np.floor(pos).astype(np.int64), 0, max(n_loops - 2, 0))
        a = pos - j0
        j1 = np.minimum(j0 + 1, n_loops - 1)
        xy_in = xy[:, 1:-1].reshape(-1, 2)
        # each point on its two loops (weights 1 - a and a; zero weights left out), the
        # membrane map of each loop evaluated once for all its points; row by row in
        # sparse-row order (loop j0's samples, then loop j1's: j0 < j1 when there are two
        # loops; with one, the weight on j1 is 0), so the matrix needs no sorting
        jj = np.concatenate([j0, j1])
        wj = np.concatenate([1.0 - a, a])
        pt = np.concatenate([np.arange(a.size), np.arange(a.size)])
        use = np.flatnonzero(wj > 0)
        jj, wj, pt, side = jj[use], wj[use], pt[use], use // a.size
        blocks = np.zeros((a.size, 2, k))
        for j in np.unique(jj):
            sel = np.flatnonzero(jj == j)
            blocks[pt[sel], side[sel]] = lam(j, xy_in[pt[sel]]) * wj[sel, None]
        at = np.stack([j0, j1], axis=1)[:, :, None] * k + kk                  # (n_in, 2, k)
        counts = np.zeros((n, p), dtype=np.int64)
        counts[:, 1:-1] = 2 * k
        inner = sp.csr_matrix((blocks.reshape(-1), at.reshape(-1),
                               np.concatenate([[0], np.cumsum(counts.reshape(-1))])),
                              shape=(n * p, n_cols))
        inner.eliminate_zeros()
    # ends: the fibres' places on the first / last inner membrane, projected on its frame,
    # carried onto the whole patch by area and in order (the membrane's projected area
    # measure onto the patch's, Knothe-Rosenblatt both ways: fibres.attachments.patch_map); the fibres
    # then bend towards them (_bend_to_ends)
    ends = []
    for col, mask, patch, j in ((0, plan.origin_faces, plan.origin, 0),
                                (p - 1, plan.insertion_faces, plan.insertion, n_loops - 1)):
        if not mask.any():
            mask = patch[plan.faces].any(axis=1)
        e1 = slices.axes[j]
        e2 = np.cross(slices.normals[j], e1)
        tri, area = membrane(j)
        on = lam(j, xy[:, col]) @ rest[j] - slices.centres[j]
        X, Y = kr_coordinates((tri - slices.centres[j]) @ e1, (tri - slices.centres[j]) @ e2,
                              area, on @ e1, on @ e2, samples=len(area))
        ends.append((mask, *area_points(plan.rest_vertices, plan.faces, mask, slices.centres[j],
                                        e1, e2, X, Y)))
    relaxed = relax_on_patches(plan.rest_vertices, plan.faces, ends)   # both at once
    for col, (_, face, bary), (moved, mbary) in zip((0, p - 1), ends, relaxed):
        rows.append(np.repeat(rid[:, col], 3))
        cols.append(base + plan.faces[moved].reshape(-1))
        vals.append(mbary.reshape(-1))
        # the ends' relaxation shift, carried along the whole fibre and fading linearly to
        # the other end: where both ends move alike (a straight cylinder) fibres stay straight
        if p > 2:
            fade = np.linspace(1.0, 0.0, p)[1:-1] if col == 0 else np.linspace(0.0, 1.0, p)[1:-1]
            for fc, bc, sign in ((moved, mbary, 1.0), (face, bary, -1.0)):
                rows.append(np.repeat(rid[:, 1:-1].reshape(-1), 3))
                cols.append(np.repeat(base + plan.faces[fc], p - 2, axis=0).reshape(-1))
                vals.append((sign * np.repeat(bc, p - 2, axis=0)
                             * np.tile(fade, n)[:, None]).reshape(-1))
    mat = inner + sp.csr_matrix((np.concatenate(vals),
                                 (np.concatenate(rows), np.concatenate(cols))),
                                shape=(n * p, n_cols))
    # bending and even steps are (N P, N P) maps of the points: composed first (small), then
    # applied to the map of the vertices in one sparse product
    bend = _bend_to_ends(n, p)
    rest_pts = (bend @ (mat @ np.concatenate([slices.samples @ plan.rest_vertices,
                                              plan.rest_vertices]))).reshape(n, p, 3)
    return (_even(rest_pts) @ bend) @ mat


def _bend_to_ends(n, p):
    """Sparse (N P, N P) matrix bending each fibre gradually towards its ends: the offset
    ``delta = E - (2 P_1 - P_2)`` of the end E from the fibre's own course continued one
    segment is added to the inner points at ``q`` segments from that end with weight
    ``(1 - q / B)^2`` (B = `END_BEND` of the points, at least 3): where an attachment patch
    lies to the side of the fibres' course (a strip along the muscle's edge), the fibres
    turn towards it over several segments instead of hooking in the last one."""
    bend = max(3.0, END_BEND * (p - 1))
    rows, cols, vals = [np.arange(n * p)], [np.arange(n * p)], [np.ones(n * p)]
    base = np.arange(n) * p
    for end, one, two, sign in ((0, 1, 2, 1), (p - 1, p - 2, p - 3, -1)):
        if p < 3:
            break
        for q in range(1, p - 1):
            g = (1.0 - q / bend) ** 2 if q < bend else 0.0
            if g <= 0.0:
                break
            r = base + (q if sign > 0 else p - 1 - q)
            for c, w in ((end, g), (one, -2.0 * g), (two, g)):
                rows.append(r)
                cols.append(base + c)
                vals.append(np.full(n, w))
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n * p, n * p))


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
    r = np.arange(n * p)
    first = (np.arange(n)[:, None] * p + k).reshape(-1)
    return sp.csr_matrix((np.concatenate([(1.0 - w).reshape(-1), w.reshape(-1)]),
                          (np.concatenate([r, r]), np.concatenate([first, first + 1]))),
                         shape=(n * p, n * p))


def maps_key(tmpl, n_fibres, resolution, seed, smoothing) -> tuple:
    """The fibres a plan's cached maps are for (`HarmonicPlan.cached`): template (name and
    parameters), count, resolution, seed and smoothing."""
    from ..plan import template_spec
    spec = template_spec(tmpl)
    return (spec[0], repr(sorted(dict(spec[1]).items())), int(n_fibres), int(resolution),
            int(seed), int(smoothing))


def _maps(plan: HarmonicPlan, tmpl, n_fibres, resolution, seed, smoothing):
    """(slices, fibre matrix, fairing matrix, rs) for these fibres, made once per plan and
    cached."""
    from ..template.sampling import sobol_rs

    def make():
        slices = plan.cached(("slices", int(resolution)), lambda: _slices(plan, int(resolution)))
        rs = sobol_rs(int(n_fibres), seed=seed)
        mat = _fibre_matrix(plan, slices, tmpl, rs, int(resolution))
        rest = (mat @ np.concatenate([slices.samples @ plan.rest_vertices,
                                      plan.rest_vertices])).reshape(len(rs), -1, 3)
        fair = fairing_operator(rest, iterations=taubin_pairs(smoothing))
        return slices, mat, fair, rs
    return plan.cached(maps_key(tmpl, n_fibres, resolution, seed, smoothing), make)


def harmonic_points(plan: HarmonicPlan, vertices, tmpl, n_fibres, resolution, seed,
                    smoothing=0):
    """Fibre points (N, R + 1, 3) of the surface ``vertices`` (the plan's rest pose or a
    deformed copy), faired (step 8: Taubin smoothing, `fibres.finishing.fairing.taubin_pairs`
    of ``smoothing``, then
    the turn-aware resampling of `fibres.finishing.fairing`, frozen at rest) but not yet
    contained; also returns rs (N, 2) and notes."""
    slices, mat, fair, rs = _maps(plan, tmpl, n_fibres, resolution, seed, smoothing)
    v = np.asarray(vertices, dtype=np.float64)
    basis = np.concatenate([slices.samples @ v, v])
    pts = (fair @ (mat @ basis)).reshape(len(rs), int(resolution) + 1, 3)
    return pts, rs, slices.notes
