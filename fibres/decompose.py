"""`decompose`: a closed muscle surface and two attachment sets in, fibre polylines out.

Kohout, Clapworthy, Martelli & Viceconti, "Muscle fibres modelling", GRAPP 2012, Fig. 3:

1. the template (Blemker & Delp 2005) gives fibre polylines in the unit cube at Sobol
   parameters (r, s) (§3.1; `fibres.template.templates`, `fibres.template.sampling`);
2. the cube is fitted to the muscle as a principal-axis OBB whose attachment areas best
   match the landmarks (§3.2; `fibres.fit.fitting`);
3. the fibres are morphed slice by slice into the muscle: planes perpendicular to the axis
   cut the box (a rectangle) and the surface (a contour), the rectangle is subdivided to
   correspond with the contour, and mean value coordinates (Hormann & Floater 2006) carry
   each point from the rectangle to the contour (§3.3; `fibres.slicing.planes`,
   `fibres.slicing.contours`, `fibres.slicing.correspondence`, `fibres.slicing.mvc`, `fibres.slicing.morph`);
4. the fibres are trimmed near the attachment areas and reconstructed to the surface
   (§3.4; `fibres.attachments.filtering`), then smoothed (`fibres.finishing.smoothing`);
5. (our addition) inner points left outside the surface by the straight reconstructed
   segments, the resampling chords and the morph's folds are pulled back in along their
   shortest path, smoothly (`fibres.finishing.containment`).

The discrete choices are recorded in a `DecompositionPlan` (`fibres.plan`) and can be
reused for a deformed copy of the same mesh, so that fibre ``k`` stays the same fibre.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .bundle import FibreBundle
from .finishing.containment import CONTAIN_REACH, contain as contain_points
from .mesh.surface_distance import SurfaceGrid
from .slicing.contours import choose_loops
from .errors import InputError
from .attachments.filtering import apply_filter, filter_choices
from .fit.box import shape_sign
from .fit.fitting import fit_box, prepare, principal_frame, reference_frame
from .slicing.harmonic import HarmonicPlan, harmonic_points, make_harmonic_plan, maps_key
from .slicing.morph import anchored_maps, morph_local, slice_fractions, slice_maps
from .plan import DecompositionPlan, box_and_local, template_spec
from .template.sampling import sobol_rs
from .slicing.planes import mesh_topology, slice_mesh
from .finishing.carried_pull import planned_pull, pull_rounds
from .finishing.smoothing import DECOMPOSE_MAX_SHIFT, DEFAULT_ITERATIONS, smooth
from .mesh.surface import Surface, as_points, as_surface, clean_mesh_geometry
from .template.templates import Template, get_template
from .threads import blas_single

__all__ = ["decompose", "make_plan", "SLICINGS", "DEFAULT_SLICING"]

_AXES = ("auto", "attachments", "covariance")

#: cross-section methods: isolines of a harmonic field (Modenese & Kohout 2020,
#: `fibres.slicing.harmonic`) or parallel planes (Kohout et al. 2012)
SLICINGS = ("harmonic", "planes")
#: the default: fills real muscles better (README, "Slicing")
DEFAULT_SLICING = "harmonic"


def _inputs(mesh, origin, insertion, units, plan):
    """(vertices, faces, origin, insertion, notes, topology, mean_edge): the surface through
    `as_surface`, except a (vertices, faces) tuple with exactly the plan's faces (a frame of
    a motion), which is used as is (the plan's mesh was checked and repaired already), and a
    clean tuple (`_clean_tuple`), whose topology and mean edge length come from the check
    (else None)."""
    notes = []
    if (plan is not None and isinstance(mesh, tuple) and len(mesh) == 2
            and np.shape(mesh[1]) == plan.topology.faces.shape
            and (mesh[1] is plan.topology.faces
                 or np.array_equal(mesh[1], plan.topology.faces))):
        v = np.asarray(mesh[0], dtype=np.float64) * (1e-3 if units == "mm" else 1.0)
        if units not in ("m", "mm"):
            raise InputError(f"unknown units {units!r}", where="units", fix="Use 'm' or 'mm'.")
        if v.shape != (plan.topology.n_vertices, 3) or not np.isfinite(v).all():
            raise InputError("the deformed vertices must be finite and match the plan's mesh "
                             f"({plan.topology.n_vertices}, 3), got {v.shape}",
                             where="mesh", fix="Pass the same mesh, deformed.")
        faces = plan.topology.faces
        topology, mean_edge = plan.topology, None
    else:
        clean = _clean_tuple(mesh, units)
        if clean is not None:
            v, faces, topology, mean_edge = clean
        else:
            # a Surface is in metres by definition; ``units`` then applies to the landmarks
            surface = mesh if isinstance(mesh, Surface) else as_surface(mesh, units=units)
            v, faces, topology, mean_edge = surface.vertices, surface.faces, None, None
            notes.extend(f"surface repaired: {r}" for r in surface.repairs)
    o = as_points(origin, units=units, name="origin")
    i = as_points(insertion, units=units, name="insertion")
    return v, faces, o, i, notes, topology, mean_edge


def _clean_tuple(mesh, units):
    """(vertices, faces, topology, mean_edge) of a (vertices, faces) tuple that `as_surface` would
    return unchanged (`fibres.mesh.surface.clean_topology`: closed, manifold, consistently and
    outward wound, one edge-connected piece, every vertex used, no vertices merged or
    triangles dropped by the repair), else None (then `as_surface` repairs or refuses it).
    Skips the general repair for the common clean input and keeps the topology it built."""
    if not (isinstance(mesh, tuple) and len(mesh) == 2) or units not in ("m", "mm"):
        return None
    v = np.asarray(mesh[0], dtype=np.float64)
    f = np.asarray(mesh[1])
    if (v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) < 4
            or not np.issubdtype(f.dtype, np.integer) or not np.isfinite(v).all()):
        return None
    # int64 faces go in as given when compiled (the check range-checks them and keeps a
    # contiguous copy, the topology's faces, so the caller's array is never kept)
    f = f.astype(np.int64, copy=True)
    v = v * 1e-3 if units == "mm" else v
    topology, mean_edge = clean_mesh_geometry(v, f)
    return None if topology is None else (v, topology.faces, topology, mean_edge)


def _template(template, template_params) -> Template:
    if isinstance(template, Template):
        if template_params:
            raise ValueError("template_params cannot be combined with a Template instance")
        return template
    return get_template(template, **dict(template_params or {}))


def _cross_section_ref(vertices, frame, vt=None):
    """A reference direction for v0 derived from the muscle itself, so that the rotations
    searched in §3.2 move rigidly with the muscle (any v0 is allowed by Kohout 2012 §3.2):
    the major axis of the vertices' spread perpendicular to the principal axis, its sign
    fixed by the muscle's shape (`fibres.fit.box.shape_sign`: the box search's ties between
    rotations half a turn apart, which a symmetric template leaves, are broken by the
    lowest rotation from v0, so the sign decides them) or, for a symmetric shape, by the
    vertex order (``sum_k (k + 1) (V_k - c) . v > 0``), which rides along.
    ``frame`` is the muscle's `fibres.fit.fitting.principal_frame` without a template: its
    axis depends on the muscle only (with an oblique template the axis depends on v_ref,
    by default a world axis, and a reference taken about it would turn with the model's
    frame).

    Returns None (the fitting's default, a world axis) when that spread is isotropic
    (eigenvalues within `ISOTROPIC` of each other: a circular cylinder, a cube), where no
    direction is defined by the shape and a world axis keeps axis-aligned shapes exact.

    Component-wise over the (3, V) coordinates: (3, 3) @ (3, V) products would start BLAS
    threads for a few microseconds of work. The sign of the reference is that of the moment
    ``sum_i i (ref . d_i)`` (numpy's dot). ``vt``: the (3, V) transposed vertices when at
    hand."""
    u = frame.axis
    vt = np.ascontiguousarray(vertices.T) if vt is None else vt
    dt = vt - frame.centroid[:, None]                                   # (3, V)
    axial = u[0] * dt[0] + u[1] * dt[1] + u[2] * dt[2]
    for c in range(3):  # coordinates
        dt[c] -= u[c] * axial
    gram = np.empty((3, 3))
    for r in range(3):  # coordinates
        for c in range(r, 3):
            gram[r, c] = gram[c, r] = np.dot(dt[r], dt[c])
    vals, vecs = np.linalg.eigh(gram)
    if vals[2] <= vals[1] * (1.0 + ISOTROPIC):
        return None
    ref = vecs[:, -1]
    sign = shape_sign(dt, axial, u, ref)
    if sign == 0:  # a symmetric muscle: the vertex order decides
        along = ref[0] * dt[0] + ref[1] * dt[1] + ref[2] * dt[2]
        sign = -1 if np.dot(np.arange(1.0, dt.shape[1] + 1.0), along) < 0 else 1
    return sign * ref




#: Relative eigenvalue gap below which a cross-section's spread counts as isotropic.
ISOTROPIC = 1e-6


#: Scores within this relative margin of the best count as tied; the lowest rotation index
#: wins, so that symmetric muscles do not pick a rotation by rounding noise.
SCORE_TIE = 1e-9


def _new_plan(vertices, faces, origin, insertion, tmpl, resolution, axis, angle_step_deg,
              topology=None, prepared=None):
    """Fit the box (§3.2) and record the choices known before slicing; ``prepared``:
    `fibres.fit.fitting.prepare` of the vertices when at hand."""
    if axis not in _AXES:
        raise ValueError(f"axis must be one of {_AXES}, got {axis!r}")
    prepared = prepare(vertices) if prepared is None else prepared
    # the frame without the template: for an oblique template the axis depends on v_ref
    # (the rotations searched start at v0), so the reference is taken about the axis that
    # does not (the attachment or covariance axis), and the template's axis is then found
    # from it (`reference_frame` returns None; `fit_box` iterates with v_ref=ref)
    frame = principal_frame(vertices, origin, insertion, axis=axis, prepared=prepared)
    ref = _cross_section_ref(vertices, frame, prepared.vt)
    box = fit_box(vertices, origin, insertion, tmpl, angle_step_deg=angle_step_deg, axis=axis,
                  v_ref=ref, frame=reference_frame(frame, ref, tmpl), prepared=prepared)
    scores = box.scores
    best = int(np.flatnonzero(scores <= scores.min() * (1 + SCORE_TIE) + 1e-300)[0])
    theta = np.deg2rad(box.angle_step_deg * box.angle_index)
    v0 = np.cos(theta) * box.axes[:, 0] - np.sin(theta) * box.axes[:, 1]
    fr = slice_fractions(resolution)
    n_s = fr.size
    return DecompositionPlan(topology if topology is not None else
                             mesh_topology(faces, len(vertices)),
                             np.asarray(vertices), v0, box.method, best,
                             box.angle_step_deg, fr, np.full((n_s, 4), -1, np.int64),
                             np.zeros((n_s, 4, 4), np.int64), np.zeros((n_s, 4, 4)), tmpl,
                             rest_origin=origin, rest_insertion=insertion)


def _sweep(plan: DecompositionPlan, vertices, origin, insertion, *, fresh: bool, vt=None):
    """Box, slicing and correspondence of every plane (§3.3); returns what morphing needs.

    ``fresh``: the paper's choices (and the plan's record of them); otherwise the plan's
    anchors are carried along (`fibres.slicing.morph.anchored_maps`) -- except on the plan's own
    vertices, where the fresh choices are the plan's and are reproduced exactly. ``vt``:
    the (3, V) transposed vertices when at hand."""
    # fresh: the plan was made on these vertices (its rest copy is equal; no comparison)
    box, local_t = box_and_local(plan, plan.rest_vertices if fresh else vertices, origin,
                                 insertion, vt=vt)
    tf = np.eye(4)
    tf[:3, :3] = box.axes
    tf[:3, 3] = box.corner
    heights = plan.fractions * box.extents[2]
    sections = slice_mesh(vertices, plan.topology, tf, heights, local_t=local_t)
    n_s = heights.size
    centres = np.broadcast_to(0.5 * box.extents[:2], (n_s, 2))
    chosen, notes = choose_loops(sections, centres, n_slices=n_s)
    if fresh or vertices is plan.rest_vertices or np.array_equal(vertices, plan.rest_vertices):
        P, Q, choice, anchors, map_notes = slice_maps(sections, chosen, box.extents,
                                                      topology=plan.topology)
        return box, heights, P, Q, (choice, anchors), notes + map_notes
    # material anchors (S, 4) in the plane frame, projected along the axis
    uv = np.einsum("skn,dskn->dsk", plan.anchor_weights, local_t[:2, plan.anchor_vertices])
    anchors_uv = np.moveaxis(uv, 0, -1)                                     # (S, 4, 2)
    # with the plan: a plane that cut one loop at rest keeps its whole section (continuous
    # through loops splitting/merging; see fibres.slicing.morph.anchored_maps)
    P, Q, map_notes = anchored_maps(sections, chosen, box.extents, anchors_uv,
                                    topology=plan.topology, plan=plan)
    return box, heights, P, Q, None, notes + map_notes


@blas_single
def make_plan(mesh, origin, insertion, *, template="parallel", resolution: int = 19,
              units: str = "m", template_params=None, axis: str = "auto",
              angle_step_deg: float = 5.0, slicing: str = DEFAULT_SLICING):
    """Make every discrete choice of a decomposition once, on a rest-pose surface.

    Parameters
    ----------
    mesh, origin, insertion, template, resolution, units, template_params
        As for `decompose`.
    axis : {"auto", "attachments", "covariance"}, keyword-only
        Principal-axis rule (`fibres.fit.fitting.principal_frame`).
    angle_step_deg : float, keyword-only
        Rotation step of the OBB search (5 degrees in Kohout 2012).

    slicing : {"harmonic", "planes"}, keyword-only
        As for `decompose`.

    Returns
    -------
    HarmonicPlan or DecompositionPlan
        Reuse with ``decompose(deformed, o, i, plan=plan)`` for every frame.
    """
    _check_slicing(slicing)
    v, faces, o, i, _, topology, _ = _inputs(mesh, origin, insertion, units, None)
    if slicing == "harmonic":
        return make_harmonic_plan(v, faces, o, i, topology=topology)
    tmpl = _template(template, template_params)
    plan = _new_plan(v, faces, o, i, tmpl, int(resolution), axis, angle_step_deg, topology)
    *_, choice, _ = _sweep(plan, v, o, i, fresh=True)
    return _with_choice(plan, choice)


def _check_slicing(slicing):
    if slicing not in SLICINGS:
        raise InputError(f"unknown slicing {slicing!r}", where="slicing",
                         fix=f"Use one of: {', '.join(SLICINGS)}.")


def _with_choice(plan, choice, filter_choice=None):
    """``plan`` with the sweep's ``choice`` (and the attachment filter's, if given)."""
    edges, (anchor_v, anchor_w) = choice
    extra = {} if filter_choice is None else {"filter_choice": filter_choice}
    return dataclasses.replace(plan, choice=edges, anchor_vertices=anchor_v,
                               anchor_weights=anchor_w, **extra)


def _morph_fibres(tmpl, box, heights, P, Q, n_fibres, resolution, seed):
    """Template fibres at the Sobol parameters, morphed into the muscle (§3.1, §3.3).
    Returns (rs (N, 2), points (N, R + 1, 3), the template fibres mapped affinely into the
    box (N, R + 1, 3): the attachment filter's ray directions)."""
    rs = sobol_rs(int(n_fibres), seed=seed)
    unit = tmpl._points(rs, np.linspace(0.0, 1.0, int(resolution) + 1))   # (N, P, 3)
    flat = (unit * box.extents).reshape(-1, 3)
    uv = morph_local(flat[:, :2], flat[:, 2], heights, P, Q)
    pts = box.corner + np.concatenate([uv, flat[:, 2:]], axis=1) @ box.axes.T
    boxed = box.corner + flat @ box.axes.T
    return rs, pts.reshape(unit.shape), boxed.reshape(unit.shape)


def _plan_filter_choice(plan, tmpl, n_fibres, resolution, seed, notes):
    """The attachment filter's rest-pose choices for these fibres: the plan's own record if
    it covers them (same seed, template and resolution, at least as many fibres), else made
    once on the plan's rest pose and cached on the plan object (not a field: a frozen plan
    stays equal to itself)."""
    spec = template_spec(tmpl)
    key = (spec[0], repr(sorted(spec[1].items())), int(seed), int(resolution) + 1)

    def covers(fc):
        return (fc is not None and fc.n_fibres >= n_fibres
                and (fc.template is None or fc.template[0] == key[0]
                     and repr(sorted(dict(fc.template[1]).items())) == key[1])
                and fc.seed == key[2] and fc.n_points == key[3])

    if covers(plan.filter_choice):
        return plan.filter_choice
    cache = plan.__dict__.setdefault("_filter_cache", {})
    fc = cache.get(key)
    if covers(fc):
        return fc
    if plan.rest_origin is None or plan.rest_insertion is None:
        return None
    v, faces = plan.rest_vertices, plan.topology.faces
    o, i = plan.rest_origin, plan.rest_insertion
    box, heights, P, Q, _, _ = _sweep(plan, v, o, i, fresh=True)
    _, pts, boxed = _morph_fibres(tmpl, box, heights, P, Q, n_fibres, resolution, seed)
    fc = filter_choices(pts, (v, faces), o, i, box.axes[:, 2], seed=seed, template=spec,
                        reference=boxed)
    cache[key] = fc
    notes.append("attachment filter: choices made on the plan's rest pose (the plan had none "
                 "for these fibres)")
    return fc


@blas_single
def decompose(mesh, origin, insertion, *, template="parallel", n_fibres: int = 100,
              resolution: int = 19, seed: int = 0, units: str = "m", template_params=None,
              smoothing_iterations: int = DEFAULT_ITERATIONS, filter_attachments: bool = True,
              plan: DecompositionPlan | HarmonicPlan | None = None, axis: str = "auto",
              contain: bool = True, slicing: str = DEFAULT_SLICING) -> FibreBundle:
    """Decompose a closed muscle surface into fibres (Kohout et al., GRAPP 2012).

    The fibres depend on the muscle, not on how it is given: a rigid motion of the mesh and
    landmarks moves them alike, and renumbering the vertices or reordering the faces or
    landmarks leaves them unchanged, up to rounding (orientations are fixed by the shape,
    `fibres.fit.box.shape_sign`; only an exactly symmetric muscle falls back to a world
    axis or the vertex order). Two lengths are absolute, in metres, by design (anatomy-scale
    choices, docs/decisions.md): the bound on the planar smoothing's shift
    (`fibres.finishing.smoothing.DECOMPOSE_MAX_SHIFT`, 1 mm) and the containment band
    (``contain``); a uniformly scaled muscle gets uniformly scaled fibres only with those
    scaled too (`tests/fibres/test_decompose_invariance.py`).

    Parameters
    ----------
    mesh : (vertices (V, 3), faces (T, 3)) tuple, Surface, trimesh/pyvista mesh or path
        Closed surface (anything `fibres.as_surface` takes), in ``units`` (a `Surface` is
        always in metres and used as is).
    origin, insertion : (K, 3) float or anything `fibres.as_points` takes
        Landmarks of the origin and insertion areas, in ``units``.
    template : str or Template, keyword-only
        Fibre architecture: one of `fibres.TEMPLATES`.
    n_fibres : int, keyword-only
        N, the number of fibres (Sobol points; fibre k is the same for any N > k).
    resolution : int, keyword-only
        R, segments per fibre (R + 1 points); 19 in the paper.
    seed : int, keyword-only
        Sobol scrambling seed.
    units : {"m", "mm"}, keyword-only
        Units of ``mesh`` and the landmarks; the result is in metres.
    template_params : mapping, optional
        Parameters of the template (`fibres.get_template`).
    smoothing_iterations : int, keyword-only
        Planes: iterations of the smoothing ``P'_i = (P_{i-1} + 4 P_i + P_{i+1}) / 6`` (§3.4;
        harmonic: `fibres.finishing.fairing.taubin_pairs` lambda|mu pairs of
        `fibres.finishing.smoothing.smooth_taubin`, before the turn-aware resampling of
        `fibres.finishing.fairing`;
        default `fibres.finishing.smoothing.DEFAULT_ITERATIONS`); 0 switches it off. Planes:
        each point's smoothing shift is softly bounded by
        `fibres.finishing.smoothing.DECOMPOSE_MAX_SHIFT` (1 mm) so that smoothing cannot pull
        fibres out through a concave wall.
    filter_attachments : bool, keyword-only
        Trim the fibres at the planes through the extreme landmarks and reconstruct their
        ends on the attachment areas (§3.4).
    plan : DecompositionPlan, optional
        Choices from an earlier decomposition of the same mesh (same faces); the result is
        then consistent with it (no orientation, start-vertex or split flips, and the
        attachment filter's trims and targets frozen, `fibres.attachments.filtering.apply_filter`).
        A plan from `make_plan`, or one made for other fibres (seed, template, resolution,
        fewer fibres), gets the filter's choices made once on its rest pose.
    axis : {"auto", "attachments", "covariance"}, keyword-only
        Principal-axis rule when no plan is given.
    contain : bool, keyword-only
        Finally pull every inner fibre point that lies outside the surface, or inside it
        by less than 0.2 mm, smoothly in along the surface normal (`fibres.finishing.containment`;
        our addition to the paper: its straight reconstructed end segments, resampling
        chords and mean value coordinates on non-convex contours leave points up to ~4 mm
        outside curved muscles). Points deeper than 0.2 mm are not moved; pulled points
        end inside, at least 0.1 mm deep. Every inner
        point is classified on every call (timings in bench/README.md); with harmonic
        slicing the rest pose's pull (a wider band, more spread rounds) is made once per
        plan and carried to the frame first (`fibres.finishing.carried_pull`). False skips
        it.

    slicing : {"harmonic", "planes"}, keyword-only
        Cross-sections: isolines of a harmonic field between the attachment patches
        (default; Modenese & Kohout 2020, `fibres.slicing.harmonic`: the fibre ends cover
        the patches, no attachment filter is needed and ``filter_attachments`` and ``axis``
        do not apply) or the parallel planes of Kohout et al. 2012. A plan decides for
        itself.

    Returns
    -------
    FibreBundle
        ``flags`` holds ``trimmed`` and ``reconstructed`` (attachment filter, planes) and
        ``contained`` (a point was pulled in); ``quality`` measures the result
        (`fibres.finishing.quality`).
    """
    if isinstance(n_fibres, bool) or not isinstance(n_fibres, (int, np.integer)) or n_fibres < 1:
        raise ValueError(f"n_fibres must be a positive integer, got {n_fibres!r}")
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) \
            or resolution < 1:
        raise ValueError(f"resolution must be a positive integer, got {resolution!r}")
    _check_slicing(slicing)
    if plan is not None:
        slicing = getattr(plan, "slicing", "planes")
    v, faces, o, i, notes, topology, mean_edge = _inputs(mesh, origin, insertion, units, plan)
    tmpl = _template(template, template_params)
    if slicing == "harmonic":
        return _decompose_harmonic(v, faces, o, i, notes, tmpl, int(n_fibres),
                                   int(resolution), seed, smoothing_iterations, contain, plan,
                                   topology)
    prepared = None
    if plan is None:
        # the transposed vertices, bounds, centroid: made once for the fit, filter, grid
        prepared = prepare(v)
        plan = _new_plan(v, faces, o, i, tmpl, int(resolution), axis, 5.0, topology,
                         prepared)
        fresh = True
    else:
        plan.check_mesh(v, faces)
        fresh = False
    box, heights, P, Q, choice, sweep_notes = _sweep(
        plan, v, o, i, fresh=fresh, vt=None if prepared is None else prepared.vt)
    notes.extend(sweep_notes)

    rs, pts, boxed = _morph_fibres(tmpl, box, heights, P, Q, n_fibres, resolution, seed)

    flags = {}
    fc = None
    if filter_attachments:
        if fresh:
            fc = filter_choices(pts, (v, faces), o, i, box.axes[:, 2], seed=seed,
                                template=template_spec(tmpl), mean_edge=mean_edge,
                                reference=boxed, prepared=prepared)
        else:
            fc = _plan_filter_choice(plan, tmpl, int(n_fibres), int(resolution), seed, notes)
            if fc is None:  # a plan without rest landmarks: choices made on this frame
                notes.append("attachment filter: choices made on this frame (the plan has "
                             "no rest landmarks)")
                fc = filter_choices(pts, (v, faces), o, i, box.axes[:, 2], reference=boxed)
        pts, trimmed, rebuilt = apply_filter(pts, v, o, i, box.axes[:, 2], fc)
        flags = {"trimmed": trimmed, "reconstructed": rebuilt}
    if smoothing_iterations:
        pts = smooth(pts, k=4.0, iterations=int(smoothing_iterations),
                     max_shift=DECOMPOSE_MAX_SHIFT)
    if contain:
        pts, flags["contained"] = contain_points(pts, v, faces)
    if fresh:  # the sweep's and the filter's choices recorded at once
        plan = _with_choice(plan, choice, fc)
    return FibreBundle(pts, rs, tmpl, plan, flags, tuple(notes), box, (v, faces))


