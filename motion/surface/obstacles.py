"""What a wrapped muscle surface must keep out of, and how finely its line is sampled.

Used by `motion.wrap_surfaces` per muscle:

- bone meshes given for the muscle (``bones``): signed-distance obstacles riding their bodies
  (`motion.surface.collision.BoneObstacle`); the wrap objects then only guide the line;
- no bone mesh: a bone derived from every active wrap object of the muscle's action lines (not
  WrapTorus): the wrap surface moved inwards by the muscle's local half-thickness, at most half
  the object's smallest radius (`motion.surface.thickness`), no squeeze;
- line samples: enough that they are at most WRAP_SAMPLE_ANGLE apart on the smallest wrap
  object of the muscle (`line_samples`).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .bone_obstacles import BoneDistance, BoneObstacle
from .collision import wrap_obstacle
from .thickness import INSET_MAX_FRACTION, local_half_thickness

__all__ = ["muscle_obstacles", "line_samples", "WRAP_SAMPLE_ANGLE", "TANGENT_SMOOTHING"]

_BONE_CACHE: dict = {}


def _apply(tf: np.ndarray, p: np.ndarray) -> np.ndarray:
    """tf (..., 4, 4) applied to points (K, 3) -> (..., K, 3)."""
    return np.einsum("...ij,kj->...ki", tf[..., :3, :3], p) + tf[..., None, :3, 3]


def _bone_distance(bone, vertices_body: np.ndarray, spacing: float) -> BoneDistance:
    """Signed distance grid of a bone in its body frame, cached per bone object and placement."""
    import hashlib

    digest = hashlib.sha1(np.ascontiguousarray(vertices_body).tobytes()
                          + np.ascontiguousarray(bone.faces).tobytes()).hexdigest()
    key = (digest, float(spacing))
    if key not in _BONE_CACHE:
        if len(_BONE_CACHE) >= 16:  # a few bones per model; bound the memory
            _BONE_CACHE.pop(next(iter(_BONE_CACHE)))
        _BONE_CACHE[key] = BoneDistance.from_mesh(vertices_body, bone.faces, spacing=spacing)
    return _BONE_CACHE[key]


#: Generated bellies: standard deviation of the tangent smoothing, in belly half-thicknesses.
TANGENT_SMOOTHING = 1.0

#: Line samples are at most this angle (rad) apart on the smallest wrap object of the muscle.
WRAP_SAMPLE_ANGLE = 0.25


def line_samples(model, spec, rest_curves, n_samples: int) -> int:
    """``n_samples``, raised so that the samples are at most WRAP_SAMPLE_ANGLE x the smallest
    radius of the muscle's wrap objects apart (longest rest line + 30 % for stretch; at most 240):
    the belly's centre line between samples (a Catmull-Rom spline) then stays within ~1e-4 R of
    a wrap arc."""
    radii = []
    for name in spec.action_lines:
        for pw in model.path(name).wraps:
            wo = model.wrap_object(pw.wrap_object)
            r = [wo.radius] if wo.kind in ("cylinder", "sphere") else (
                list(wo.dimensions) if wo.kind == "ellipsoid" else [wo.inner_radius])
            radii += [x for x in r if np.isfinite(x) and x > 0]
    if not radii:
        return int(n_samples)
    longest = max(float(np.sum(np.linalg.norm(np.diff(c, axis=0), axis=-1))) for c in rest_curves)
    need = int(np.ceil(1.3 * longest / (WRAP_SAMPLE_ANGLE * min(radii)))) + 1
    return int(min(max(int(n_samples), need), 240))


def muscle_obstacles(model, spec, tf, rest, vertices, rest_curves, n_surface, *, n_samples, margin, bone_spacing):
    """Bone meshes where the muscle has them; else a bone derived from every active wrap object
    of its action lines (`motion.surface.thickness`)."""
    names = list(model.body_names)
    obstacles = []
    for k, bone in enumerate(spec.bones):
        if bone.body not in names:
            raise InputError(f"bone body {bone.body!r} is not a body of the model",
                             file=getattr(model, "file", None), where=f"muscle {spec.name!r}: bones[{k}]",
                             fix=f"use one of: {', '.join(names)}")
        b = names.index(bone.body)
        if bone.in_body_frame:
            local = np.asarray(bone.vertices)
        else:
            local = _apply(np.linalg.inv(rest.tf_ground_body[b]) @ rest.tf_ground_data, bone.vertices)
        dist = _bone_distance(bone, local, bone_spacing)
        obstacles.append(BoneObstacle.bind(dist, tf[:, b], vertices, rest.tf_ground_body[b], margin=margin))
    if obstacles:
        return obstacles
    half = None
    seen = set()
    for name in spec.action_lines:
        for pw in model.path(name).wraps:
            if pw.wrap_object in seen:
                continue
            seen.add(pw.wrap_object)
            wo = model.wrap_object(pw.wrap_object)
            if not wo.active or wo.kind == "torus":
                continue
            if half is None:
                half = local_half_thickness(vertices, n_surface, rest_curves, n_samples=n_samples)
            radii = (wo.radius,) if wo.kind in ("cylinder", "sphere") else tuple(wo.dimensions)
            inset = np.minimum(half, INSET_MAX_FRACTION * float(np.min(radii)))
            obs = wrap_obstacle(wo, tf[:, model.body_index(wo.body)], margin=margin, inset=inset, knee=None)
            if obs is not None:
                obstacles.append(obs)
    return obstacles
