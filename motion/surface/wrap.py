"""Model-level entry point: move muscle surfaces with the bones and the action lines.

Signature (the analysis package calls this)::

    wrap_surfaces(model, motion, muscles, *, lines=None, poses=None, n_samples=40, margin=5e-4,
                  bone_spacing=2e-3, rigid_radius=None, blend_radius=None)
        -> tuple of WrappedSurface, one per MuscleSurfaceSpec, in order

``model`` is a `motion.Model`, ``motion`` a `motion.Motion` (or any object with ``q``
(F, C) and ``coordinate_names``), ``muscles`` a sequence of `motion.MuscleSurfaceSpec`.
``lines`` may pass the `motion.wrapping.action_lines` result: its current points are reused for paths
without wrap objects (wrapped paths are recomputed here, since the arcs need the tangent points
in path order, which `ActionLines.points` does not keep). ``poses`` may pass the (F, B, 4, 4)
body poses (or a `BodyPoses`); both are computed when absent.

Per muscle (one muscle = its action lines, loops over muscles only):

1. Rest pose (`motion.surface.rest`): coordinates and body transforms; mesh, landmarks and bones
   to ground. A mesh farther from its action line than 0.25 m + 3 x its own size is refused as a
   likely unit mistake (InputError naming the muscle and the ``units`` key).
2. No mesh: a generated surface. With the model's tendon slack length (`motion.surface.tendons`,
   `motion.osim.muscle_parameters`) it is the belly only: a straight flat-capped tube of the rest
   belly length ``L - l_ts`` (`motion.surface.generate.belly_surface`), bound to the straightened
   rest belly line and bent onto the belly piece ``[l_ts / 2, L - l_ts / 2]`` of the current line
   in every frame; its landmarks (the caps) ride the belly, and its end cross-sections turn with
   the bones the caps lie over (`motion.surface.caps`). Without one, a fusiform surface around
   the first action line (`motion.surface.generate.fusiform_surface`). Volume from ``spec.volume``
   or the muscle's max isometric force and optimal fibre length.
3. Current action lines per frame, including the arc over every wrap object between its two
   tangent points (cylinder: the helix, i.e. the geodesic; sphere: the great circle in the
   direction the path arrives; ellipsoid: the great circle of the scaled unit sphere mapped
   back; torus: the chord).
4. `motion.surface.binding`: bind at rest, deform for all frames at once, with the muscle's bone
   meshes as obstacles or, where it has none, bones derived from its wrap objects (the wrap
   surface moved inwards by the local half-thickness: the wrap object guides the centre line,
   tissue may lie inside it; `motion.surface.obstacles`, `motion.surface.thickness`). Landmarks
   at a MovingPathPoint end of the first line follow that point (`motion.surface.tendons`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError
from .binding import bind_surface
from .caps import cap_bodies, cap_turning
from ..osim.muscle_parameters import BELLY_MIN_FRACTION, muscle_parameters
from .generate import belly_surface, fusiform_surface
from .rest import rest_pose
from .tendons import belly_polylines, corner_radius, end_point_offsets, straight_belly, tendon_slacks
from .curves import round_sliding_corners
from .obstacles import TANGENT_SMOOTHING, line_samples, muscle_obstacles
from .thickness import local_half_thickness
from .volume import mesh_volume

__all__ = ["WrappedSurface", "wrap_surfaces", "path_polylines"]

_ARC_POINTS = 24


@dataclass(frozen=True, eq=False)
class WrappedSurface:
    """One muscle surface over a motion.

    Attributes
    ----------
    name : str
    vertices : (F, V, 3) float
        In ground, metres; same topology as ``faces`` in every frame.
    faces : (T, 3) int
        Outward oriented.
    origin, insertion : (F, K, 3) float
        Attachment landmarks in ground, rigid with their bodies.
    rest_vertices : (V, 3) float
        The rest surface in ground (at ``rest_q``).
    rest_origin, rest_insertion : (K, 3) float
    rest_q : (C,) float
        Coordinates of the rest pose.
    radial_scale : (F,) float
        Cross-section scale of the belly solved for volume preservation.
    volume : (F,) float
    rest_volume : float
    generated : bool
        True when the surface was generated (no mesh given).
    rest_residual : float
        ``frame = "bodies"``: residual of the solved all-frames-coincide pose.
    tendon_slack : tuple of float
        Tendon slack length per action line (0: no tendons; `motion.surface.tendons`). With
        tendons the surface is the belly and ``origin`` / ``insertion`` ride it.
    notes : tuple of str
        Warnings for the user (a path shorter than its tendon slack length).
    rider_frames : (F, R, 3, 3) float or None
        For a mesh with riders (``spec.riders = R``, no tendons): the belly's line frames
        (columns normal, binormal, tangent) at each rider, so a caller that moves rider ends
        (fibre ends riding their bones) can carry the correction along the bent belly.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    origin: np.ndarray
    insertion: np.ndarray
    rest_vertices: np.ndarray
    rest_origin: np.ndarray
    rest_insertion: np.ndarray
    rest_q: np.ndarray
    radial_scale: np.ndarray
    volume: np.ndarray
    rest_volume: float
    generated: bool = False
    rest_residual: float = 0.0
    tendon_slack: tuple = ()
    notes: tuple = ()
    rider_frames: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "tendon_slack", tuple(float(x) for x in self.tendon_slack))
        object.__setattr__(self, "notes", tuple(str(x) for x in self.notes))
        for key in ("vertices", "faces", "origin", "insertion", "rest_vertices", "rest_origin",
                    "rest_insertion", "rest_q", "radial_scale", "volume"):
            arr = np.array(getattr(self, key), copy=True)
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)

    @property
    def volume_error(self) -> np.ndarray:
        """(F,) relative volume change."""
        return self.volume / self.rest_volume - 1.0


