"""Keep fibre points inside the muscle surface: a smooth pull along the surface normal.

Why (a departure from Kohout et al. 2012, see `fibres.decompose`): the paper's attachment
filter (§3.4) joins the last kept fibre point to the attachment area by ONE straight segment
and the arc-length resampling puts points on chords between morphed points; both cut the
concave walls of curved muscles (measured on the LHDL hip muscles: up to 4.2 mm outside), and
mean value coordinates fold slightly outside a non-convex contour (up to 1.5 mm). After the
chain, every inner fibre point closer to the surface than the band depth ``b`` (or outside it)
is moved along the surface normal of its nearest triangles to the signed distance

    s' = -b + a (1 - exp(-(s + b) / a)),   a = b / 2     (for s > -b; s' = s deeper)

(``s`` signed distance, positive outside; ``b`` = margin), i.e. ``x' = x - (s - s') n``.
``s`` and ``n`` come from `fibres.mesh.surface_distance` (``offset=True``): exact point-triangle
distances soft-blended over the nearest triangles, ``s = sum w (x - c_t) . n_t / sum w`` (the
blended signed normal offset: the exact signed distance over a flat piece of surface, a
little less in magnitude near edges and vertices) and ``n`` the blended face normal. Both
stay continuous where two walls are equally near (the medial surfaces, where the single
closest triangle jumps) AND through the surface itself (the blended distance's magnitude does
not reach 0 there while its sign flips: with it, a point crossing the surface jumped by
~13 um on the LHDL psoas bend sweep). ``s'`` is C1 in ``s`` where the band starts
(``s' = s - (s + b)^2 / (2 a) + ...`` at ``s = -b``), so the pull switches on smoothly: a point
drifting towards the surface during a motion is not kinked (a hard projection would be). And
``s' < -b + a = -b / 2`` for every ``s``: every pulled point ends INSIDE, at least ``b / 2``
deep (a point on the surface ends ``0.57 b`` deep, one far outside ``b / 2``), so a straight
segment between two points cannot leave through a wall of curvature ``kappa`` unless it is
longer than ``2 sqrt(b / kappa)`` (its sagitta ``h^2 kappa / 8`` exceeds ``b / 2``). Points
deeper than ``b`` do not move at all and fibre ends (on the attachment areas) never move. A
second step from the new closest point puts points near mesh edges and vertices at ``s'`` too.
(The first version pulled only the points outside, to ``m (1 - exp(-s / m))``: C1 at the
surface but it ended them up to ``m`` OUTSIDE, and on the bent tube of the tests the default
smoothing left 32 points 0.13 mm outside its concave wall.)

Every inner point is measured on every call (each frame of a motion): no points are chosen on
the rest pose and skipped later, because fibres slide along the surface as it deforms (on the
LHDL bend sweeps of tests/fibres/test_decompose_lhdl.py a point's depth changes by up to 8 mm
over 20 degrees, and points 3.5 mm deep at rest end up outside). Points with no triangle within
`reach` (8 mm) are taken as inside (the chain's excursions are a few mm). Every point is
classified by ray parity; a point inside looks for triangles within ``watch = max(b, OFFSET_FAR
tau)`` only (then, when one is nearer, for the others of its blend), so the deep points cost a
parity test and a look at the cells around them (`fibres.mesh.surface_distance`).

Cost: the surface's grids are built per call, O(T), by compiled loops; the search per point
visits the cells near it (timings: bench/README.md; what was tried: docs/decisions.md).
"""
from __future__ import annotations

import numpy as np

from ..mesh.surface_distance import OFFSET_FAR, SurfaceGrid

__all__ = ["contain", "CONTAIN_MARGIN", "CONTAIN_REACH", "CONTAIN_SOFTNESS"]

#: band depth b (metres) of the pull: points shallower move, and end at least b / 2 deep
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
            iterations: int = 2, grid: SurfaceGrid | None = None):
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
        Band depth b: a point at signed distance s > -b goes to
        ``-b + (b / 2) (1 - exp(-2 (s + b) / b))`` (< -b / 2: inside).
    softness : float, keyword-only
        Soft-min width tau of the distance blend (`fibres.mesh.surface_distance`).
    reach : float, keyword-only
        Points farther from every triangle are taken as inside.
    iterations : int, keyword-only
        Pull steps (>= 1): the first moves by ``s - s'`` along the shortest path, the
        others correct towards the same ``s'`` from the new closest point.
    grid : SurfaceGrid, keyword-only
        The surface already prepared with this ``reach`` (several pulls on one surface bin
        its triangles once); ``vertices`` and ``faces`` must be the grid's.

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
    if grid is None:
        grid = SurfaceGrid(vertices, faces, reach=reach)
    elif grid.reach != float(reach):
        raise ValueError(f"the grid's reach {grid.reach} is not the pull's {reach}")
    # inside points deeper than the band are not measured: they look for triangles within
    # `watch` only (and, when one is nearer, for every triangle of their blend); beyond
    # OFFSET_FAR tau the offset measure is the blended distance (>= d_min), so an inside
    # point farther than watch from every triangle is deeper than the band: not pulled.
    watch = max(margin, OFFSET_FAR * softness)
    # the inner points, fibre by fibre (the flat rows `_inner`; a strided copy)
    s, d = grid.signed_distance(out[:, 1:-1].reshape(-1, 3), tau=softness, watch=watch,
                                offset=True)
    return _pull(out, s, d, grid, margin, softness, iterations, watch)


def _pull(out, s, d, grid, margin, softness, iterations, watch):
    """Move the inner points of out (N, P, 3) (flat rows `_inner`, in that order) with
    signed distance s > -margin along -d to ``s'`` (module docstring), in place; returns
    (out, moved (N,))."""
    n, p = out.shape[:2]
    moved = np.zeros(n, bool)
    band = s > -margin                    # (-inf, i.e. deep or unmeasured, is not)
    if not band.any():
        return out, moved
    flat = out.reshape(-1, 3)
    rows, s, d = _inner(n, p)[band], s[band], d[band]
    a = 0.5 * margin
    target = -margin - a * np.expm1(-(s + margin) / a)
    y = flat[rows] - (s - target)[:, None] * d
    for _ in range(int(iterations) - 1):  # correction steps (a few), not a loop over points
        s2, d2 = grid.signed_distance(y, tau=softness, watch=watch, offset=True)
        ok = np.isfinite(s2)                  # (-inf: deeper than watch, no correction)
        y[ok] -= (s2[ok] - target[ok])[:, None] * d2[ok]
    flat[rows] = y
    moved[rows // p] = True
    return out, moved

