"""Harmonic-field slicing: template slices mapped onto the isolines of a harmonic field.

The decomposition of Modenese & Kohout (Ann. Biomed. Eng. 48:1793-1804, 2020; Kohout's
later LHPBuilder pipeline) replaces the parallel planes of Kohout et al. (GRAPP 2012) by the
isolines of a harmonic scalar field between the attachment areas (Dong, Kircher & Garland,
CAGD 22, 2005). Here, step by step:

1. **Patches and field** (rest pose, once): the landmarks become surface patches
   (`fibres.attachment_patch`); the field is 0 on the origin patch, 1 on the insertion patch
   and harmonic elsewhere (`fibres.harmonic_field`). The field is a material property: it
   is kept per vertex in the `HarmonicPlan`, so a deformed frame needs no new solve and its
   isolines are the same material curves (`fibres.isolines`).
2. **Levels** (`_levels`): the R - 1 inner slices of a fibre of resolution R sit at field
   levels whose isolines' centroids are evenly spaced along the muscle (a harmonic field is
   not proportional to length: it changes fast where a fan narrows); the fibre's two ends
   lie on the patches.
3. **One loop per level**: where an isoline has several loops (a saddle of the field: a
   patch in several pieces), the longest is kept and a note says so.
4. **Cross-section frame**: each loop's centroid ``c`` and unit normal ``n`` (its vector
   area; loops of a field turn the same way round it, so all normals point towards the
   insertion). The axis ``e1`` is the major axis of the middle loop (its sign by a rule on
   the vertex numbering, so it is material), carried to the other loops by parallel
   transport (projection onto each next loop's plane); ``e2 = n x e1``.
5. **Square <-> loop**: each loop is sampled at `SAMPLES` points of equal arc length from a
   *seam*: on the middle loop, its point towards the square's corner (0, 0) in the frame
   ``(e1, e2)``; on every other loop, the point nearest to the previous loop's seam (the
   field's flow lines cross the isolines at right angles, so the seam follows one). Sample k
   corresponds to the point at k / SAMPLES of the perimeter of a rectangle with the loop's
   aspect (its extents along e1 and e2), counter-clockwise from (0, 0), scaled to the unit
   square: the square's sides go to the loop's sides, also for a flat muscle. A template
   point ``(x, y)`` of the slice goes to ``sum_k lambda_k(x, y)
   S_k``: its mean value coordinates (Hormann & Floater, ACM TOG 25(4), 2006) with respect
   to the square's samples applied to the loop's -- a 3D generalisation of Kohout 2012
   §3.3 without planarisation: the map spans the loop like a membrane. Seam and arc
   lengths change continuously from loop to loop, so fibres do not jump between slices.
6. **Fibre ends spread over the patches** (`fibres.patch_map`): the template's origin and
   insertion coordinates go onto the whole patches by area and order-preserving (a
   Knothe-Rosenblatt map in the frame of the first / last inner loop, so the ends line up
   with the fibres' places in the sections); the end's offset from the fibre's own course
   (its first inner segment continued) is spread over the fibre's first (last) `END_BEND`,
   so fibres turn towards their place on the patch without hooking (`_bend_to_ends`). The
   points are then put at equal arc-length steps of each rest fibre (`_even`): a slice that
   hugs a patch leaves no stub segment.
7. The template's cross-section coordinates are first normalised by the extent of its whole
   family at the same curve parameter (a grid of `_ENVELOPE` x `_ENVELOPE` fibres): the
   field already follows the muscle's fans and bends, so the template gives the fibres'
   arrangement across the section (their order and relative places), not their course; a
   fan, curved or pennate template is not fanned, bent or slanted a second time (pennation
   then comes from the patches: aponeurosis landmarks). Template heights below the first or
   above the last inner slice are clamped onto it.

Every fibre point is then a fixed linear combination of the vertices (loop samples are
edge points, ends are points of patch triangles, bending and resampling are fixed blends),
frozen in the plan: ``points = W V`` on any deformed copy. Smoothing and the containment
pull (`fibres.containment`) follow as for the planar method.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import threading

import numpy as np
import scipy.sparse as sp

from .attachment_patch import attachment_patches
from .errors import InputError
from .harmonic_field import harmonic_field, mesh_edges
from .isolines import isoline_loops, isoline_moments
from .mvc import mean_value_coordinates
from .patch_map import area_points, knothe_rosenblatt, locate

__all__ = ["HarmonicPlan", "make_harmonic_plan", "harmonic_points", "SAMPLES"]

#: loop samples per level (a multiple of 4: the square's corners are samples)
SAMPLES = 64
#: template fibres per side of the grid that measures the family's extent (step 7)
_ENVELOPE = 11
#: grid cells per side of the square that triangulate a membrane for its area measure
_MEMBRANE = 16
#: share of a fibre over which it bends towards its ends (`_bend_to_ends`)
END_BEND = 0.3
#: candidate levels (x 2) searched for the slice levels
_CANDIDATES = 96
#: field level of the patches' rim loops
_RIM = 1e-6


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
    _lock: object = field(default_factory=threading.Lock, repr=False, compare=False)

    slicing = "harmonic"

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_cache"], state["_lock"] = {}, None
        return state

    def __setstate__(self, state):
        state["_lock"] = threading.Lock()
        self.__dict__.update(state)

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


def make_harmonic_plan(vertices, faces, origin, insertion) -> HarmonicPlan:
    """Patches and harmonic field of a rest-pose surface (metres)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    edges, face_edges = mesh_edges(f, len(v))
    patches = attachment_patches(v, f, origin, insertion, edges)
    u = harmonic_field(v, f, patches.origin, patches.insertion, edges=edges,
                       face_edges=face_edges)
    return HarmonicPlan(f, v, u, patches.origin, patches.insertion, patches.origin_faces,
                        patches.insertion_faces, np.asarray(origin, float),
                        np.asarray(insertion, float), edges, face_edges, patches.notes)