# ----------------------------------------------------------------------------- paths
def _compact(points: np.ndarray, mask: np.ndarray):
    """Points (F, K, 3) where ``mask`` (F, K), moved to the front in order, NaN-padded; and the
    original index of every slot (F, K) (-1 for padding)."""
    perm = np.argsort(~mask, axis=1, kind="stable")
    out = np.take_along_axis(np.where(mask[..., None], points, np.nan), perm[..., None], axis=1)
    ids = np.where(np.take_along_axis(mask, perm, axis=1), perm, -1)
    return out, ids


def _anchor_positions(path, ids: np.ndarray) -> np.ndarray | None:
    """(F, K) positions in each frame's polyline of the path points that are always present
    (fixed and moving points: not conditional), or None when they are only the two ends."""
    keep = [k for k, p in enumerate(path.points) if p.kind != "conditional"]
    if len(keep) < 3 or keep[0] != 0 or keep[-1] != len(path.points) - 1:
        return None
    hit = ids[:, :, None] == np.asarray(keep)[None, None, :]       # (F, N, K)
    if not np.all(hit.any(axis=1)):
        return None
    return np.argmax(hit, axis=1)


def _conditional(path, ids: np.ndarray) -> np.ndarray:
    """(F, N) bool: polyline entries (ids from `_compact`/`_path_polyline_ids`) that are
    ConditionalPathPoints of ``path``."""
    kinds = np.array([p.kind == "conditional" for p in path.points] + [False])
    ids = np.asarray(ids)
    return kinds[np.where((ids >= 0) & (ids < len(path.points)), ids, -1)]


