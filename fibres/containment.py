"""Keep fibre points inside the muscle surface: a smooth pull along the shortest path.

Why (a departure from Kohout et al. 2012, see `fibres.decompose`): the paper's attachment
filter (§3.4) joins the last kept fibre point to the attachment area by ONE straight segment
and the arc-length resampling puts points on chords between morphed points; both cut the
concave walls of curved muscles (measured on the LHDL hip muscles: up to 4.2 mm outside), and
mean value coordinates fold slightly outside a non-convex contour (up to 1.5 mm). After the
chain, every inner fibre point that lies OUTSIDE the surface is moved back along the shortest
path (towards its closest surface point) to the signed distance

    s' = m (1 - exp(-s / m))          (s > 0: signed distance, positive outside; m = margin)

i.e. ``x' = x - (s - s') n`` with ``n`` the outward direction of the shortest path
(`fibres.surface_distance`: exact point-triangle distances soft-blended over the nearest
triangles, so that ``s`` and ``n`` stay continuous where two walls are equally near). ``s'`` is
C1 in ``s`` at the surface (``s' = s - s^2 / (2 m) + ...``), so the pull switches on smoothly:
a point crossing the surface during a motion is not kinked (a hard projection would be).
Points inside (``s <= 0``) do not move at all and fibre ends (on the attachment areas) never
move. A far-outside point ends less than ``m`` outside (0.2 mm in `fibres.decompose`); a
second step from the new closest point puts points near mesh edges and vertices at ``s'`` too.

Every inner point is measured on every call (each frame of a motion): no points are chosen on
the rest pose and skipped later, because fibres slide along the surface as it deforms (on the
LHDL bend sweeps of tests/fibres/test_decompose_lhdl.py a point's depth changes by up to 8 mm
over 20 degrees, and points 3.5 mm deep at rest end up outside). Points with no triangle within
`reach` (8 mm) are taken as inside (the chain's excursions are a few mm). Only the points
OUTSIDE are measured: a point in an empty grid cell takes the cell's inside/outside label, a
point in a cell holding triangles is classified by ray parity along the grid
(`fibres.surface_distance`, ``watch = 0``).

Cost (one core, CPU): the grid and its cell labels are built per call, O(T); the inside test
of a point is a label look-up or a short parity walk, the distance search runs for outside
points only (the triangles' normals and bounding spheres are made only then). Measured per
call on the bench meshes (100 fibres x 20 points): 0.8 ms (1K vertices), 1.4 ms (15K),
4.6 ms (60K); LHDL muscles 1.3-2.8 ms. Tried and dropped:
candidate triangles or watched points chosen on the rest pose and frozen in the plan (cheap per
frame, but wrong on deformed frames: fibres slide along the surface, see above).
"""
from __future__ import annotations

import numpy as np

from .surface_distance import SurfaceGrid

__all__ = ["contain", "CONTAIN_MARGIN", "CONTAIN_REACH", "CONTAIN_SOFTNESS"]

#: depth scale m (metres) of the pull: points far outside end less than m outside
CONTAIN_MARGIN = 2e-4
#: points farther than this (metres) from every triangle are taken as inside
CONTAIN_REACH = 8e-3
#: soft-min width tau (metres) of the blend over the nearest triangles
CONTAIN_SOFTNESS = 5e-5


def _check(**values):
    for name, value in values.items():
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive number, got {value!r}")


def _as_fibres(points):
    out = np.array(points, dtype=np.float64, copy=True)
    if out.ndim != 3 or out.shape[2] != 3:
        raise ValueError(f"points must be (N, P, 3), got {out.shape}")
    return out


def _inner(n, p):
    """Flat indices of the inner points of N fibres of P points."""
    return (np.arange(n)[:, None] * p + np.arange(1, p - 1)[None]).ravel()


def contain(points, vertices, faces, *, margin: float = CONTAIN_MARGIN,
            softness: float = CONTAIN_SOFTNESS, reach: float = CONTAIN_REACH,
            iterations: int = 2, mean_edge: float | None = None, bounds=None):
    """Pull the inner fibre points that lie outside a closed surface back in (module
    docstring).

    Parameters
    ----------
    points : (N, P, 3) float
        Fibres; the first and last point of each never move.
    vertices : (V, 3) float
    faces : (T, 3) int
        Closed, consistently and outward wound surface.
    margin : float, keyword-only
        m: a point at signed distance s > 0 goes to ``m (1 - exp(-s / m))`` (< m).
    softness : float, keyword-only
        Soft-min width tau of the distance blend (`fibres.surface_distance`).
    reach : float, keyword-only
        Points farther from every triangle are taken as inside.
    iterations : int, keyword-only
        Pull steps (>= 1): the first moves by ``s - s'`` along the shortest path, the
        others correct towards the same ``s'`` from the new closest point.
    mean_edge : float, optional
        The faces' mean edge length when known (sizes the search grid; measured otherwise).
    bounds : ((3,) float, (3,) float), optional
        The vertices' coordinate-wise minimum and maximum when known (else measured).

    Returns
    -------
    points : (N, P, 3) float64
        A new array; points not pulled are unchanged (bit for bit).
    moved : (N,) bool
        Fibres with at least one point pulled in.
    """
    _check(margin=margin, softness=softness, reach=reach)
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) \
            or iterations < 1:
        raise ValueError(f"iterations must be a positive integer, got {iterations!r}")
    out = _as_fibres(points)
    n, p = out.shape[:2]
    if n == 0 or p < 3:
        return out, np.zeros(n, bool)
    grid = SurfaceGrid(vertices, faces, reach=reach, mean_edge=mean_edge, bounds=bounds)
    index = _inner(n, p)
    # points in enclosed grid cells are inside: not measured (watch = 0)
    s, d = grid.signed_distance(out.reshape(-1, 3)[index], tau=softness, watch=0.0)
    return _pull(out, index, s, d, grid, margin, softness, iterations)


def _pull(out, index, s, d, grid, margin, softness, iterations):
    """Move the points ``index`` (flat) of out (N, P, 3) with signed distance s > 0 along
    -d to ``s'`` (module docstring), in place; returns (out, moved (N,))."""
    n, p = out.shape[:2]
    moved = np.zeros(n, bool)
    outside = s > 0
    if not outside.any():
        return out, moved
    flat = out.reshape(-1, 3)
    rows, s, d = index[outside], s[outside], d[outside]
    target = margin * -np.expm1(-s / margin)
    y = flat[rows] - (s - target)[:, None] * d
    for _ in range(int(iterations) - 1):  # correction steps (a few), not a loop over points
        s2, d2 = grid.signed_distance(y, tau=softness)
        y = np.where(np.isfinite(s2)[:, None], y - (s2 - target)[:, None] * d2, y)
    flat[rows] = y
    moved[rows // p] = True
    return out, moved