# -- levels, loops, frames ------------------------------------------------------------------

def _levels(plan: HarmonicPlan, resolution: int) -> np.ndarray:
    """(R + 1,) field levels whose isolines' centroids are evenly spaced along the muscle.

    The centroid C(t) and vector area of the whole isoline are measured at `_CANDIDATES`
    levels (evenly spaced, and at the area quantiles of the field, which resolve the levels
    where the muscle is; `fibres.isolines.isoline_moments`). Progress along the muscle is
    the centroid's advance along the isolines' mean normal, ``ds = max(0, dC . n)``: an
    isoline sweeping back through a dead end beyond a patch (the field is flat there) makes
    no progress and gets no slice. The R - 1 inner levels divide s evenly."""
    v, u, f = plan.rest_vertices, plan.field, plan.faces
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    uc = u[f].mean(axis=1)
    order = np.argsort(uc, kind="stable")
    cum = np.cumsum(area[order])
    q = np.interp(np.linspace(0, 1, _CANDIDATES), cum / cum[-1], uc[order])
    cand = np.unique(np.concatenate([q, np.linspace(0.0, 1.0, _CANDIDATES)]))
    cand = cand[(cand > 2 * _RIM) & (cand < 1 - 2 * _RIM)]
    cand = np.concatenate([[_RIM], cand, [1 - _RIM]])
    length, centre, _ = isoline_moments(u, v, f, cand)
    ok = length > 0
    cand, centre = cand[ok], centre[ok]
    step = np.diff(centre, axis=0)
    ahead = np.einsum("ij,ij->i", step, centre[-1] - centre[:-1]) > 0
    ds = np.where(ahead, np.linalg.norm(step, axis=1), 0.0)
    s = np.concatenate([[0.0], np.cumsum(ds)])
    s = s + 1e-12 * np.arange(s.size)                     # strictly increasing
    levels = np.interp(np.linspace(0.0, s[-1], resolution + 1), s, cand)
    levels[0], levels[-1] = _RIM, 1.0 - _RIM
    levels[1:-1] = np.clip(levels[1:-1], 2 * _RIM, 1 - 2 * _RIM)
    return levels


