"""The end cross-sections (caps) of a tendon-aware belly turn with the bones they lie over.

A belly's cross-sections otherwise stand perpendicular to its action line
(`motion.surface.binding`): a fibre at offset ``x`` from the line then has length ``b - x Theta``,
``Theta`` the line's turning between the belly's ends, and its moment arm ``r_line + x
dTheta/dq``. Where a line starts to wrap, ``dTheta/dq`` jumps from 0 to about 1 and so does every
fibre's moment arm, by its offset (docs/decisions.md, 12 c).

Rule: each cap turns with one body (`cap_bodies`): the frames at the belly's ends are tilted from
the line's end tangents onto the body-carried rest end tangents, and each cap's tilt fades
smoothly over its half of the belly (`cap_turning`), so the middle cross-section turns with the
line. To first order in the offsets a fibre's length is then ``b - x Phi``, ``Phi`` the caps'
relative rotation (the bodies'): a straight belly's fibre at offset x towards a joint axis has
moment arm ``r_line - x`` (its own distance from the axis, as a fibre attached to its bones
through the aponeuroses), a belly wrapped on a cylinder about the axis ``R - x``; both continuous
in the poses, since the bodies' rotations are. The median fibre (x = 0) keeps the line's.
Physically the caps stand for the aponeuroses, sheets that lie on a bone and through which the
fibres pull on their tendons.

Why half the belly: a tilt alpha faded over a length lambda bends a fibre at offset x by
x alpha / lambda there and lengthens it by about x^2 alpha^2 / (2 lambda), the same for fibres on
both sides, so the median fibre's moment arm moves off the line's; where a cap's bone turns much
more than the line (a belly ending near a joint it crosses) that bias is smallest with lambda as
long as it can be without the two caps' tilts overlapping.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..osim.muscle_parameters import belly_span
from .binding import smoothstep
from .curves import closest_on_polyline

__all__ = ["CapTurning", "cap_bodies", "cap_turning", "tilt_frames", "TILT_LINEAR", "TILT_MAX"]

#: A cap's tilt off its line (rad) is the body's up to TILT_LINEAR, then saturates smoothly
#: towards TILT_MAX (`saturated_tilt`; module docstring).
TILT_LINEAR = 0.3
TILT_MAX = 0.6


def _body_chain(model, first: str, last: str) -> tuple:
    """Body names along the kinematic tree from ``first`` to ``last`` (both included) and the
    joints between consecutive ones."""
    parent = {j.child: (j.parent, j) for j in model.joints}

    def up(name):
        out = [name]
        while out[-1] in parent:
            out.append(parent[out[-1]][0])
        return out

    a, b = up(first), up(last)
    common = next(x for x in a if x in b)
    down = b[:b.index(common)][::-1]
    bodies = a[:a.index(common) + 1] + down
    joints = [parent[x][1] for x in a[:a.index(common)]] + [parent[x][1] for x in down]
    return tuple(bodies), tuple(joints)


def cap_bodies(model, path_name: str, rest_curve, tf_rest_ground_body, slack: float,
               origin_share: float = 0.5) -> tuple:
    """The bodies (indices) the origin and insertion caps of a tendon-aware belly turn with: the
    bone each cap lies over at the rest pose.

    Rule: walk the kinematic tree from the path's origin body to its insertion body; project the
    centre of every joint on that chain (its child-side joint frame's origin at rest) onto the
    rest path ``rest_curve`` (P, 3) (arc length of the nearest point); a cap at arc length ``s``
    (`motion.osim.muscle_parameters.belly_span` with ``slack`` and ``origin_share``) lies over
    the chain body after the
    joints projected before ``s``. A gastrocnemius' caps both lie over the tibia (its tendons
    cross the knee above and the ankle below), a rectus femoris' over the femur; a belly that
    spans a joint has one cap on each side. ``tf_rest_ground_body`` (B, 4, 4): body poses at rest.
    """
    path = model.path(path_name)
    c = np.asarray(rest_curve, dtype=float)
    c = c[np.isfinite(c).all(axis=1)]
    seg = np.linalg.norm(np.diff(c, axis=0), axis=-1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    bodies, joints = _body_chain(model, path.points[0].body, path.points[-1].body)
    tf = np.asarray(tf_rest_ground_body, dtype=float)
    at = np.zeros(0)
    if joints:
        centres = np.stack([(tf[model.body_index(j.child)] @ j.tf_child_jointframe)[:3, 3] for j in joints])
        j, t, _ = closest_on_polyline(centres, c)
        at = cum[j] + t * seg[j]
    start, stop, _ = belly_span(cum[-1:], slack, origin_share)
    return tuple(model.body_index(bodies[int(np.sum(at < s))]) for s in (float(start[0]), float(stop[0])))


def saturated_tilt(angle) -> np.ndarray:
    """``angle`` (rad, >= 0) up to `TILT_LINEAR`; beyond it ``a1 + (a2 - a1) tanh((angle - a1) /
    (a2 - a1))`` (``a1``, ``a2`` = `TILT_LINEAR`, `TILT_MAX`): C1, increasing, below `TILT_MAX`."""
    a = np.asarray(angle, dtype=float)
    a1, a2 = TILT_LINEAR, TILT_MAX
    return np.where(a <= a1, a, a1 + (a2 - a1) * np.tanh((a - a1) / (a2 - a1)))


def tilt_frames(frames, target, weight) -> np.ndarray:
    """Frames (F, n, 3, 3) (columns normal, binormal, tangent) rotated about the axis of the
    minimal rotation that takes the tangent at the sample where ``weight`` (n,) is largest onto
    ``target`` (F, 3), each by ``weight`` times its angle made `saturated_tilt` (Rodrigues'
    formula); weight 1 and an angle up to `TILT_LINEAR` put that sample's tangent on ``target``."""
    fr = np.asarray(frames, dtype=float)
    a = fr[:, int(np.argmax(weight)), :, 2]
    axis = np.cross(a, target)
    sin = np.linalg.norm(axis, axis=-1)
    angle = saturated_tilt(np.arctan2(sin, np.sum(a * target, axis=-1)))
    k = axis / np.maximum(sin, 1e-300)[:, None]                                   # (F, 3)
    weight = np.asarray(weight, dtype=float)
    # samples of weight 0 keep their frames (the rotation is the identity there, exactly)
    turned = np.flatnonzero(weight != 0.0)
    if len(turned) and turned[-1] - turned[0] == len(turned) - 1:
        turned = slice(int(turned[0]), int(turned[-1]) + 1)
    phi = angle[:, None] * weight[None, turned]                                   # (F, n')
    c, s = np.cos(phi)[..., None], np.sin(phi)[..., None]                         # (F, n', 1)
    # R v = c v + s (k x v) + (1 - c) k (k . v) for the three columns v at once, written out
    # component by component (a stack of 3 x 3 matmuls costs more than the arithmetic)
    k0, k1, k2 = (k[:, j, None, None] for j in range(3))                          # (F, 1, 1)
    part = fr[:, turned]
    v0, v1, v2 = part[..., 0, :], part[..., 1, :], part[..., 2, :]                # (F, n', 3)
    along = (1.0 - c) * (k0 * v0 + k1 * v1 + k2 * v2)
    out = fr.copy()
    out[:, turned, 0, :] = c * v0 + s * (k1 * v2 - k2 * v1) + along * k0
    out[:, turned, 1, :] = c * v1 + s * (k2 * v0 - k0 * v2) + along * k1
    out[:, turned, 2, :] = c * v2 + s * (k0 * v1 - k1 * v0) + along * k2
    return out


