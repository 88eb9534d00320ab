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

Watched points (a speed-up for motions). `containment_choice` marks, on one pose (the rest
pose, kept in the `fibres.DecompositionPlan` with the attachment filter's choices), the inner
points that are outside or within `watch` (2 mm) of the surface; `apply_containment` then
measures only those on every frame (the search is made afresh per frame: fibres slide along
the surface when it deforms, so a frozen set of candidate triangles would go stale). Points
deeper than `watch` on the rest pose are taken as staying inside. Points with no triangle
within `reach` (8 mm) are taken as inside (the chain's excursions are a few mm).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .surface_distance import SurfaceGrid

__all__ = ["ContainChoice", "containment_choice", "apply_containment", "contain",
           "CONTAIN_MARGIN", "CONTAIN_REACH", "CONTAIN_SOFTNESS", "CONTAIN_WATCH"]

#: depth scale m (metres) of the pull: points far outside end less than m outside
CONTAIN_MARGIN = 2e-4
#: points farther than this (metres) from every triangle are taken as inside
CONTAIN_REACH = 8e-3
#: soft-min width tau (metres) of the blend over the nearest triangles
CONTAIN_SOFTNESS = 5e-5
#: inner points within this depth (metres) on the choice's pose are watched
CONTAIN_WATCH = 2e-3


@dataclass(frozen=True)
class ContainChoice:
    """The inner fibre points that `apply_containment` measures.

    Attributes
    ----------
    index : (W,) int64
        Flat indices ``fibre * P + point`` of the watched points (never an end point),
        ascending.
    n_points : int
        P, points per fibre.
    cell : float
        Grid cell size used on the choice's pose (reused for speed; results do not depend
        on it).
    """

    index: np.ndarray
    n_points: int
    cell: float | None = None

    def __post_init__(self):
        a = np.array(self.index, dtype=np.int64, copy=True)
        if a.ndim != 1:
            raise ValueError("index must be (W,)")
        a.flags.writeable = False
        object.__setattr__(self, "index", a)
        object.__setattr__(self, "n_points", int(self.n_points))

    def head(self, n: int) -> "ContainChoice":
        """The choices of the first ``n`` fibres."""
        return ContainChoice(self.index[self.index < n * self.n_points], self.n_points,
                             self.cell)


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


def containment_choice(points, vertices, faces, *, watch: float = CONTAIN_WATCH,
                       reach: float = CONTAIN_REACH, grid: SurfaceGrid | None = None
                       ) -> ContainChoice:
    """Mark the inner fibre points that are outside or within `watch` of the surface.

    Parameters
    ----------
    points : (N, P, 3) float
    vertices : (V, 3) float
    faces : (T, 3) int
        Closed, consistently and outward wound surface.
    watch : float, keyword-only
        Depth (metres) down to which inside points are watched.
    reach : float, keyword-only
        Points farther from every triangle are taken as inside.
    grid : SurfaceGrid, optional, keyword-only
        The surface already prepared (same vertices and faces).

    Returns
    -------
    ContainChoice
    """
    _check(watch=watch, reach=reach)
    pts = _as_fibres(points)
    n, p = pts.shape[:2]
    grid = SurfaceGrid(vertices, faces, reach=reach) if grid is None else grid
    if n == 0 or p < 3:
        return ContainChoice(np.zeros(0, np.int64), p, grid.cell)
    flat = _inner(n, p)
    s, _ = grid.signed_distance(pts.reshape(-1, 3)[flat], tau=CONTAIN_SOFTNESS, watch=watch)
    return ContainChoice(flat[np.isfinite(s) & (s > -watch)], p, grid.cell)


def apply_containment(points, vertices, faces, choice: ContainChoice | None = None, *,
                      margin: float = CONTAIN_MARGIN, softness: float = CONTAIN_SOFTNESS,
                      reach: float = CONTAIN_REACH, iterations: int = 2,
                      grid: SurfaceGrid | None = None):
    """Pull the inner points that lie outside the surface back in (module docstring).

    Parameters
    ----------
    points : (N, P, 3) float
        Fibres.
    vertices : (V, 3) float
    faces : (T, 3) int
        Closed, consistently and outward wound surface (the choice's pose or a deformed
        copy with the same faces).
    choice : ContainChoice, optional
        Measure only these points (N <= the choice's fibres, same P); None: every inner
        point.
    margin : float, keyword-only
        m: a point at signed distance s > 0 goes to ``m (1 - exp(-s / m))`` (< m).
    softness : float, keyword-only
        Soft-min width tau of the distance blend.
    reach : float, keyword-only
        Points farther from every triangle are taken as inside.
    iterations : int, keyword-only
        Pull steps (>= 1): the first moves by ``s - s'`` along the shortest path, the
        others correct towards the same ``s'`` from the new closest point.
    grid : SurfaceGrid, optional, keyword-only
        The surface already prepared (same vertices and faces).

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
    moved = np.zeros(n, bool)
    if choice is None:
        index = _inner(n, p) if p >= 3 else np.zeros(0, np.int64)
        cell = None
    else:
        if p != choice.n_points:
            raise ValueError(f"the choice is for {choice.n_points} points per fibre, got {p}")
        index, cell = choice.head(n).index, choice.cell
    if len(index) == 0:
        return out, moved
    if grid is None:
        grid = SurfaceGrid(vertices, faces, reach=reach, cell=cell)
    flat = out.reshape(-1, 3)
    s, d = grid.signed_distance(flat[index], tau=softness)
    outside = s > 0
    if not outside.any():
        return out, moved
    rows, s, d = index[outside], s[outside], d[outside]
    target = margin * -np.expm1(-s / margin)
    y = flat[rows] - (s - target)[:, None] * d
    for _ in range(int(iterations) - 1):  # correction steps (a few), not a loop over points
        s2, d2 = grid.signed_distance(y, tau=softness)
        y = np.where(np.isfinite(s2)[:, None], y - (s2 - target)[:, None] * d2, y)
    flat[rows] = y
    moved[rows // p] = True
    return out, moved


def contain(points, vertices, faces, *, margin: float = CONTAIN_MARGIN,
            softness: float = CONTAIN_SOFTNESS, reach: float = CONTAIN_REACH,
            iterations: int = 2):
    """`apply_containment` on every inner point (no choice).

    Returns
    -------
    points : (N, P, 3) float64
    moved : (N,) bool
    """
    return apply_containment(points, vertices, faces, None, margin=margin, softness=softness,
                             reach=reach, iterations=iterations)
