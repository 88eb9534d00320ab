"""The closest point of a triangle to a point: the one routine of the code base.

Contract: `closest_points_on_triangles` (p, a, b, c) -> q, all (..., 3) float and broadcast
against each other; q is the point of the closed triangle (a, b, c) nearest to p.

Method: Ericson, Real-Time Collision Detection (2005), §5.1.5 — the Voronoi regions of the
triangle's vertices, edges and face told apart by six dot products (``d1 .. d6``) and three
signed sub-areas (``va, vb, vc``), evaluated for all pairs at once; the regions are tested in
Ericson's order (A, B, edge AB, C, edge AC, edge BC, face), so that on a region's border the
first one wins, as in his scalar code. A degenerate triangle (zero area) falls into one of its
vertex or edge regions: no division by zero reaches the result.

Used by `motion.surface.collision` (bone meshes): `motion` imports this geometry from `fibres`
(docs/DESIGN.md, "Layering"). The compiled search of `fibres.mesh.surface_distance` measures
its pairs in its own loop (one point against the triangles it meets); the tests compare both
with the brute-force oracle of tests/fibres/distance_oracle.py.
"""
from __future__ import annotations

import numpy as np

__all__ = ["closest_points_on_triangles"]


def _dot(x, y):
    return x[..., 0] * y[..., 0] + x[..., 1] * y[..., 1] + x[..., 2] * y[..., 2]


def _ratio(num, den, where):
    """num / den where ``where`` and den != 0, else 0 (a degenerate edge: its first end)."""
    ok = where & (den != 0.0)
    return np.where(ok, num / np.where(ok, den, 1.0), 0.0)


def closest_points_on_triangles(p, a, b, c):
    """Closest points (..., 3) of the triangles (a, b, c) to the points p (module docstring).

    Parameters
    ----------
    p, a, b, c : (..., 3) float
        Points and triangle corners, broadcast against each other.

    Returns
    -------
    q : (..., 3) float64
        The closest point of each triangle to its point.
    """
    p, a, b, c = (np.asarray(x, dtype=np.float64) for x in (p, a, b, c))
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    # the regions, last assignment wins: written from the face back to vertex A
    with np.errstate(divide="ignore", invalid="ignore"):
        den = va + vb + vc
        face = den > 0.0
        inv = np.where(face, 1.0 / np.where(face, den, 1.0), 0.0)
        q = a + ab * (vb * inv)[..., None] + ac * (vc * inv)[..., None]
        e_bc = (va <= 0.0) & (d4 - d3 >= 0.0) & (d5 - d6 >= 0.0)
        t = _ratio(d4 - d3, (d4 - d3) + (d5 - d6), e_bc)
        q = np.where(e_bc[..., None], b + (c - b) * t[..., None], q)
        e_ac = (vb <= 0.0) & (d2 >= 0.0) & (d6 <= 0.0)
        t = _ratio(d2, d2 - d6, e_ac)
        q = np.where(e_ac[..., None], a + ac * t[..., None], q)
        q = np.where(((d6 >= 0.0) & (d5 <= d6))[..., None], c, q)
        e_ab = (vc <= 0.0) & (d1 >= 0.0) & (d3 <= 0.0)
        t = _ratio(d1, d1 - d3, e_ab)
        q = np.where(e_ab[..., None], a + ab * t[..., None], q)
    q = np.where(((d3 >= 0.0) & (d4 <= d3))[..., None], b, q)
    q = np.where(((d1 <= 0.0) & (d2 <= 0.0))[..., None], a, q)
    return q