def _current_polylines(model, motion, names, lines, tf_ground_body) -> dict:
    """Mapping path name -> ((F, N, 3) current polyline with wrap arcs, NaN-padded;
    (F, K) anchor positions or None; (F, N) bool, the points that are ConditionalPathPoints)."""
    out = {}
    table = getattr(lines, "muscle_names", None) if lines is not None else None
    for name in names:
        path = model.path(name)
        if table is not None and name in table and not path.wraps:
            m = table.index(name)
            pts, ids = _compact(np.asarray(lines.points)[:, m, :len(path.points)],
                                np.asarray(lines.point_mask)[:, m, :len(path.points)])
            out[name] = (pts, _anchor_positions(path, ids), _conditional(path, ids))
    missing = [n for n in names if n not in out]
    if missing:
        from ..osim.kinematics import body_pose_derivatives
        from ..wrapping.path_points import path_points

        tf, dtf, q_used, jac = body_pose_derivatives(model, motion, derivatives=True)
        for name in missing:  # loop over paths (few)
            path = model.path(name)
            pp = path_points(path, model, q_used, tf, jac=jac, d_tf_ground_body=dtf)
            if path.wraps:
                from ..wrapping.path import wrap_path

                wrapped = wrap_path(path, model, pp.points, pp.active, pp.d_points, tf, dtf)
                pts, ids = _path_polyline_ids(model, wrapped, tf)
            else:
                pts, ids = _compact(pp.points, np.asarray(pp.active, dtype=bool))
            out[name] = (pts, _anchor_positions(path, ids), _conditional(path, ids))
    return out


def _arc_points(kind, radii, t1, t2, before, u):
    """Points (F, A, 3) strictly between tangent points t1, t2 (F, 3) in the wrap frame."""
    if kind == "cylinder":
        r = radii[0]
        phi1, phi2 = np.arctan2(t1[:, 1], t1[:, 0]), np.arctan2(t2[:, 1], t2[:, 0])
        d_in = t1 - before
        turn = np.sign(t1[:, 0] * d_in[:, 1] - t1[:, 1] * d_in[:, 0])
        turn = np.where(turn == 0, 1.0, turn)
        span = np.where(turn > 0, np.mod(phi2 - phi1, 2 * np.pi), -np.mod(phi1 - phi2, 2 * np.pi))
        phi = phi1[:, None] + u[None] * span[:, None]
        z = t1[:, None, 2] + u[None] * (t2[:, 2] - t1[:, 2])[:, None]
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
    if kind in ("sphere", "ellipsoid"):
        s1, s2, sb = t1 / radii, t2 / radii, before / radii
        n1 = np.linalg.norm(s1, axis=-1, keepdims=True)
        a = s1 / n1
        b = s2 / np.linalg.norm(s2, axis=-1, keepdims=True)
        axis = np.cross(a, b)
        sin = np.linalg.norm(axis, axis=-1)
        cos = np.sum(a * b, axis=-1)
        angle = np.arctan2(sin, cos)
        axis = axis / np.maximum(sin, 1e-15)[:, None]
        # the path arrives along d_in; if it points against the short way, go the long way
        d_in = s1 - sb
        forward = np.sum(d_in * np.cross(axis, a), axis=-1) >= 0
        axis = np.where(forward[:, None], axis, -axis)
        angle = np.where(forward, angle, 2 * np.pi - angle)
        phi = u[None] * angle[:, None]
        c, s = np.cos(phi)[..., None], np.sin(phi)[..., None]
        ax = axis[:, None]
        pts = a[:, None] * c + np.cross(ax, a[:, None]) * s + ax * np.sum(ax * a[:, None], -1, keepdims=True) * (1 - c)
        rad = n1[:, None] + u[None, :, None] * (np.linalg.norm(s2, axis=-1, keepdims=True)[:, None] - n1[:, None])
        return pts * rad * radii
    return t1[:, None] + u[None, :, None] * (t2 - t1)[:, None]  # torus: chord