@dataclass(frozen=True, eq=False)
class CapTurning:
    """The cap rule of one bound surface: per action line the rest end tangents ``(t_o, t_i)``
    (ground, at rest) and the two weight profiles over the line samples (1 at the cap, fading
    to 0 at the belly's middle)."""

    tangents: tuple
    weights: tuple

    def turn(self, frames, rot_origin, rot_insertion, line: int) -> np.ndarray:
        """Frames (F, n, 3, 3) of line ``line`` with both ends tilted onto the rest end tangents
        carried by the cap bodies' rotations since rest, ``rot_origin``, ``rot_insertion`` (F, 3, 3)."""
        (t_o, t_i), (w_o, w_i) = self.tangents[line], self.weights[line]
        fr = tilt_frames(frames, np.einsum("fij,j->fi", rot_origin, t_o), w_o)
        return tilt_frames(fr, np.einsum("fij,j->fi", rot_insertion, t_i), w_i)


def cap_turning(binding, rest_curves) -> CapTurning:
    """The `CapTurning` of ``binding`` (`motion.surface.binding.SurfaceBinding`, bound with the cap
    bodies' rest poses): ``rest_curves`` the current lines at the rest pose (their end tangents
    are the caps' rest orientation); each tilt fades over half the belly (module docstring)."""
    _, frames = binding.line_frames(rest_curves, binding.tf_rest_origin, binding.tf_rest_insertion)
    u = np.asarray(binding.arc_fraction)
    fade = (1.0 - smoothstep(2.0 * u), 1.0 - smoothstep(2.0 * (1.0 - u)))
    tangents = tuple((frames[0, line, 0, :, 2].copy(), frames[0, line, -1, :, 2].copy())
                     for line in range(frames.shape[1]))
    return CapTurning(tangents, (fade,) * len(tangents))
