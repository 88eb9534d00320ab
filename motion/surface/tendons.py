"""Tendons of generated muscles and attachments on moving path points, for `motion.wrap_surfaces`.

Tendon-aware muscles (`motion.osim.muscle_parameters` states the rule): a surface with a positive
tendon slack length is the *belly*, the fibre part of its action line. In every frame the
current line (moving and conditional points, wrap arcs, all as OpenSim places them) is cut to
the arc-length span ``[t, L - t]`` of `motion.osim.muscle_parameters.belly_span` and the belly is
bound to that piece, so it slides along the whole path as a rigid-tendon muscle does: its
length is ``L - l_ts`` and its fibres change length with the path, ``dl/dq = dL/dq``.

The rest belly is straight: the rest piece of the line is replaced by the straight segment of
the same arc length from its start towards its end (`straight_belly`), the belly surface is
generated around it and bound to it, and every frame (the rest frame included) bends it onto
the current piece of the line. Fibres are decomposed in that straight belly, where the parallel
template's fibres are exact (Kohout et al.'s plane slicing follows a straight muscle, not a bent
one), and carried onto the path by the deformation.

Attachments on MovingPathPoints: a landmark near a path end that is a MovingPathPoint (the
patellar insertions of the Gait2392 quadriceps) does not stay fixed in its body: it is carried
by the body and translated by the end point's own motion in the body since the rest pose
(`end_point_offsets`), so the fibres' ends follow the insertion OpenSim moves.
"""
from __future__ import annotations

import numpy as np

from ..osim.muscle_parameters import belly_span, muscle_parameters
from .curves import round_corners, trim_polylines
from .generate import belly_radius

__all__ = ["tendon_slacks", "belly_polylines", "corner_radius", "end_point_offsets", "polyline_lengths", "straight_belly",
           "CORNER_SAMPLES"]


def tendon_slacks(model, spec) -> tuple:
    """Tendon slack length (m) per action line of ``spec`` (`motion.MuscleSurfaceSpec`).

    ``spec.tendon_slack`` when given; else the model's ``tendon_slack_length`` for a generated
    surface (0 where the path force has none) and 0 for a mesh.
    """
    if spec.tendon_slack is not None:
        return tuple(spec.tendon_slack)
    if not spec.generated:
        return (0.0,) * len(spec.action_lines)
    out = []
    for name in spec.action_lines:
        slack = muscle_parameters(model, name).tendon_slack_length
        out.append(float(slack) if slack and slack > 0 else 0.0)
    return tuple(out)


def polyline_lengths(points) -> np.ndarray:
    """Arc lengths (F,) of NaN-padded polylines (F, P, 3)."""
    pts = np.asarray(points, dtype=float)
    seg = np.linalg.norm(np.diff(pts, axis=1), axis=-1)
    return np.nansum(seg, axis=1)


def belly_polylines(points, slack: float, *, corner_radius: float = 0.0, origin_share: float = 0.5):
    """The belly pieces (F, P', 3) of polylines (F, P, 3) with tendon slack ``slack`` (m), the
    share ``origin_share`` of the tendon at the origin end, and the (F,) frames in which the
    path is too short to hold its tendon.

    ``corner_radius > 0``: the pieces are cut from the path with its corners rounded
    (`motion.surface.curves.round_corners`), and they keep the belly length ``b(L)`` of the
    *unrounded* path (`motion.osim.muscle_parameters.belly_span`): the rounding shortens the
    line by ``d (2 tan(a/2) - a) / tan(a/2)`` per corner, a function of the corner angle ``a``,
    which would otherwise add ``-d(shortening)/dq`` to every fibre's moment arm; here the
    tendons give up that length instead (in their shares), so the belly's centre line is
    exactly ``L - l_ts`` long and changes length with the path, ``db/dq = dL/dq``.
    """
    pts = np.asarray(points, dtype=float)
    length = polyline_lengths(pts)
    start, stop, short = belly_span(length, slack, origin_share)
    if corner_radius <= 0:
        return trim_polylines(pts, start, stop), short
    rounded = round_corners(pts, corner_radius)
    length_r = polyline_lengths(rounded)
    belly = stop - start
    start = np.clip(origin_share * (length_r - belly), 0.0, None)
    stop = np.minimum(start + belly, length_r)
    return trim_polylines(rounded, start, stop), short


