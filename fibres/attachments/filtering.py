"""Fibre filtering near wide attachment areas: trimming and reconstruction (Kohout 2012 §3.4).

Morphed fibres tend to converge on one point at a wide attachment instead of spreading over it.
Kohout et al. cut every fibre with two planes perpendicular to the principal axis passing
through the extreme landmarks (the origin landmark farthest along the axis, the insertion
landmark least far along it), throw away the parts beyond the planes and replace each by ONE
new segment from the cut point to the surface point of the attachment area closest to the ray
that continues the last kept segment.

Attachment area on the surface (our reading of "the part of the surface cut out at the contour
of the projected landmarks"): every landmark is projected to its nearest surface vertex; the
area is the set of surface vertices within ``r`` of a projected landmark, where r is the median
distance between neighbouring landmarks (at least the mean edge length of the surface), plus
the projections themselves. For one landmark the area is its projection and that vertex's
neighbourhood of radius r = mean edge length. The area's SURFACE is the faces whose three
corners are all in the area, plus each area vertex on no such face as a point.

The new end point ("a new point such that it lies on the surface of muscle, in the insertion
area, and is closest the ray defined by the segment (P_m-1, P_m)", §3.4) is the point of the
area's surface closest to the ray from the cut point along the last kept segment (t >= 0):
the first hit where the ray hits the area (Moeller-Trumbore), else the closest point between
the ray and the area's triangles (their interiors, edges or vertices). Not a vertex: on a flat
end cap whose only vertices are its centre and its rim, a straight fibre ends where its own
line meets the cap and stays straight (the closest VERTEX kinks it towards the centre or the
rim: 0.16 % of its length on the analytic cylinder of tests/analysis/test_run_cylinders.py).

Fibres that were cut are resampled uniformly by arc length so every fibre keeps P points;
untouched fibres are returned unchanged.

Ties. A fibre end lying ON a cutting plane (flat end caps: a cube, a cylinder) is not beyond
it: heights within ``TIE`` times the surface's bounding-box diagonal of a plane count as on
it, so rounding cannot decide whether a fibre is trimmed.

Frozen decisions (our addition for motions). The filter makes discrete choices: the extreme
landmark of each set, which fibres are cut and in which segment, the attachment-area point
each new end goes to, and which piece (new end segment or kept fibre) each resampled point
falls on. `filter_choices` makes them on the rest pose and returns them as a `FilterChoice`;
`apply_filter` re-applies them to a deformed copy (same topology, same fibres): the planes
go through the SAME landmarks along the current axis, each cut stays in its rest segment
(its position in it follows the current plane), the new end is the same material point
(a triangle and barycentric coordinates in it) and every resampled point keeps its piece
and its parameter there (a fraction
of the new segment, or a fractional fibre index between the two cuts). Every output point is
then a smooth function of the morphed fibre, the surface and the landmarks; on the rest pose
it is the paper's arc-length resampling (to rounding). No KD-tree or search per frame.

Rays (our departure from the paper, `filter_choices(reference=...)`). The paper's ray
continues the last kept MORPHED segment; near a wide attachment the morph bends the fibres
towards the narrow end of the muscle (the very convergence this filter is meant to undo), so
their rays meet the area on one side: gluteus medius' fibres left one end of the
iliac crest empty (largest landmark-to-fibre-start gap 22.5 mm). When `reference` (the same
fibres mapped affinely into the fitted box, i.e. the template's own directions) is given, a
fibre whose reference ray HITS the area ends there; the others keep the paper's ray. The gap
falls to 15.8 mm (gluteus maximus 58 -> 45 mm; iliacus and psoas unchanged, 19 and 11 mm).
The choice is made once on the rest pose (a material point), so motions stay smooth.

Inside the surface (measured on the LHDL hip muscles, 100 fibres x 16 points): the morph
keeps points within 1.5 mm of the surface; after this filter (no smoothing) up to 4.2 mm lie
outside, from two sources that are the method's own: (1) the straight new segment from the
cut point to the attachment area crosses concave parts of the surface when the cutting plane
is far from the area (segments of 44-96 mm on glut_med / iliacus); (2) resampled points on
the kept part lie on chords between morphed points, which cut concave walls for fibres
running along the surface (up to 3.4 mm, iliacus / psoas). We keep the paper's straight
segment and chords here; `fibres.finishing.containment` pulls the points that end outside back in
after smoothing (`fibres.decompose`; then every point is within 0.2 mm).

Cutting planes. "Two cutting planes perpendicular to the principal axis passing through the
extremal (in the direction of the principal axis) landmarks" (§3.4): we take, for the
origin, the landmark farthest along the axis towards the insertion (and the reverse for the
insertion), so every fibre loses its whole stretch alongside the area, as in the paper's
Fig. 9. Tried and not kept: the other extreme (planes through the landmarks farthest from
the other attachment) keeps the morph's convergence, every gluteus medius fibre then starts
at the crest's top (landmark gap 108 mm); per-fibre planes through the innermost landmark
above each fibre kept fibres converging to the top as well (gap 36 mm).

Code. The attachment area and its triangles are `fibres.attachments.area`, the area's
closest point to a ray `fibres.attachments.ray_triangles`.
`filter_choices` and `apply_filter` are written step by step in numpy (no compiled passes:
docs/decisions.md, issue 13).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .filter_pieces import evaluate_pieces, record_resampling, untouched
from .area import _mean_edge, _region_indices, attachment_region, regions_triangles
from .ray_triangles import closest_on_triangles
from ..plan import _readonly

__all__ = ["trim_and_reconstruct", "attachment_region", "FilterChoice", "filter_choices",
           "apply_filter", "TIE"]

#: heights within TIE x (bounding-box diagonal of the surface) of a cutting plane are on it
TIE = 1e-9
#: on a deformed copy the cut may move past the ends of its rest segment by at most this
#: fraction of the segment (extrapolated along it) -- a guard for segments turning parallel
#: to the plane; the rest pose always has 0 <= s <= 1
CUT_SLACK = 0.5


@dataclass(frozen=True)
class FilterChoice:
    """The discrete choices of the attachment filter for N fibres of P points (rest pose).

    Attributes
    ----------
    landmarks : (2,) int
        Index of the extreme origin landmark and of the extreme insertion landmark (the
        cutting planes pass through them).
    cut : (N, 2) bool
        The origin (column 0) / insertion (column 1) end of the fibre is cut and rebuilt.
    segment : (N, 2) int
        First point index of the fibre segment containing the cut.
    cut_param : (N, 2) float
        Position of the cut in its segment on the rest pose (0..1).
    target_face : (N, 2) int
        Surface triangle holding the rebuilt end (-1 where not cut).
    target_vertices : (N, 2, 3) int
        That triangle's corners (the rows of ``faces``; 0 where not cut).
    target_bary : (N, 2, 3) float
        Barycentric coordinates of the rebuilt end in its triangle (a material point:
        ``sum_k target_bary[..., k] * vertices[target_vertices[..., k]]``).
    piece : (N, P) int8
        Where each output point lies: 0 on the new origin segment, 1 on the kept fibre,
        2 on the new insertion segment.
    param : (N, P) float
        Fraction along the new segment (0: surface end for piece 0, cut point for piece 2),
        or along the kept fibre from the origin cut (0) to the insertion cut (1), measured
        in fibre-index units.
    seed : int
        Sobol seed of the fibres (the choices hold for fibres 0..N-1 of that seed).
    template : tuple or None
        ``(name, params)`` of the fibre template.
    """

    landmarks: np.ndarray
    cut: np.ndarray
    segment: np.ndarray
    cut_param: np.ndarray
    target_face: np.ndarray
    target_vertices: np.ndarray
    target_bary: np.ndarray
    piece: np.ndarray
    param: np.ndarray
    seed: int = 0
    template: tuple | None = None

    def __post_init__(self):
        for name, dt in (("landmarks", np.int64), ("cut", bool), ("segment", np.int64),
                         ("cut_param", np.float64), ("target_face", np.int64),
                         ("target_vertices", np.int64), ("target_bary", np.float64),
                         ("piece", np.int8),
                         ("param", np.float64)):
            object.__setattr__(self, name, _readonly(getattr(self, name), dt))
        n = self.cut.shape[0]
        if self.landmarks.shape != (2,):
            raise ValueError("landmarks must be (2,)")
        for name in ("cut", "segment", "cut_param", "target_face"):
            if getattr(self, name).shape != (n, 2):
                raise ValueError(f"{name} must be (N, 2) = ({n}, 2)")
        for name in ("target_vertices", "target_bary"):
            if getattr(self, name).shape != (n, 2, 3):
                raise ValueError(f"{name} must be (N, 2, 3) = ({n}, 2, 3)")
        if self.piece.ndim != 2 or self.piece.shape[0] != n or self.param.shape != self.piece.shape:
            raise ValueError("piece and param must be (N, P)")

    @classmethod
    def _owned(cls, landmarks, cut, segment, cut_param, target_face, target_vertices,
               target_bary, piece, param, seed=0, template=None) -> "FilterChoice":
        """The choices from arrays made for them (`filter_choices`: the fields' dtypes and
        shapes, referenced nowhere else): made read-only in place instead of copied."""
        self = object.__new__(cls)
        for name, a in zip(_ARRAYS, (landmarks, cut, segment, cut_param, target_face,
                                     target_vertices, target_bary, piece, param)):
            a.flags.writeable = False
            object.__setattr__(self, name, a)
        object.__setattr__(self, "seed", int(seed))
        object.__setattr__(self, "template", template)
        return self

    @property
    def n_fibres(self) -> int:
        """N."""
        return int(self.cut.shape[0])

    @property
    def n_points(self) -> int:
        """P."""
        return int(self.piece.shape[1])

    def head(self, n: int) -> "FilterChoice":
        """The choices of the first ``n`` fibres (Sobol fibre k is the same for any N > k)."""
        return FilterChoice(self.landmarks, self.cut[:n], self.segment[:n], self.cut_param[:n],
                            self.target_face[:n], self.target_vertices[:n],
                            self.target_bary[:n], self.piece[:n], self.param[:n], self.seed,
                            self.template)


#: the array fields of FilterChoice, in order
_ARRAYS = ("landmarks", "cut", "segment", "cut_param", "target_face", "target_vertices",
           "target_bary", "piece", "param")


def _vertices_faces(surface):
    if hasattr(surface, "vertices") and hasattr(surface, "faces"):
        return np.asarray(surface.vertices, float), np.asarray(surface.faces, np.int64)
    v, f = surface
    return np.asarray(v, float), np.asarray(f, np.int64)


def _planes(origin, insertion, u, landmarks=None):
    """Heights of the two cutting planes along u and the landmarks they pass through."""
    if landmarks is None:
        landmarks = np.array([np.argmax(origin @ u), np.argmin(insertion @ u)])
    return float(origin[landmarks[0]] @ u), float(insertion[landmarks[1]] @ u), landmarks


def _cuts(pts, h, segment, level, fallback, slack):
    """Cut parameter s in each fibre's segment (level - h_a) / (h_b - h_a) and the cut point
    p_a + s (p_b - p_a); s within [-slack, 1 + slack], ``fallback`` for a segment parallel to
    the plane. Returns (s (N,), point (N, 3))."""
    rows = np.arange(len(pts))
    ha, hb = h[rows, segment], h[rows, segment + 1]
    dh = hb - ha
    ok = np.abs(dh) > 1e-12 * (np.abs(ha) + np.abs(hb) + 1e-300)
    s = np.where(ok, (level - ha) / np.where(ok, dh, 1.0), fallback)
    s = np.clip(s, -slack, 1.0 + slack)
    a = pts[rows, segment]
    return s, a + s[:, None] * (pts[rows, segment + 1] - a)


def filter_choices(points, surface, origin, insertion, axis, *, seed: int = 0,
                   template=None, mean_edge: float | None = None,
                   reference=None, prepared=None) -> FilterChoice:
    """Make the attachment filter's choices on one (rest-pose) decomposition.

    Kohout et al. (GRAPP 2012) §3.4: cutting planes through the extreme landmarks, the
    attachment-area surface point closest to the ray of the last kept segment, uniform arc-length
    resampling of [new end, cut, kept points, cut, new end] (module docstring).

    Parameters
    ----------
    points : (N, P, 3) float
        Fibres from the origin (index 0) to the insertion (index P-1).
    surface : Surface or (vertices (V, 3), faces (T, 3))
    origin, insertion : (K, 3) float
        Attachment landmarks.
    axis : (3,) float
        Principal axis pointing from origin to insertion.
    seed : int, keyword-only
    template : (name, params) or None, keyword-only
        Recorded with the choices (which fibres they belong to).
    mean_edge : float, optional, keyword-only
        Mean length of the surface's face edges when already known (e.g. from
        `fibres.mesh.surface.clean_mesh_geometry`); computed when None.
    reference : (N, P, 3) float, optional, keyword-only
        The same fibres before the morph (the template mapped affinely into the fitted
        box): the rays then follow the reference fibre's segment at the cut instead of the
        morphed one (module docstring, "Rays"); None: the paper's morphed segment.
    prepared : fibres.fit.fitting.Prepared, optional, keyword-only
        `fibres.fit.fitting.prepare` of exactly these vertices when at hand (its transposed
        vertices and bounds; speed only: the same choices).

    Returns
    -------
    FilterChoice
    """
    pts = np.asarray(points, dtype=np.float64)
    n, p = pts.shape[:2]
    u = np.asarray(axis, dtype=np.float64)
    u = u / np.linalg.norm(u)
    origin = np.asarray(origin, float).reshape(-1, 3)
    insertion = np.asarray(insertion, float).reshape(-1, 3)
    verts, faces = _vertices_faces(surface)
    h_o, h_i, lms = _planes(origin, insertion, u)
    if n == 0 or p < 2 or h_o >= h_i:  # overlapping attachment bands: nothing sensible to cut
        return FilterChoice._owned(lms, *untouched(n, p), seed, template)
    if prepared is None:
        vt = np.ascontiguousarray(verts.T)                             # (3, V)
        tol = TIE * float(np.linalg.norm(vt.max(axis=1) - vt.min(axis=1)))
    else:
        vt = prepared.vt
        tol = TIE * float(np.linalg.norm(prepared.hi - prepared.lo))
    pts = np.ascontiguousarray(pts)
    h = pts @ u                                                       # (N, P)
    cut, segment, cut_param, t_face, t_vert, t_bary, piece, param = untouched(n, p)

    def done():
        return FilterChoice._owned(lms, cut, segment, cut_param, t_face, t_vert, t_bary, piece,
                                   param, seed, template)

    idx = np.arange(p)[None, :]
    below = h < h_o - tol    # beyond the origin plane (not on it)
    above = h > h_i + tol    # beyond the insertion plane
    j_o = np.where(below.any(axis=1), np.where(below, idx, -1).max(axis=1), -1)
    j_i = np.where(above.any(axis=1), np.where(above, idx, p).min(axis=1), p)
    # cut where the fibre truly passes between the planes: at least one point inside
    inside = (h >= h_o - tol) & (h <= h_i + tol)
    ok = inside.any(axis=1) & (j_o < j_i - 1)
    cut[:, 0] = ok & (j_o >= 0)
    cut[:, 1] = ok & (j_i <= p - 1)
    if not cut.any():
        return done()
    segment[:, 0] = np.clip(j_o, 0, p - 2)
    segment[:, 1] = np.clip(j_i, 1, p - 1) - 1
    s_o, c_o = _cuts(pts, h, segment[:, 0], h_o, 0.0, 0.0)
    s_i, c_i = _cuts(pts, h, segment[:, 1], h_i, 0.0, 0.0)
    cut_param[:] = np.stack([s_o, s_i], axis=1)
    mean_edge = _mean_edge(vt, faces) if mean_edge is None else float(mean_edge)
    rows = np.arange(n)
    ref = None if reference is None else np.asarray(reference, dtype=np.float64)
    ends = [end for end in range(2) if cut[:, end].any()]
    # the areas' triangles of both ends with one pass over the faces
    areas = dict(zip(ends, regions_triangles(
        faces, [_region_indices(verts, faces, (origin, insertion)[end], vt, mean_edge)
                for end in ends], len(verts))))
    for end, (landmarks, c, a, b) in enumerate((
            (origin, c_o, segment[:, 0] + 1, segment[:, 0]),     # ray towards the origin
            (insertion, c_i, segment[:, 1], segment[:, 1] + 1))):  # ray towards the insertion
        sel = cut[:, end]
        if sel.any():  # two ends, not a loop over fibres
            corners, owner = areas[end]
            rs, bs, as_, cs = rows[sel], b[sel], a[sel], c[sel]      # indexed once per end
            tv = verts[corners]
            if reference is not None:  # the template's direction where its ray hits the area
                d2 = ref[rs, bs] - ref[rs, as_]
                # only hits matter: rays farther than 2 tol stop early (index -1)
                k2, w2 = closest_on_triangles(tv, cs, d2, within=2 * tol,
                                              corner_ids=corners)
                q = np.einsum("nkc,nk->nc", tv[np.maximum(k2, 0)], w2) - cs
                d2 = d2 / np.linalg.norm(d2, axis=1, keepdims=True)
                along = np.maximum(np.einsum("nc,nc->n", q, d2), 0.0)
                hit = (k2 >= 0) & (np.linalg.norm(q - along[:, None] * d2, axis=1) <= tol)
            if reference is None or not hit.any():  # the paper's ray for every fibre
                k, w = closest_on_triangles(tv, cs, pts[rs, bs] - pts[rs, as_],
                                            corner_ids=corners)
            elif hit.all():
                k, w = k2, w2
            else:  # the paper's ray for the others (each ray on its own)
                k, w = k2, w2
                miss = ~hit
                rm = rs[miss]
                k[miss], w[miss] = closest_on_triangles(
                    tv, cs[miss], pts[rm, bs[miss]] - pts[rm, as_[miss]], corner_ids=corners)
            face = owner[k]
            fv = faces[face]
            # barycentric coordinates on the owning face's corners (a point: all on its slot)
            match = fv[:, :, None] == corners[k][:, None, :]                # (n, 3, 3)
            t_face[sel, end] = face
            t_vert[sel, end] = fv
            t_bary[sel, end] = (match * w[:, None, :]).sum(axis=2)
    record_resampling(pts, verts, cut, segment, cut_param, (t_vert, t_bary), piece, param)
    return done()


def apply_filter(points, vertices, origin, insertion, axis, choice: FilterChoice):
    """Re-apply recorded filter choices to a (deformed) copy of the fibres and surface.

    The planes pass through the recorded landmarks, perpendicular to the current axis; each
    cut lies where the current plane crosses the recorded segment's line (within
    `CUT_SLACK`); the new ends are the recorded material points; each output point keeps
    its recorded piece and parameter (module docstring). Smooth in every input.

    Parameters
    ----------
    points : (N, P, 3) float
        Morphed fibres (N <= choice.n_fibres; the first N choices are used).
    vertices : (V, 3) float
        The surface's vertices (same topology as when the choices were made).
    origin, insertion : (K, 3) float
    axis : (3,) float
    choice : FilterChoice

    Returns
    -------
    points : (N, P, 3) float64
    trimmed, reconstructed : (N,) bool
    """
    pts = np.asarray(points, dtype=np.float64)
    n, p = pts.shape[:2]
    if n > choice.n_fibres or p != choice.n_points:
        raise ValueError(f"the choices are for {choice.n_fibres} fibres x {choice.n_points} "
                         f"points, got {n} x {p}")
    ch = choice.head(n) if n < choice.n_fibres else choice
    sel = ch.cut.any(axis=1)
    out = np.array(pts, copy=True)
    if not sel.any():
        return out, sel.copy(), sel.copy()
    u = np.asarray(axis, dtype=np.float64)
    u = u / np.linalg.norm(u)
    origin = np.asarray(origin, float).reshape(-1, 3)
    insertion = np.asarray(insertion, float).reshape(-1, 3)
    h_o, h_i, _ = _planes(origin, insertion, u, ch.landmarks)
    fib = pts[sel]
    seg, cutf = ch.segment[sel], ch.cut[sel]
    h = fib @ u
    s_o, _ = _cuts(fib, h, seg[:, 0], h_o, ch.cut_param[sel, 0], CUT_SLACK)
    s_i, _ = _cuts(fib, h, seg[:, 1], h_i, ch.cut_param[sel, 1], CUT_SLACK)
    s = np.stack([s_o, s_i], axis=1)
    out[sel] = evaluate_pieces(fib, np.asarray(vertices, float), cutf, seg, s,
                         (ch.target_vertices[sel], ch.target_bary[sel]),
                         ch.piece[sel], ch.param[sel])
    return out, sel.copy(), sel.copy()


def trim_and_reconstruct(points, surface, origin, insertion, axis):
    """Cut fibres at the extreme-landmark planes and rebuild their ends on the attachment areas.

    Kohout et al. (GRAPP 2012) §3.4, vectorised over fibres: `filter_choices` on these
    fibres, then `apply_filter`.

    Parameters
    ----------
    points : (N, P, 3) float
        Fibres running from the origin (index 0) to the insertion (index P-1).
    surface : Surface or (vertices (V,3), faces (T,3))
        The muscle surface.
    origin, insertion : (K, 3) float
        Attachment landmarks.
    axis : (3,) float
        Principal axis pointing from origin to insertion.

    Returns
    -------
    points : (N, P, 3) float64
        Filtered fibres (untouched fibres are returned as they were).
    trimmed : (N,) bool
        A part beyond a cutting plane was removed.
    reconstructed : (N,) bool
        A new end segment was added on an attachment area.
    """
    pts = np.array(points, dtype=np.float64, copy=True)
    if pts.shape[0] == 0 or pts.shape[1] < 2:
        z = np.zeros(pts.shape[0], bool)
        return pts, z, z.copy()
    choice = filter_choices(pts, surface, origin, insertion, axis)
    return apply_filter(pts, _vertices_faces(surface)[0], origin, insertion, axis, choice)
