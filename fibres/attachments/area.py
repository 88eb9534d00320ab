"""Attachment areas of the attachment filter (`fibres.attachments.filtering`; Kohout et al., GRAPP 2012, §3.4).

Attachment area on the surface (our reading of "the part of the surface cut out at the contour
of the projected landmarks"): every landmark is projected to its nearest surface vertex; the
area is the set of surface vertices within ``r`` of a projected landmark, where r is the median
distance between neighbouring landmarks (at least the mean edge length of the surface), plus
the projections themselves. For one landmark the area is its projection and that vertex's
neighbourhood of radius r = mean edge length.

`_region_indices` finds the area by brute force over the vertices (no KD-tree of the surface:
K landmarks need K distances per vertex, cheaper than building a tree), measuring exactly only
the candidates that the triangle inequality leaves.

The area's surface (what the filter's rays search, `fibres.attachments.ray_triangles`): the faces whose
three corners are all in the area, plus each area vertex on no such face as a point (a
degenerate triangle held by a face with that corner): `region_triangles`, or
`regions_triangles` for both areas with one pass over the faces.
"""
from __future__ import annotations

import numpy as np

__all__ = ["attachment_region", "region_triangles", "regions_triangles"]


def _region_indices(vertices, faces, landmarks, vt=None, mean_edge=None) -> np.ndarray:
    """Vertex indices of an attachment area (module docstring), by brute force over the
    vertices, component-wise (no KD-tree of the surface: K landmarks need K distances per
    vertex, cheaper than building a tree). ``vt`` (3, V) and ``mean_edge`` may be passed
    when already computed."""
    vt = np.ascontiguousarray(vertices.T) if vt is None else vt
    landmarks = np.asarray(landmarks, float).reshape(-1, 3)
    radius = _mean_edge(vt, faces) if mean_edge is None else mean_edge
    if len(landmarks) > 1:
        dl = np.sqrt(_sq_distances(np.ascontiguousarray(landmarks.T), landmarks))
        np.fill_diagonal(dl, np.inf)
        near = np.sort(dl.min(axis=1))  # their median (np.median's arithmetic, ~10x faster)
        h = len(near) // 2
        radius = max(radius, float(near[h] if len(near) % 2 else (near[h - 1] + near[h]) / 2))
    d2 = _sq_distances(vt, landmarks)                                  # (K, V)
    nearest = np.argmin(d2, axis=1)
    proj = np.unique(nearest)
    # |x - proj| <= r needs |x - landmark| <= r + |landmark - proj| (triangle inequality):
    # only those candidates are measured exactly
    reach = radius + np.sqrt(d2[np.arange(len(landmarks)), nearest])
    cand = np.flatnonzero((d2 <= (reach[:, None] * (1 + 1e-9)) ** 2).any(axis=0))
    near = (_sq_distances(vt[:, cand], vertices[proj]) <= radius * radius).any(axis=0)
    return np.unique(np.concatenate([cand[near], nearest.astype(np.int64)]))


def _sq_distances(vt, points):
    """(K, V) squared distances of points (K, 3) to vertices given as (3, V)."""
    d2 = (vt[0] - points[:, 0, None]) ** 2
    d2 += (vt[1] - points[:, 1, None]) ** 2
    d2 += (vt[2] - points[:, 2, None]) ** 2
    return d2


def _mean_edge(vt, faces) -> float:
    """Mean length of the faces' (directed) edges, from (3, V) vertices."""
    if len(faces) == 0:
        return 0.0
    c = np.take(vt, np.ascontiguousarray(faces.T), axis=1)              # (3, 3, T)
    e = c[:, [1, 2, 0]] - c
    return float(np.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).mean())


def attachment_region(vertices, faces, landmarks) -> np.ndarray:
    """Surface points of an attachment area (module docstring).

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (T, 3) int
    landmarks : (K, 3) float

    Returns
    -------
    (C, 3) float
        Surface vertices belonging to the area.
    """
    vertices = np.asarray(vertices, float)
    return vertices[_region_indices(vertices, np.asarray(faces, np.int64),
                                    np.asarray(landmarks, float).reshape(-1, 3))]


def regions_triangles(faces, regions, n_vertices):
    """`region_triangles` of several areas (at most 8) with one pass over the faces.

    Parameters
    ----------
    faces : (T, 3) int
    regions : sequence of (C_r,) int
        The areas' vertex indices (each without repeats; areas may overlap).
    n_vertices : int
        V.

    Returns
    -------
    list of (corners (T'_r, 3) int, face (T'_r,) int)
        Exactly `region_triangles` of each area.
    """
    return [region_triangles(faces, r, n_vertices) for r in regions]


def region_triangles(faces, region, n_vertices):
    """The attachment area's surface: the faces with all three corners in the area, plus
    each area vertex on no such face as a point (a degenerate triangle (v, v, v)).

    Parameters
    ----------
    faces : (T, 3) int
    region : (C,) int
        The area's vertex indices.
    n_vertices : int
        V.

    Returns
    -------
    corners : (T', 3) int
        The area triangles' vertex indices (a point: its vertex three times).
    face : (T',) int
        For each, a face of the mesh holding it (for a point: a face with that corner).
    """
    inside = np.zeros(n_vertices, bool)
    inside[region] = True
    f0, f1, f2 = faces[:, 0], faces[:, 1], faces[:, 2]
    # column by column (faces may be a strided view; a (T, 3) gather is ~6x slower)
    full = np.flatnonzero(inside[f0] & inside[f1] & inside[f2])
    covered = np.zeros(n_vertices, bool)
    covered[faces[full].ravel()] = True
    lone = region[~covered[region]]
    if len(lone) == 0:
        return faces[full], full
    alone = np.zeros(n_vertices, bool)
    alone[lone] = True
    owner = np.full(n_vertices, -1, np.int64)          # a face holding each lone vertex
    for col in (f0, f1, f2):  # the three corners
        rows = np.flatnonzero(alone[col])
        owner[col[rows]] = rows
    corners = np.concatenate([faces[full], np.repeat(lone[:, None], 3, axis=1)])
    return corners, np.concatenate([full, owner[lone]])