def _loop_frame(points):
    """(centroid, unit normal, segment lengths) of a closed loop."""
    nxt = np.roll(points, -1, axis=0)
    seg = np.linalg.norm(nxt - points, axis=1)
    total = seg.sum()
    c = (0.5 * (points + nxt) * seg[:, None]).sum(axis=0) / total if total > 0 \
        else points.mean(axis=0)
    area = 0.5 * np.cross(points - c, nxt - c).sum(axis=0)
    norm = np.linalg.norm(area)
    n = area / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
    return c, n, seg


def _major_axis(points, c, n, loop):
    d = points - c
    d = d - np.outer(d @ n, n)
    vals, vecs = np.linalg.eigh(d.T @ d)
    e1 = vecs[:, -1]
    # material sign: the vertex numbering rides along with a deformed copy
    if np.dot((loop.a + 1.0), d @ e1) < 0:
        e1 = -e1
    return e1


def _transport(e1, n):
    p = e1 - np.dot(e1, n) * n
    norm = np.linalg.norm(p)
    if norm < 1e-9:
        return None
    return p / norm


def _rectangle_samples(k: int, share: float) -> np.ndarray:
    """(k, 2) points of the unit square's boundary, counter-clockwise from (0, 0), evenly
    spaced on the perimeter of a rectangle whose sides along x take ``share`` of its
    perimeter (the loop's aspect: ``a / (a + b)`` for extents a along e1, b along e2)."""
    w = min(max(float(share), 0.02), 0.98)
    phi = np.arange(k) / k
    out = np.empty((k, 2))
    bounds = np.array([0.0, w / 2, 0.5, 0.5 + w / 2, 1.0])
    side = np.searchsorted(bounds, phi, side="right") - 1
    f = (phi - bounds[side]) / np.diff(bounds)[side]
    out[:, 0] = np.choose(side, [f, np.ones_like(f), 1 - f, np.zeros_like(f)])
    out[:, 1] = np.choose(side, [np.zeros_like(f), f, np.ones_like(f), 1 - f])
    return out


def _position_point(points, pos):
    m = len(points)
    i = int(np.floor(pos)) % m
    f = pos - np.floor(pos)
    return (1.0 - f) * points[i] + f * points[(i + 1) % m]