def end_point_offsets(model, path_name: str, curve, rest_curve, tf_ground_body, tf_rest_ground_body):
    """How far each end point of a path has moved in its body since the rest pose, in ground.

    Parameters
    ----------
    model : motion.Model
    path_name : str
    curve : (F, P, 3) float
        The current polylines of the path (NaN-padded).
    rest_curve : (P', 3) float
        The rest polyline.
    tf_ground_body : (F, B, 4, 4) float
    tf_rest_ground_body : (B, 4, 4) float

    Returns
    -------
    dict
        ``{"origin": (body index, (F, 3) offset), "insertion": (...)}`` for the ends that are
        MovingPathPoints; other ends are left out (their offset is zero).
    """
    path = model.path(path_name)
    c = np.asarray(curve, dtype=float)
    valid = np.isfinite(c).all(axis=-1)
    last = np.maximum(valid.sum(axis=1) - 1, 0)
    now = {"origin": c[:, 0], "insertion": c[np.arange(len(c)), last]}
    rest = {"origin": np.asarray(rest_curve[0], dtype=float), "insertion": np.asarray(rest_curve[-1], dtype=float)}
    out = {}
    for end, point in (("origin", path.points[0]), ("insertion", path.points[-1])):
        if point.kind != "moving":
            continue
        b = model.body_index(point.body)
        tf = np.asarray(tf_ground_body)[:, b] @ np.linalg.inv(np.asarray(tf_rest_ground_body)[b])
        carried = np.einsum("fij,j->fi", tf[:, :3, :3], rest[end]) + tf[:, :3, 3]
        out[end] = (b, now[end] - carried)
    return out


def straight_belly(piece, n_points: int = 8) -> np.ndarray:
    """A straight polyline (n_points, 3) from ``piece[0]`` towards ``piece[-1]`` with the arc
    length of the polyline ``piece`` (P, 3)."""
    p = np.asarray(piece, dtype=float)
    length = float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=-1)))
    chord = p[-1] - p[0]
    norm = float(np.linalg.norm(chord))
    direction = chord / norm if norm > 1e-12 else np.array([0.0, 0.0, 1.0])
    return p[0] + np.linspace(0.0, length, int(n_points))[:, None] * direction


#: Tendon-aware bellies: path corners under the belly are rounded with a radius of at least
#: this many line sample spacings (`corner_radius`).
CORNER_SAMPLES = 1.5


def corner_radius(rest_belly, n_samples: int, volume: float | None) -> float:
    """The radius (m) with which a tendon-aware belly's path corners are rounded
    (`motion.surface.tendons.belly_polylines`): the generated belly's own radius
    (`motion.surface.generate.belly_radius` of the straight rest belly ``rest_belly`` (P, 3);
    for a mesh belly, ``volume`` None, the 1:10 default), at least ``CORNER_SAMPLES`` line
    sample spacings.

    Why the belly's radius: the belly slides along its path (rigid tendon), so its material
    fibre polylines (segments of a few mm) pass the path's corners, and a polyline cuts a
    corner by an amount that depends on where the corner falls between its points: its length
    ripples as the corner passes and its derivative, the fibre's moment arm, saw-tooths by
    ~theta s / (24 rho) of the moment arm (s the segment, rho the rounding radius, theta the
    turn). Rounded over 1.5 line samples (0.6-3.4 mm) Gait2392's psoas and iliacus medians
    were 3.3-3.5 mm off their lines, Arm26's TRIlong 1.6 mm (saw-tooth over the elbow angle);
    rounded over the belly's radius (10-14 mm) the segments resolve the bend. A tube of radius
    r cannot bend tighter than r without its inner side folding, and the cross-sections
    already turn over about that length (`motion.surface.obstacles.TANGENT_SMOOTHING`). The belly keeps its length
    ``L - l_ts`` (the tendons give up what the rounding shortens), so the centre line's moment
    arm stays the path's.
    """
    c = np.asarray(rest_belly, dtype=float)
    length = float(np.sum(np.linalg.norm(np.diff(c, axis=0), axis=-1)))
    spacing = length / max(int(n_samples) - 1, 1)
    return max(belly_radius(length, volume=volume), CORNER_SAMPLES * spacing)