def _decompose_harmonic(v, faces, o, i, notes, tmpl, n_fibres, resolution, seed,
                        smoothing_iterations, contain, plan, topology=None):
    """`decompose` by harmonic-field slicing (`fibres.slicing.harmonic`, with its fairing:
    lambda|mu pairs of Taubin's non-shrinking smoothing (`fibres.finishing.fairing.taubin_pairs`
    of ``smoothing_iterations``) and the
    turn-aware resampling of `fibres.finishing.fairing`, both in the plan's linear map), then
    the rest pose's containment pull carried to this frame
    (`fibres.finishing.carried_pull`) and this frame's own pull, its displacement spread
    along each fibre (`fibres.finishing.fairing.spread_pull`) and pulled again."""
    fresh = plan is None
    if fresh:
        plan = make_harmonic_plan(v, faces, o, i, topology=topology)
        notes.extend(plan.notes)
    else:
        plan.check_mesh(v, faces)
    pts, rs, slice_notes = harmonic_points(plan, v, tmpl, n_fibres, resolution, seed,
                                           int(smoothing_iterations))
    notes.extend(slice_notes)
    flags = {}
    if contain:
        # the rest pose's pull carried in the walls' frames, then this frame's own pull
        key = maps_key(tmpl, n_fibres, resolution, seed, smoothing_iterations)
        grid = SurfaceGrid(v, faces, reach=CONTAIN_REACH)   # at rest the plan's surface too
        carried = planned_pull(plan, key, lambda: pts if fresh else harmonic_points(
            plan, plan.rest_vertices, tmpl, n_fibres, resolution, seed,
            int(smoothing_iterations))[0], grid if fresh else None)
        pts = carried.apply(pts, v)
        pts, moved = pull_rounds(pts, grid)
        flags["contained"] = moved | carried.fibres
    return FibreBundle(pts, rs, tmpl, plan, flags, tuple(notes), None, (v, faces))