def path_polylines(model, wrapped, tf_ground_body, *, arc_points: int = _ARC_POINTS) -> np.ndarray:
    """A wrapped path's current polyline per frame, with the arcs over the wrap objects.

    Parameters
    ----------
    model : motion.Model
    wrapped : motion.wrapping.path.WrappedPath
    tf_ground_body : (F, B, 4, 4) float

    Returns
    -------
    (F, N, 3) float
        Points in path order, NaN-padded at the end.
    """
    return _path_polyline_ids(model, wrapped, tf_ground_body, arc_points=arc_points)[0]


def _path_polyline_ids(model, wrapped, tf_ground_body, *, arc_points: int = _ARC_POINTS):
    """`path_polylines`, plus what each point of the polyline is (second return value)."""
    order = np.asarray(wrapped.order)
    pts = np.asarray(wrapped.points)
    nf, nk = order.shape
    valid = order >= 0
    ordered = np.take_along_axis(pts, np.where(valid, order, 0)[..., None], axis=1)
    ordered = np.where(valid[..., None], ordered, np.nan)
    n_wraps = len(wrapped.wrap_objects)
    if n_wraps == 0:
        return ordered, np.where(valid, order, -1)
    n_points = pts.shape[1] - 2 * n_wraps
    u = np.linspace(0.0, 1.0, arc_points + 2)[1:-1]
    slots = np.full((nf, nk, 1 + arc_points, 3), np.nan)
    slots[:, :, 0] = ordered
    prev = np.concatenate([ordered[:, :1], ordered[:, :-1]], axis=1)
    nxt_node = np.concatenate([order[:, 1:], np.full((nf, 1), -1)], axis=1)
    for w, name in enumerate(wrapped.wrap_objects):  # loop over wrap objects (few)
        first = (order == n_points + 2 * w) & (nxt_node == n_points + 2 * w + 1)
        if not first.any():
            continue
        wo = model.wrap_object(name)
        tf = np.asarray(tf_ground_body)[:, model.body_index(wo.body)] @ np.asarray(wo.tf_body_wrap)
        f_idx, k_idx = np.nonzero(first)
        tfw = tf[f_idx]
        to_local = lambda p: np.einsum("fji,fj->fi", tfw[:, :3, :3], p - tfw[:, :3, 3])  # noqa: E731
        t1 = to_local(ordered[f_idx, k_idx])
        t2 = to_local(ordered[f_idx, k_idx + 1])
        before = to_local(prev[f_idx, k_idx])
        if wo.kind == "cylinder":
            radii = np.array([wo.radius, wo.radius, wo.length])
        elif wo.kind == "sphere":
            radii = np.full(3, wo.radius)
        elif wo.kind == "ellipsoid":
            radii = np.asarray(wo.dimensions, dtype=float)
        else:
            radii = np.ones(3)
        arc = _arc_points(wo.kind if wo.kind != "torus" else "torus", radii, t1, t2, before, u)
        slots[f_idx, k_idx, 1:] = np.einsum("fij,faj->fai", tfw[:, :3, :3], arc) + tfw[:, None, :3, 3]
    flat = slots.reshape(nf, -1, 3)
    node = np.full((nf, nk, 1 + arc_points), -1)
    node[:, :, 0] = np.where(valid, order, -1)
    node = node.reshape(nf, -1)
    keep = np.isfinite(flat).all(axis=-1)
    perm = np.argsort(~keep, axis=1, kind="stable")
    return (np.take_along_axis(flat, perm[..., None], axis=1),
            np.where(np.take_along_axis(keep, perm, axis=1), np.take_along_axis(node, perm, axis=1), -1))


# ----------------------------------------------------------------------------- muscles
def _apply(tf: np.ndarray, p: np.ndarray) -> np.ndarray:
    """tf (..., 4, 4) applied to points (K, 3) -> (..., K, 3)."""
    return np.einsum("...ij,kj->...ki", tf[..., :3, :3], p) + tf[..., None, :3, 3]


