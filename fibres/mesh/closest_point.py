"""The closest point of a triangle to a point: the one routine of the code base.

Contract: `closest_points_on_triangles` (p, a, b, c) -> q, all (..., 3) float and broadcast
against each other; q is the point of the closed triangle (a, b, c) nearest to p.

Method: Ericson, Real-Time Collision Detection (2005), §5.1.5 — the Voronoi regions of the
triangle's vertices, edges and face told apart by six dot products (``d1 .. d6``) and three
signed sub-areas (``va, vb, vc``), tested in Ericson's order (A, B, edge AB, C, edge AC, edge
BC, face), so that on a region's border the first one wins, as in his scalar code. A degenerate
triangle (zero area) falls into one of its vertex or edge regions: no division by zero reaches
the result.

One routine, compiled (numba, module level, ``cache=True``): `closest_point` for one point and
one triangle, called inside compiled loops (the search of `fibres.mesh.surface_distance`, the
Lloyd steps of `fibres.attachments.patch_map`), and `closest_points_on_triangles` for arrays, a
loop over it, used by `motion.surface.bone_obstacles` (bone meshes): `motion` imports this
geometry from `fibres` (docs/DESIGN.md, "Layering"). The tests compare it and the distance
search with the brute-force oracle of tests/fibres/distance_oracle.py.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["closest_point", "closest_points_on_triangles"]


@njit(cache=True, nogil=True, error_model="numpy")
def _edge_dots(p0, p1, p2, ab0, ab1, ab2, ac0, ac1, ac2):
    """(AB . p, AC . p) of a vector p from a corner."""
    return ab0 * p0 + ab1 * p1 + ab2 * p2, ac0 * p0 + ac1 * p1 + ac2 * p2


@njit(cache=True, nogil=True, error_model="numpy")
def _along(p0, p1, p2, u0, u1, u2, start, end):
    """The point p + u t of an edge from p along u, ``t = start / (start - end)`` (0 on a
    degenerate edge, ``start == end``)."""
    t = start / (start - end) if start - end != 0.0 else 0.0
    return p0 + u0 * t, p1 + u1 * t, p2 + u2 * t


@njit(cache=True, nogil=True, error_model="numpy")
def closest_point(y0, y1, y2, a, b, c):
    """The point (q0, q1, q2) of the closed triangle with corners ``a``, ``b``, ``c`` ((3,)
    float arrays) nearest to the point (y0, y1, y2) (module docstring)."""
    ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    d1, d2 = _edge_dots(y0 - a[0], y1 - a[1], y2 - a[2], ab0, ab1, ab2, ac0, ac1, ac2)
    d3, d4 = _edge_dots(y0 - b[0], y1 - b[1], y2 - b[2], ab0, ab1, ab2, ac0, ac1, ac2)
    d5, d6 = _edge_dots(y0 - c[0], y1 - c[1], y2 - c[2], ab0, ab1, ab2, ac0, ac1, ac2)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    if d1 <= 0.0 and d2 <= 0.0:                                   # vertex A
        return a[0], a[1], a[2]
    if d3 >= 0.0 and d4 <= d3:                                    # vertex B
        return b[0], b[1], b[2]
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:                     # edge AB
        return _along(a[0], a[1], a[2], ab0, ab1, ab2, d1, d3)
    if d6 >= 0.0 and d5 <= d6:                                    # vertex C
        return c[0], c[1], c[2]
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:                     # edge AC
        return _along(a[0], a[1], a[2], ac0, ac1, ac2, d2, d6)
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:           # edge BC
        return _along(b[0], b[1], b[2], c[0] - b[0], c[1] - b[1], c[2] - b[2], d4 - d3, d6 - d5)
    den = va + vb + vc
    if not den > 0.0:                                             # degenerate: vertex A
        return a[0], a[1], a[2]
    inv = 1.0 / den                                               # the face
    f, h = vb * inv, vc * inv
    return a[0] + ab0 * f + ac0 * h, a[1] + ab1 * f + ac1 * h, a[2] + ab2 * f + ac2 * h


@njit(cache=True, nogil=True, error_model="numpy")
def _closest_loop(p, a, b, c, out):
    for k in range(p.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = closest_point(p[k, 0], p[k, 1], p[k, 2], a[k], b[k],
                                                        c[k])


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
    arrays = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (p, a, b, c)))
    shape = arrays[0].shape
    if shape[-1:] != (3,):
        raise ValueError(f"points and corners must be (..., 3), got {shape}")
    flat = [np.ascontiguousarray(x.reshape(-1, 3)) for x in arrays]
    out = np.empty_like(flat[0])
    _closest_loop(*flat, out)
    return out.reshape(shape)
