"""How deep a muscle's tissue may go into a wrap object: its local half-thickness around the line.

An OpenSim wrap object (WrapCylinder, WrapSphere, WrapEllipsoid) stands for the path of the
muscle's *centre line*, not for the bone: a thick muscle whose line wraps a cylinder of radius
R has its inner half inside R. What tissue must not enter is bone. Where the fibre model gives
bone meshes for a muscle, those are its obstacles (`motion.surface.collision.BoneObstacle`) and
its wrap objects only guide the line. Where it gives none, the tool assumes a bone derived from
each wrap object: the wrap surface moved inwards by the muscle's local half-thickness, so the
cross-section around the line fits between the line and that bone unchanged. Per surface
point (and per carried fibre point) the inset is

    inset = min(h(s), INSET_MAX_FRACTION * smallest radius of the object),

``h(s)`` the largest distance from the rest action line of the surface vertices whose nearest
line station is ``s`` (a max over the cross-section; stations that no surface vertex is nearest
to, as between the rings of a generated belly on a finely sampled line, interpolated from their
neighbours; then widened by one station on each side; the nearest of several action lines
decides). The cap keeps the
derived bone at least half the wrap object's size: a muscle thicker than its wrap object
allows is flattened against that smaller bone by the push-out, not let through the object.
"""
from __future__ import annotations

import numpy as np

from .curves import closest_on_polyline, resample_polylines

__all__ = ["local_half_thickness", "INSET_MAX_FRACTION"]

#: The derived bone is never smaller than (1 - this) times the wrap object's smallest radius.
INSET_MAX_FRACTION = 0.5


def local_half_thickness(vertices, n_surface: int, rest_curves, *, n_samples: int = 40) -> np.ndarray:
    """The local half-thickness ``h`` (V,) of a rest surface at each of its points.

    Parameters
    ----------
    vertices : (V, 3) float
        The rest surface in ground, optionally followed by carried points (fibre points).
    n_surface : int
        How many leading vertices are the surface (the profile is taken from these only).
    rest_curves : sequence of (P_l, 3) float
        The action lines at rest (resampled here at ``n_samples`` stations by arc length).
    n_samples : int, keyword-only

    Returns
    -------
    (V,) float
        ``h(s)`` at each point's nearest station on its nearest line (metres).
    """
    verts = np.asarray(vertices, dtype=float)
    best = np.full(len(verts), np.inf)
    out = np.zeros(len(verts))
    for curve in rest_curves:  # loop over action lines (few)
        c = resample_polylines(np.asarray(curve, dtype=float), int(n_samples))
        j, _, d = closest_on_polyline(verts, c)
        profile = np.zeros(len(c) - 1)
        np.maximum.at(profile, j[:n_surface], d[:n_surface])
        seen = np.zeros(len(profile), dtype=bool)
        seen[j[:n_surface]] = True
        if seen.any() and not seen.all():   # stations between rings: interpolated, not 0
            profile = np.interp(np.arange(len(profile)), np.nonzero(seen)[0], profile[seen])
        widened = profile.copy()
        widened[1:] = np.maximum(widened[1:], profile[:-1])
        widened[:-1] = np.maximum(widened[:-1], profile[1:])
        closer = d < best
        out = np.where(closer, widened[j], out)
        best = np.minimum(best, d)
    return out