def _attachment(model, spec, which: str, rest, first_curve_path):
    """(body index, (K, 3) ground points at rest) of one attachment."""
    att = getattr(spec, which)
    names = list(model.body_names)
    if att is None:
        point = first_curve_path.points[0 if which == "origin" else -1]
        b = names.index(point.body)
        return b, _apply(rest.tf_ground_body[b], np.asarray(point.location, dtype=float)[None])
    if att.body not in names:
        raise InputError(f"{which} body {att.body!r} is not a body of the model",
                         file=getattr(model, "file", None), where=f"muscle {spec.name!r}: {which}.body",
                         fix=f"use one of: {', '.join(names)}")
    b = names.index(att.body)
    tf = rest.tf_ground_body[b] if att.in_body_frame else rest.tf_ground_data
    return b, _apply(tf, att.points)


def _check_units(spec, vertices: np.ndarray, curves: list) -> None:
    """Refuse a mesh that sits metres away from its action lines (likely mm read as m)."""
    size = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    pts = np.concatenate([c[np.isfinite(c).all(axis=1)] for c in curves])
    centre = vertices.mean(axis=0)
    gap = float(np.min(np.linalg.norm(pts - centre, axis=1)))
    if gap > 0.25 + 3.0 * min(size, 1.0) or size > 3.0:
        raise InputError(f"the mesh lies {gap:.3g} m from its action lines and is {size:.3g} m across: "
                         "likely a unit or frame mistake", where=f"muscle {spec.name!r}: mesh",
                         fix="set units = \"mm\" if the mesh is in millimetres, and check frame/rest_pose")


def wrap_surfaces(model, motion, muscles, *, lines=None, poses=None, n_samples: int = 40,
                  margin: float = 5e-4, bone_spacing: float = 2e-3, rigid_radius: float | None = None,
                  blend_radius: float | None = None) -> tuple:
    """Deform every muscle surface for every frame of ``motion`` (see the module docstring).

    Parameters
    ----------
    model : motion.Model
    motion : motion.Motion or Motion-like (``q`` (F, C), ``coordinate_names``)
    muscles : sequence of MuscleSurfaceSpec
    lines : motion.ActionLines, optional, keyword-only
        Reused for paths without wrap objects (their current points); wrapped paths are
        recomputed here because the arcs need the tangent points in path order.
    poses : (F, B, 4, 4) float or motion.BodyPoses, optional, keyword-only
    n_samples : int, keyword-only
        Arc-length samples per action line.
    margin : float, keyword-only
        Push-out shell thickness (m).
    bone_spacing : float, keyword-only
        Grid spacing of bone distance fields (m).
    rigid_radius, blend_radius : float, keyword-only
        Attachment blending radii (m); default 5 % / 20 % of the action-line length.

    Returns
    -------
    tuple of WrappedSurface
    """
    from ..osim.kinematics import body_poses

    muscles = tuple(muscles)
    path_names = list(model.path_names)
    for spec in muscles:
        for k, name in enumerate(spec.action_lines):
            if name not in path_names:
                raise InputError(f"action line {name!r} is not a path force of the model",
                                 file=getattr(model, "file", None),
                                 where=f"muscle {spec.name!r}: action_lines[{k}]",
                                 fix=f"choose among {', '.join(path_names[:10])}"
                                     + (" ..." if len(path_names) > 10 else ""))
    tf = np.asarray(body_poses(model, motion).tf_ground_body if poses is None else
                    getattr(poses, "tf_ground_body", poses), dtype=float)
    needed = list(dict.fromkeys(n for spec in muscles for n in spec.action_lines))
    current = _current_polylines(model, motion, needed, lines, tf)
    return tuple(_wrap_one(model, spec, tf, current, n_samples=n_samples, margin=margin, bone_spacing=bone_spacing,
                           rigid_radius=rigid_radius, blend_radius=blend_radius) for spec in muscles)


