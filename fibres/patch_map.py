"""Fibre ends on an attachment patch: the rim membrane's points carried onto the patch.

`fibres.harmonic_slicing` maps a template slice onto a loop as a membrane spanning it (mean
value coordinates of the square applied to the loop's samples). The fibre ends use the same
map on the patch's rim (the isoline that hugs the patch's border), and each membrane point is
carried onto the patch surface along the rim's normal ``n``: the nearest intersection of the
line ``m + t n`` with the patch's triangles (Moeller & Trumbore, J. Graphics Tools 2(1),
1997), or, where the line misses the patch, the patch point nearest to ``m``. The square's
border goes to the rim and its inside to the patch's inside, with the same order and the
same map as every other slice: a fibre of a straight cylinder between its caps is straight,
and fibres leave the patch without hooks. The result is a face and barycentric weights: a
material point that rides a deformed copy of the surface.
"""
from __future__ import annotations

import numpy as np

from .surface_distance import _closest_points

__all__ = ["patch_points", "REACH"]

#: a ray may reach this many times the distance to the nearest patch point
REACH = 3.0


def _closest_barycentrics(p, tri):
    """Barycentric weights (N, 3) of the closest points of (N, 3) points on (N, 3, 3) paired
    triangles (`fibres.surface_distance._closest_points`)."""
    q = _closest_points(tri, p)
    a = tri[:, 0]
    e1, e2, d = tri[:, 1] - a, tri[:, 2] - a, q - a
    d00 = np.einsum("ij,ij->i", e1, e1)
    d01 = np.einsum("ij,ij->i", e1, e2)
    d11 = np.einsum("ij,ij->i", e2, e2)
    d20 = np.einsum("ij,ij->i", d, e1)
    d21 = np.einsum("ij,ij->i", d, e2)
    den = np.maximum(d00 * d11 - d01 * d01, 1e-300)
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return np.stack([1.0 - v - w, v, w], axis=1)


def patch_points(vertices, faces, face_mask, start, direction):
    """Patch points where the fibres' end rays meet the patch (module docstring).

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (T, 3) int
    face_mask : (T,) bool
        The patch's faces (at least one).
    start : (N, 3) float
        The fibres' last inner points.
    direction : (N, 3) float
        The rays' directions (the fibres' last segment, continued).

    Returns
    -------
    face : (N,) int64
        Index into ``faces``.
    bary : (N, 3) float
        Barycentric weights of the face's corners (non-negative, summing to 1).
    """
    idx = np.flatnonzero(face_mask)
    tri = vertices[faces[idx]]                                     # (Tp, 3, 3)
    a = tri[:, 0]
    e1 = tri[:, 1] - a
    e2 = tri[:, 2] - a
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    pv = np.cross(d[:, None, :], e2[None])                          # (N, Tp, 3)
    det = np.einsum("ntk,tk->nt", pv, e1)
    ok = np.abs(det) > 1e-300
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tv = start[:, None, :] - a[None]                                # (N, Tp, 3)
    u = np.einsum("ntk,ntk->nt", tv, pv) * inv
    qv = np.cross(tv, e1[None])
    v = np.einsum("nk,ntk->nt", d, qv) * inv
    t = np.einsum("ntk,tk->nt", qv, e2) * inv
    hit = ok & (t > 0) & (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1 + 1e-9)
    # the nearest patch point: the fallback, and the limit on how far a ray may go
    cen = tri.mean(axis=1)
    near = np.argmin(((start[:, None] - cen[None]) ** 2).sum(axis=2), axis=1)
    near_bary = _closest_barycentrics(start, tri[near])
    near_pt = np.einsum("nk,nkd->nd", near_bary, tri[near])
    reach = REACH * np.linalg.norm(near_pt - start, axis=1) + 1e-9
    dist = np.where(hit & (t <= reach[:, None]), t, np.inf)
    pick = np.argmin(dist, axis=1)
    rows = np.arange(len(start))
    found = np.isfinite(dist[rows, pick])
    bary = np.stack([1 - u[rows, pick] - v[rows, pick], u[rows, pick], v[rows, pick]], axis=1)
    pick = np.where(found, pick, near)
    bary = np.where(found[:, None], bary, near_bary)
    bary = np.clip(bary, 0.0, None)
    bary /= np.maximum(bary.sum(axis=1, keepdims=True), 1e-300)
    return idx[pick], bary
