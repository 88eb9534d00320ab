"""Attachment landmarks against their muscle surface, before any fibre is made: a landmark set far
from the surface is refused with one error that names the muscle, the end, the units and frame
in use, and the likely fix, found by trying the usual mistakes on the actual numbers:

- landmarks copied from the .osim (path-point locations, each in its own body's frame) but read
  in the muscle's frame: the fix ``frame = "body"`` on that attachment;
- the reverse (``frame = "body"`` on points that are in the muscle's frame);
- millimetres read as metres, or metres as millimetres: the fix ``units = ...``.

Distance measure: the median distance of the end's landmarks to the axis-aligned bounding box of
the rest-pose surface (in ground). Landmarks on the bone next to a muscle end lie inside the box
or a few millimetres from it; the set is refused when that median exceeds half the box diagonal
(and 2 cm), far beyond any real attachment (LHDL hip muscles: at most 0.04 of the diagonal; the
bundled arm: 0).
"""
from __future__ import annotations

import numpy as np

from .errors import InputError

__all__ = ["check_landmarks", "landmark_gap"]


def landmark_gap(points, lo, hi) -> float:
    """Median distance (m) of points (K, 3) to the box [lo, hi]."""
    p = np.asarray(points, dtype=float)
    d = np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=1)
    return float(np.median(d))


def _apply(tf, p):
    return p @ tf[:3, :3].T + tf[:3, 3]


def check_landmarks(model, mspec, sspec, rest) -> None:
    """Raise `InputError` if an attachment's landmarks lie far from the rest surface (module
    docstring). ``sspec`` is the muscle's `motion.MuscleSurfaceSpec`, ``rest`` its rest-pose
    `motion.WrappedSurface`."""
    from motion.surface.rest import rest_pose

    lo = rest.rest_vertices.min(axis=0)
    hi = rest.rest_vertices.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    limit = max(0.5 * size, 0.02)
    pose = None
    for end, ground in (("origin", rest.rest_origin), ("insertion", rest.rest_insertion)):
        att = getattr(mspec, end)
        if att is None or att.source.endswith(f"path point of {mspec.action_lines[0]}"):
            continue
        n = len(att.points)
        gap = landmark_gap(np.asarray(ground)[:n], lo, hi)
        if gap <= limit:
            continue
        pose = pose or rest_pose(model, sspec)
        tf_body = pose.tf_ground_body[model.body_index(att.body)]
        tf_here = tf_body if att.in_body_frame else pose.tf_ground_data
        tf_other = pose.tf_ground_data if att.in_body_frame else tf_body
        frame_now = f"frame of body '{att.body}'" if att.in_body_frame else f"muscle's frame '{mspec.frame}'"
        tries = []
        if not np.allclose(tf_here, tf_other):
            if att.in_body_frame:
                hint = ("they look like points in the muscle's frame: remove frame = \"body\" from the "
                        "attachment.")
            else:
                hint = (f"they look like points in the frame of body '{att.body}' (as path points copied from "
                        f"the .osim): write {end} = {{ body = \"{att.body}\", frame = \"body\", ... }}.")
            tries.append((_apply(tf_other, att.points), hint))
        for factor, hint in ((1e-3, "they look like millimetres: set units = \"mm\" on the attachment "
                                    "(or the muscle)."),
                             (1e3, "they look like metres: set units = \"m\" on the attachment.")):
            tries.append((_apply(tf_here, att.points * factor), hint))
        fix = next((hint for pts, hint in tries if landmark_gap(pts, lo, hi) <= 0.25 * limit), None)
        raise InputError(
            f"the {end} landmarks ({n} points from {att.source}) lie {1e3 * gap:.0f} mm from the muscle "
            f"surface, which is only {1e3 * size:.0f} mm across (units \"{mspec.units}\", points read in the "
            f"{frame_now})", file=getattr(mspec, "mesh", None), where=f"muscle '{mspec.name}': {end}",
            fix=(fix[0].upper() + fix[1:]) if fix else
            "Check that the landmarks belong to this muscle and end, their units (units = \"m\"|\"mm\") and "
            "their frame (frame = \"body\" for path points copied from the .osim).")