def _closest_position(points, q) -> float:
    """Fractional loop position (node + fraction) of the closed polyline's point nearest q."""
    a = points
    b = np.roll(points, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", q - a, ab) / np.maximum(
        np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
    d = np.linalg.norm(a + t[:, None] * ab - q, axis=1)
    k = int(np.argmin(d))
    return k + float(t[k])


def _arc_positions(seg, start, k):
    """(k,) fractional loop positions (node + fraction) that divide the closed loop with
    segment lengths ``seg`` into k equal arcs from the position ``start``."""
    m = len(seg)
    i0 = int(np.floor(start)) % m
    f0 = start - np.floor(start)
    # segment lengths in loop order from the start, the first one split there
    order = (np.arange(m) + i0) % m
    seg = seg[order]
    head = seg[0] * (1.0 - f0)
    cum = np.concatenate([[0.0, head], head + np.cumsum(seg[1:])])
    cum = np.append(cum, cum[-1] + seg[0] * f0)                  # back at the start
    pos = np.concatenate([[start], i0 + 1.0 + np.arange(m), [start + m]])
    cum = cum + 1e-15 * cum[-1] * np.arange(cum.size)            # strictly increasing
    target = np.arange(k) / k * cum[-1]
    return np.interp(target, cum, pos) % m


@dataclass(frozen=True)
class _Slices:
    """The loops of one resolution: per level (L = R + 1), `SAMPLES` loop samples as a sparse
    (L * SAMPLES, V) matrix of vertex weights, the frames at rest, and notes."""

    samples: sp.csr_matrix
    centres: np.ndarray
    normals: np.ndarray
    axes: np.ndarray
    shares: np.ndarray
    notes: tuple


def _slices(plan: HarmonicPlan, resolution: int) -> _Slices:
    levels = _levels(plan, max(int(resolution), 2))[1:-1]
    if resolution < 2:  # one segment: the ends still come from a middle membrane
        levels = levels[:1]
    v = plan.rest_vertices
    loops, notes = [], []
    for j, t in enumerate(levels):
        found = isoline_loops(plan.field, plan.faces, t, plan.edges, plan.face_edges, v)
        if not found:
            raise InputError("the harmonic field has no isoline at a slice level",
                             where="mesh", fix="Check the attachment landmarks.")
        if len(found) > 1:
            notes.append(f"slice {j}: {len(found)} isoline loops, the longest kept")
        loops.append(found[0])
    pts = [lp.points(v) for lp in loops]
    frames = [_loop_frame(p) for p in pts]
    centres = np.array([f[0] for f in frames])
    normals = np.array([f[1] for f in frames])
    mid = len(loops) // 2
    axes = np.zeros_like(centres)
    axes[mid] = _major_axis(pts[mid], centres[mid], normals[mid], loops[mid])
    for rng in (range(mid + 1, len(loops)), range(mid - 1, -1, -1)):
        prev = mid
        for j in rng:
            e = _transport(axes[prev], normals[j])
            axes[j] = e if e is not None else axes[prev]
            prev = j
    # positions along each loop by arc length from a seam that starts at the middle loop's
    # point towards the square's corner (0, 0) and is carried to each next loop by its nearest
    # point (the field's flow lines cross its isolines at right angles)
    e2m = np.cross(normals[mid], axes[mid])
    d = pts[mid] - centres[mid]
    x, y = d @ axes[mid], d @ e2m
    score = -x / max(np.ptp(x), 1e-12) - y / max(np.ptp(y), 1e-12)
    seams = [0.0] * len(loops)
    seams[mid] = float(np.argmax(score))
    for rng in (range(mid + 1, len(loops)), range(mid - 1, -1, -1)):
        prev = mid
        for j in rng:
            q = _position_point(pts[prev], seams[prev])
            seams[j] = _closest_position(pts[j], q)
            prev = j
    shares = np.empty(len(loops))
    rows, cols, vals = [], [], []
    for j, (lp, p) in enumerate(zip(loops, pts)):
        d = p - centres[j]
        a, b = np.ptp(d @ axes[j]), np.ptp(d @ np.cross(normals[j], axes[j]))
        shares[j] = a / max(a + b, 1e-300)
        seg = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
        pos = _arc_positions(seg, seams[j], SAMPLES)
        i0 = np.floor(pos).astype(np.int64) % len(lp)
        f = pos - np.floor(pos)
        i1 = (i0 + 1) % len(lp)
        r = j * SAMPLES + np.arange(SAMPLES)
        for idx, wgt in ((i0, 1.0 - f), (i1, f)):
            rows += [r, r]
            cols += [lp.a[idx], lp.b[idx]]
            vals += [wgt * (1.0 - lp.s[idx]), wgt * lp.s[idx]]
    mat = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                        shape=(len(loops) * SAMPLES, len(v)))
    return _Slices(mat, centres, normals, axes, shares, tuple(notes))


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

    def lam(j, pts):
        """MVC weights of the points of the square that spread ``pts`` evenly by area over
        loop j's membrane (Knothe-Rosenblatt in the loop's frame, as at the patches)."""
        pts = pts.reshape(-1, 2)
        memb = mean_value_coordinates(nodes, polygons[j]) @ rest[j]        # (G+1)^2 x 3
        e1 = slices.axes[j]
        e2 = np.cross(slices.normals[j], e1)
        tri = memb[cells]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                                    axis=1)
        px, py = (tri - slices.centres[j]) @ e1, (tri - slices.centres[j]) @ e2
        xs, ys = knothe_rosenblatt(px, py, area, pts[:, 0], pts[:, 1], samples=len(cells))
        pick, bary = locate(px, py, xs, ys)
        square = np.einsum("nk,nkd->nd", bary, nodes[cells[pick]])
        return mean_value_coordinates(np.clip(square, 1e-6, 1.0 - 1e-6), polygons[j])

    rows, cols, vals = [], [], []
    rid = np.arange(n * p).reshape(n, p)
    kk = np.arange(k)
    # inner points: the membranes of the two loops around their height, blended (heights
    # before the first or after the last inner slice are clamped onto it)
    if p > 2:
        pos = np.clip(z[:, 1:-1] * resolution - 1.0, 0.0, n_loops - 1.0).reshape(-1)
        j0 = np.clip(np.floor(pos).astype(np.int64), 0, max(n_loops - 2, 0))
        a = pos - j0
        j1 = np.minimum(j0 + 1, n_loops - 1)
        r_in = rid[:, 1:-1].reshape(-1)
        xy_in = xy[:, 1:-1].reshape(-1, 2)
        for jj, wj in ((j0, 1.0 - a), (j1, a)):
            use = wj > 0
            for j in np.unique(jj[use]):
                sel = np.flatnonzero(use & (jj == j))
                rows.append(np.repeat(r_in[sel], k))
                cols.append((j * k + np.broadcast_to(kk, (sel.size, k))).reshape(-1))
                vals.append((lam(j, xy_in[sel]) * wj[sel, None]).reshape(-1))
    # ends: the template's end coordinates onto the whole patch by area, in the first / last
    # inner loop's frame (fibres.patch_map), the fibres then bent towards them (_bend_to_ends)
    for col, mask, patch, j in ((0, plan.origin_faces, plan.origin, 0),
                                (p - 1, plan.insertion_faces, plan.insertion, n_loops - 1)):
        if not mask.any():
            mask = patch[plan.faces].any(axis=1)
        e1 = slices.axes[j]
        face, bary = area_points(plan.rest_vertices, plan.faces, mask, slices.centres[j], e1,
                                 np.cross(slices.normals[j], e1), xy[:, col, 0], xy[:, col, 1])
        rows.append(np.repeat(rid[:, col], 3))
        cols.append(base + plan.faces[face].reshape(-1))
        vals.append(bary.reshape(-1))
    n_cols = base + len(plan.rest_vertices)
    mat = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                        shape=(n * p, n_cols))
    mat = _bend_to_ends(n, p) @ mat
    rest_pts = (mat @ np.concatenate([slices.samples @ plan.rest_vertices,
                                      plan.rest_vertices])).reshape(n, p, 3)
    return _even(rest_pts) @ mat


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
    rows, cols, vals = [], [], []
    for f in range(n):
        c = cum[f] + 1e-15 * total[f, 0] * np.arange(p)
        k = np.clip(np.searchsorted(c, target[f], side="right") - 1, 0, p - 2)
        w = np.clip((target[f] - c[k]) / np.maximum(c[k + 1] - c[k], 1e-300), 0.0, 1.0)
        r = f * p + np.arange(p)
        rows += [r, r]
        cols += [f * p + k, f * p + k + 1]
        vals += [1.0 - w, w]
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n * p, n * p))


