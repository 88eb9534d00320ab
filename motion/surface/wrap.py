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
from .bind import bind_surface
from .caps import cap_bodies, cap_turning
from ..osim.muscle_parameters import BELLY_MIN_FRACTION, muscle_parameters
from .generate import belly_surface, fusiform_surface
from .rest import rest_pose
from .tendons import belly_polylines, corner_radius, end_point_offsets, straight_belly, tendon_slacks
from .curves import round_sliding_corners
from .obstacles import TANGENT_SMOOTHING, line_samples, muscle_obstacles
from .thickness import local_half_thickness
from .volume import mesh_volume
from .current_lines import current_polylines, path_polylines

__all__ = ["WrappedSurface", "SurfaceWrapper", "wrap_surfaces", "path_polylines"]


@dataclass(frozen=True, eq=False)
class WrappedSurface:
    """One muscle surface over a motion.

    Attributes
    ----------
    name : str
    vertices : (F, V, 3) float
        In ground, metres; same topology as ``faces`` in every frame (the first K frames only
        with ``SurfaceWrapper.wrap(..., keep=K)``).
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
    rider_frames : (R, F, 3, 3) float or None
        For a mesh with riders (``spec.riders = R``, no tendons): the belly's line frames
        (columns normal, binormal, tangent) at each rider, rider-major, so a caller that moves
        rider ends (fibre ends riding their bones) can carry the correction along the bent belly.
    riders : (R, F, 3) float or None
        For a mesh with riders (``spec.riders = R``): the riders at every frame, rider-major
        (each one's path contiguous); ``vertices`` and ``rest_vertices`` then hold the surface
        alone.
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
    riders: np.ndarray | None = None

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
                         fix="Set units = \"mm\" if the mesh is in millimetres, and check frame/rest_pose.")


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
    _check_lines(model, muscles)
    poses = body_poses(model, motion) if poses is None else poses
    tf = np.asarray(getattr(poses, "tf_ground_body", poses), dtype=float)
    needed = list(dict.fromkeys(n for spec in muscles for n in spec.action_lines))
    current = current_polylines(model, motion, needed, lines, tf, getattr(poses, "q", None))
    return tuple(SurfaceWrapper(model, spec, n_samples=n_samples, margin=margin, bone_spacing=bone_spacing,
                                rigid_radius=rigid_radius, blend_radius=blend_radius).wrap(tf, current)
                 for spec in muscles)   # loop over muscles


def _check_lines(model, muscles) -> None:
    """Every action line of the muscles is a path of the model, or InputError."""
    path_names = list(model.path_names)
    for spec in muscles:
        for k, name in enumerate(spec.action_lines):
            if name not in path_names:
                raise InputError(f"action line {name!r} is not a path force of the model",
                                 file=getattr(model, "file", None),
                                 where=f"muscle {spec.name!r}: action_lines[{k}]",
                                 fix=f"choose among {', '.join(path_names[:10])}"
                                     + (" ..." if len(path_names) > 10 else ""))


def _rest_lines(model, spec, tf_rest_actual, rest_motion):
    """Rest polylines (one (P, 3) per action line), their anchor positions (or None) and
    ConditionalPathPoint masks (P,)."""
    rest_lines = current_polylines(model, rest_motion, spec.action_lines, None, tf_rest_actual)
    curves, anchors, sliding = [], [], []
    for name in spec.action_lines:
        c = rest_lines[name][0][0]
        ok = np.isfinite(c).all(axis=1)
        curves.append(c[ok])
        a = rest_lines[name][1]
        anchors.append(None if a is None else a[0])
        sliding.append(rest_lines[name][2][0][ok])
    return curves, anchors, sliding


class SurfaceWrapper:
    """One muscle surface bound once (rest pose, rest lines, generated surface, binding) and
    wrapped over any number of motions: ``wrapper(motion)`` is ``wrap_surfaces(model, motion,
    [spec])[0]`` without repeating the per-muscle set-up (`analysis` streams a long motion
    through one wrapper in chunks of frames). The keywords are those of `wrap_surfaces`."""

    def __init__(self, model, spec, *, n_samples: int = 40, margin: float = 5e-4, bone_spacing: float = 2e-3,
                 rigid_radius: float | None = None, blend_radius: float | None = None):
        from ..osim.kinematics import body_poses, motion_from_array

        _check_lines(model, (spec,))
        self.model, self.spec, self.margin, self.bone_spacing = model, spec, margin, bone_spacing
        rest = rest_pose(model, spec)
        rest_motion = motion_from_array(model, rest.q[None])
        self.tf_rest_actual = np.asarray(body_poses(model, rest_motion).tf_ground_body, dtype=float)
        rest_curves, rest_anchors, rest_sliding = _rest_lines(model, spec, self.tf_rest_actual, rest_motion)
        self.full_rest = list(rest_curves)
        self.slacks = tendon_slacks(model, spec)
        tendons = self.tendons = any(x > 0 for x in self.slacks)
        self.n_samples = n_samples = line_samples(model, spec, self.full_rest, n_samples)
        volume = spec.volume
        if spec.generated:
            params = muscle_parameters(model, spec.action_lines[0])
            fmax, lopt = params.max_isometric_force, params.optimal_fiber_length
            if volume is None and fmax and lopt and fmax > 0 and lopt > 0:
                from .generate import SPECIFIC_TENSION

                volume = fmax / SPECIFIC_TENSION * lopt
        self.short_rest, self.corners = [], []
        at_rest = []   # with tendons: the belly pieces of the current lines at the rest pose
        share = spec.origin_tendon_share
        if tendons:
            for k, slack in enumerate(self.slacks):  # loop over lines (few)
                belly, short_rest = belly_polylines(rest_curves[k][None], slack, origin_share=share)
                rest_curves[k] = straight_belly(belly[0][np.isfinite(belly[0]).all(axis=1)])
                self.short_rest.append(bool(short_rest.any()))
                self.corners.append(corner_radius(rest_curves[k], n_samples, volume if spec.generated else None))
                at_rest.append(belly_polylines(self.full_rest[k][None], slack, corner_radius=self.corners[k],
                                               origin_share=share)[0])
            rest_anchors = [None] * len(rest_curves)
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
        self.b_o, origin_rest = _attachment(model, spec, "origin", rest, first_path)
        self.b_i, insertion_rest = _attachment(model, spec, "insertion", rest, first_path)
        self.n_v = n_v = len(vertices)
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
        # riders (and, with tendons, the landmarks after them) come back apart, rider-major
        self.apart = len(vertices) - (n_v - spec.riders) if spec.riders else 0
        # a generated belly turns its cross-sections over about its thickness where the path has a
        # corner (`motion.surface.curves.smoothed_tangents`), so its inner side does not fold
        self.half = half = float(np.max(local_half_thickness(vertices, n_v - spec.riders, rest_curves,
                                                               n_samples=n_samples)))
        smoothing = TANGENT_SMOOTHING * half if spec.generated or tendons else 0.0
        if not tendons:   # corners the line samples slide past (conditional points): rounded over h
            rest_curves, rest_anchors = round_sliding_corners(rest_curves, rest_anchors, rest_sliding, half)
        # with tendons the frames' ends turn with the caps' bones (`motion.surface.caps`)
        self.f_o, self.f_i = (cap_bodies(model, spec.action_lines[0], self.full_rest[0], self.tf_rest_actual[0],
                                         self.slacks[0], share) if tendons else (self.b_o, self.b_i))
        self.binding = bind_surface(vertices, faces, rest_curves, rest.tf_ground_body[self.f_o],
                                    rest.tf_ground_body[self.f_i], *ends, n_samples=n_samples,
                                    rigid_radius=rigid_radius, blend_radius=blend_radius,
                                    rest_anchors=rest_anchors, free_vertices=free, tangent_smoothing=smoothing)
        if tendons:
            self.binding = replace(self.binding, caps=cap_turning(self.binding, at_rest))
        self.rest, self.rest_curves, self.vertices = rest, rest_curves, vertices
        self.origin_rest, self.insertion_rest = origin_rest, insertion_rest

    def __call__(self, motion, *, lines=None, poses=None, keep=None, frames=None) -> WrappedSurface:
        """The surface over ``motion`` (see `wrap_surfaces` for ``lines`` and ``poses``; ``keep``
        and ``frames`` as in `wrap`)."""
        from ..osim.kinematics import body_poses

        poses = body_poses(self.model, motion) if poses is None else poses
        tf = np.asarray(getattr(poses, "tf_ground_body", poses), dtype=float)
        return self.wrap(tf, current_polylines(self.model, motion, list(self.spec.action_lines), lines, tf,
                                               getattr(poses, "q", None)), keep=keep, frames=frames)

    def wrap(self, tf, current, *, keep=None, frames=None) -> WrappedSurface:
        """The surface at the body poses ``tf`` (F, B, 4, 4), its lines ``current``
        (`motion.surface.current_lines.current_polylines`); ``keep``: ``vertices`` at the first
        this many poses only (riders, landmarks and the rest at all poses); ``frames``: the
        first this many poses are the motion's frames and the others copies of them (the poses
        of finite-difference moment arms), so that the note on a path too short for its tendon
        counts frames (None: every pose is a frame)."""
        model, spec, rest, tendons = self.model, self.spec, self.rest, self.tendons
        curves = [current[name][0] for name in spec.action_lines]
        anchors = [current[name][1] for name in spec.action_lines]
        notes = []
        if tendons:
            for k, (name, slack) in enumerate(zip(spec.action_lines, self.slacks)):  # loop over lines (few)
                curves[k], short = belly_polylines(curves[k], slack, corner_radius=self.corners[k],
                                                   origin_share=spec.origin_tendon_share)
                short = short if frames is None else short[:frames]
                if self.short_rest[k] or short.any():
                    notes.append(f"action line {name}: the path is shorter than its tendon slack length "
                                 f"{slack:.4g} m + {BELLY_MIN_FRACTION:.0%} of the path "
                                 f"({'at the rest pose and ' if self.short_rest[k] else ''}in {int(short.sum())} "
                                 f"of {len(short)} frames): the belly is kept at least {BELLY_MIN_FRACTION:.0%} "
                                 "of the path long there, the tendons take the rest")
            anchors = None
        else:
            curves, anchors = round_sliding_corners(curves, anchors, [current[n][2] for n in spec.action_lines],
                                                    self.half)
        n_v, b_o, b_i = self.n_v, self.b_o, self.b_i
        obstacles = muscle_obstacles(model, spec, tf, rest, self.vertices, self.rest_curves, n_v - spec.riders,
                                     n_samples=self.n_samples, margin=self.margin, bone_spacing=self.bone_spacing)
        tf_o_body = tf[:, b_o].copy()
        tf_i_body = tf[:, b_i].copy()
        tf_o = tf_o_body @ np.linalg.inv(rest.tf_ground_body[b_o])
        tf_i = tf_i_body @ np.linalg.inv(rest.tf_ground_body[b_i])
        if not tendons:
            # landmarks at a MovingPathPoint end of the first line follow that point's own motion
            moved = end_point_offsets(model, spec.action_lines[0], curves[0], self.full_rest[0], tf,
                                      self.tf_rest_actual[0])
            for end, (b, offset) in moved.items():
                if b == (b_o if end == "origin" else b_i):
                    for t in ((tf_o_body, tf_o) if end == "origin" else (tf_i_body, tf_i)):
                        t[:, :3, 3] += offset
        ends_now = (tf[:, self.f_o], tf[:, self.f_i]) if tendons else (tf_o_body, tf_i_body)
        res = self.binding.deform(curves, *ends_now, anchors=anchors, obstacles=obstacles,
                                  rider_frames=0 if tendons else spec.riders, riders_apart=self.apart,
                                  keep_vertices=keep if self.apart or not tendons else None)
        riders = res.riders
        if tendons:
            k_o = len(self.origin_rest)
            if riders is None:
                origin_now = res.vertices[:, n_v:n_v + k_o]
                insertion_now = res.vertices[:, n_v + k_o:]
                out_v = res.vertices[:keep, :n_v]
            else:
                r = spec.riders
                origin_now = riders[r:r + k_o].transpose(1, 0, 2)
                insertion_now = riders[r + k_o:].transpose(1, 0, 2)
                riders, out_v = riders[:r], res.vertices
        else:
            out_v = res.vertices
            origin_now, insertion_now = _apply(tf_o, self.origin_rest), _apply(tf_i, self.insertion_rest)
        return WrappedSurface(
            name=spec.name, vertices=out_v, faces=self.binding.faces, origin=origin_now,
            insertion=insertion_now, rest_vertices=self.vertices[:n_v - (spec.riders if self.apart else 0)],
            rest_origin=self.origin_rest,
            rest_insertion=self.insertion_rest, rest_q=rest.q, radial_scale=res.radial_scale, volume=res.volume,
            rest_volume=res.rest_volume, generated=spec.generated, rest_residual=rest.residual,
            tendon_slack=self.slacks, notes=tuple(notes), rider_frames=res.rider_frames, riders=riders)