def _rest_lines(model, spec, tf_rest_actual, rest_motion):
    """Rest polylines (one (P, 3) per action line), their anchor positions (or None) and
    ConditionalPathPoint masks (P,)."""
    rest_lines = _current_polylines(model, rest_motion, spec.action_lines, None, tf_rest_actual)
    curves, anchors, sliding = [], [], []
    for name in spec.action_lines:
        c = rest_lines[name][0][0]
        ok = np.isfinite(c).all(axis=1)
        curves.append(c[ok])
        a = rest_lines[name][1]
        anchors.append(None if a is None else a[0])
        sliding.append(rest_lines[name][2][0][ok])
    return curves, anchors, sliding


def _wrap_one(model, spec, tf, current, *, n_samples, margin, bone_spacing, rigid_radius, blend_radius):
    from ..osim.kinematics import body_poses, motion_from_array

    rest = rest_pose(model, spec)
    rest_motion = motion_from_array(model, rest.q[None])
    tf_rest_actual = np.asarray(body_poses(model, rest_motion).tf_ground_body, dtype=float)
    rest_curves, rest_anchors, rest_sliding = _rest_lines(model, spec, tf_rest_actual, rest_motion)
    full_rest = list(rest_curves)
    slacks = tendon_slacks(model, spec)
    tendons = any(x > 0 for x in slacks)
    notes = []
    curves = [current[name][0] for name in spec.action_lines]
    anchors = [current[name][1] for name in spec.action_lines]
    n_samples = line_samples(model, spec, full_rest, n_samples)
    volume = spec.volume
    if spec.generated:
        params = muscle_parameters(model, spec.action_lines[0])
        fmax, lopt = params.max_isometric_force, params.optimal_fiber_length
        if volume is None and fmax and lopt and fmax > 0 and lopt > 0:
            from .generate import SPECIFIC_TENSION

            volume = fmax / SPECIFIC_TENSION * lopt
    at_rest = []   # with tendons: the belly pieces of the current lines at the rest pose
    if tendons:
        for k, (name, slack) in enumerate(zip(spec.action_lines, slacks)):  # loop over lines (few)
            belly, short_rest = belly_polylines(rest_curves[k][None], slack)
            rest_curves[k] = straight_belly(belly[0][np.isfinite(belly[0]).all(axis=1)])
            rounding = corner_radius(rest_curves[k], n_samples, volume if spec.generated else None)
            curves[k], short = belly_polylines(curves[k], slack, corner_radius=rounding)
            at_rest.append(belly_polylines(full_rest[k][None], slack, corner_radius=rounding)[0])
            if short_rest.any() or short.any():
                notes.append(f"action line {name}: the path is shorter than its tendon slack length "
                             f"{slack:.4g} m + {BELLY_MIN_FRACTION:.0%} of the path "
                             f"({'at the rest pose and ' if short_rest.any() else ''}in {int(short.sum())} of "
                             f"{len(short)} frames): the belly is kept at least {BELLY_MIN_FRACTION:.0%} "
                             "of the path long there, the tendons take the rest")
        rest_anchors = [None] * len(rest_curves)
        anchors = None
    first_path = model.path(spec.action_lines[0])
    if spec.generated:
        if tendons:
            vertices, faces, belly_origin, belly_insertion = belly_surface(rest_curves[0], volume=volume)
        else:
            vertices, faces = fusiform_surface(rest_curves[0], volume=volume)
    else:
        vertices = _apply(rest.tf_ground_data, spec.vertices)
        faces = np.asarray(spec.faces, dtype=np.int64)
        if mesh_volume(vertices, faces) < 0:
            faces = faces[:, ::-1].copy()
        _check_units(spec, vertices, rest_curves)
    b_o, origin_rest = _attachment(model, spec, "origin", rest, first_path)
    b_i, insertion_rest = _attachment(model, spec, "insertion", rest, first_path)
    n_v = len(vertices)
    if tendons:
        if spec.generated:   # the belly's end caps, where the tendons join it
            origin_rest, insertion_rest = belly_origin, belly_insertion
        # the landmarks ride the belly: carried as extra face-less points
        vertices = np.vstack([vertices, origin_rest, insertion_rest])
        ends = (np.zeros((0, 3)), np.zeros((0, 3)))
        free = np.arange(n_v - spec.riders, len(vertices))
    else:
        ends = (origin_rest, insertion_rest)
        free = np.arange(n_v - spec.riders, n_v)
    # a generated belly turns its cross-sections over about its thickness where the path has a
    # corner (`motion.surface.curves.smoothed_tangents`), so its inner side does not fold
    half = float(np.max(local_half_thickness(vertices, n_v - spec.riders, rest_curves, n_samples=n_samples)))
    smoothing = TANGENT_SMOOTHING * half if spec.generated or tendons else 0.0
    if not tendons:   # corners the line samples slide past (conditional points): rounded over h
        rest_curves, rest_anchors = round_sliding_corners(rest_curves, rest_anchors, rest_sliding, half)
        curves, anchors = round_sliding_corners(curves, anchors, [current[n][2] for n in spec.action_lines],
                                                half)
    f_o, f_i = (cap_bodies(model, spec.action_lines[0], full_rest[0], tf_rest_actual[0], slacks[0]) if tendons
                else (b_o, b_i))   # with tendons the frames' ends turn with the caps' bones (`.caps`)
    binding = bind_surface(vertices, faces, rest_curves, rest.tf_ground_body[f_o], rest.tf_ground_body[f_i],
                           *ends, n_samples=n_samples, rigid_radius=rigid_radius, blend_radius=blend_radius,
                           rest_anchors=rest_anchors, free_vertices=free, tangent_smoothing=smoothing)
    if tendons:
        binding = replace(binding, caps=cap_turning(binding, at_rest))
    obstacles = muscle_obstacles(model, spec, tf, rest, vertices, rest_curves, n_v - spec.riders,
                           n_samples=n_samples, margin=margin, bone_spacing=bone_spacing)
    tf_o_body, tf_i_body = tf[:, b_o].copy(), tf[:, b_i].copy()
    tf_o, tf_i = (tf_o_body @ np.linalg.inv(rest.tf_ground_body[b_o]),
                  tf_i_body @ np.linalg.inv(rest.tf_ground_body[b_i]))
    if not tendons:
        # landmarks at a MovingPathPoint end of the first line follow that point's own motion
        moved = end_point_offsets(model, spec.action_lines[0], curves[0], full_rest[0], tf, tf_rest_actual[0])
        for end, (b, offset) in moved.items():
            if b == (b_o if end == "origin" else b_i):
                for t in ((tf_o_body, tf_o) if end == "origin" else (tf_i_body, tf_i)):
                    t[:, :3, 3] += offset
    res = binding.deform(curves, *((tf[:, f_o], tf[:, f_i]) if tendons else (tf_o_body, tf_i_body)),
                         anchors=anchors, obstacles=obstacles,
                         rider_frames=0 if tendons else spec.riders)
    if tendons:
        out_v = res.vertices[:, :n_v]
        k_o = len(origin_rest)
        origin_now = res.vertices[:, n_v:n_v + k_o]
        insertion_now = res.vertices[:, n_v + k_o:]
        vertices = vertices[:n_v]
    else:
        out_v = res.vertices
        origin_now, insertion_now = _apply(tf_o, origin_rest), _apply(tf_i, insertion_rest)
    return WrappedSurface(
        name=spec.name, vertices=out_v, faces=binding.faces, origin=origin_now,
        insertion=insertion_now, rest_vertices=vertices, rest_origin=origin_rest,
        rest_insertion=insertion_rest, rest_q=rest.q, radial_scale=res.radial_scale, volume=res.volume,
        rest_volume=res.rest_volume, generated=spec.generated, rest_residual=rest.residual,
        tendon_slack=slacks, notes=tuple(notes), rider_frames=res.rider_frames)