def _maps(plan: HarmonicPlan, tmpl, n_fibres, resolution, seed):
    """(slices, fibre matrix, rs) for these fibres, made once per plan and cached."""
    from .plan import template_spec
    from .sampling import sobol_rs
    spec = template_spec(tmpl)
    key = (spec[0], repr(sorted(dict(spec[1]).items())), int(n_fibres), int(resolution),
           int(seed))
    with plan._lock:
        hit = plan._cache.get(key)
        if hit is not None:
            return hit
        slices = plan._cache.get(("slices", int(resolution)))
        if slices is None:
            slices = _slices(plan, int(resolution))
            plan._cache[("slices", int(resolution))] = slices
        rs = sobol_rs(int(n_fibres), seed=seed)
        mat = _fibre_matrix(plan, slices, tmpl, rs, int(resolution))
        plan._cache[key] = (slices, mat, rs)
        return plan._cache[key]


def harmonic_points(plan: HarmonicPlan, vertices, tmpl, n_fibres, resolution, seed):
    """Fibre points (N, R + 1, 3) of the surface ``vertices`` (the plan's rest pose or a
    deformed copy), before smoothing; also returns rs (N, 2) and notes."""
    slices, mat, rs = _maps(plan, tmpl, n_fibres, resolution, seed)
    v = np.asarray(vertices, dtype=np.float64)
    basis = np.concatenate([slices.samples @ v, v])
    pts = (mat @ basis).reshape(len(rs), int(resolution) + 1, 3)
    return pts, rs, slices.notes
