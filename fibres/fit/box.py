"""The fitted box of Kohout et al. (GRAPP 2012, §3.2) and the landmarks' unit check.

`Box` is the template cube fitted to a muscle (`fibres.fit.fitting.fit_box`): a corner, three
orthonormal axes (z the principal axis, origin to insertion) and the edge lengths, with the maps
between unit-cube and world coordinates. `check_landmarks` refuses landmarks that miss the
surface by orders of magnitude and names a metres/millimetres mix-up where that explains it.
`shape_sign` orients a cross-section direction by the muscle's shape (the box's v0 here, the
harmonic slicing's cross-section axis in `fibres.slicing.harmonic_sections`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

__all__ = ["Box", "check_landmarks", "shape_sign", "SHAPE_TIE"]

#: relative size below which a shape moment counts as zero (`shape_sign`): far above the
#: rounding of the sums (~1e-13 relative for 1e5 points), far below a real asymmetry
SHAPE_TIE = 1e-9


def shape_sign(q, a, u, e) -> int:
    """+1 or -1: the sign ``s`` that makes ``s e`` point the muscle's way, told by its shape
    alone; 0 where the shape is symmetric enough not to tell.

    ``e`` is a unit direction perpendicular to the unit axis ``u``, and the points (the
    vertices) are given about a centre as their along-axis offsets ``a`` (V,) and in-plane
    parts ``q`` (3, V). Two moments of the points, in order:

    1. the in-plane skew ``m = sum_k |q_k|^2 q_k`` (which side of the cross-section the bulk
       leans to: the outer side of a bent muscle, the thick edge of a wedge);
    2. the tilt ``t = sum_k a_k q_k`` (which way the muscle slants or bends along the axis).

    For the first moment that is not zero (relative to ``sum |q|^3``, resp.
    ``sum |a| |q|``, by `SHAPE_TIE`), ``s`` makes its larger component point along ``s e``
    or, where that is the one along ``u x e``, along ``u x (s e)`` (a handedness, which tells
    the two directions apart also on a muscle that is mirror-symmetric about the plane
    normal to e; the larger component, so that a small asymmetry does not decide).

    Sums over the points: unchanged by their order (up to rounding), by a rigid motion of
    the points with u and e, and by a uniform scale -- unlike a rule on the vertex
    numbering, which a mesh exporter's renumbering flips."""
    e2 = np.array([u[1] * e[2] - u[2] * e[1], u[2] * e[0] - u[0] * e[2],
                   u[0] * e[1] - u[1] * e[0]])
    r2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2]
    r = np.sqrt(r2)
    for w, scale in ((r2, float(np.dot(r2, r))), (a, float(np.dot(np.abs(a), r)))):
        m = np.array([np.dot(w, q[c]) for c in range(3)])  # coordinates
        x1, x2 = float(m @ e), float(m @ e2)
        x = x1 if abs(x1) >= abs(x2) else x2
        if abs(x) > SHAPE_TIE * scale:
            return 1 if x > 0 else -1
    return 0


def check_landmarks(vertices, points, *, name: str = "landmarks", file=None):
    """Refuse landmarks that miss the surface by orders of magnitude (a unit mistake).

    If even the closest landmark is farther from the surface's bounding box than the surface's
    size, and scaling the landmarks by 1000 or 1/1000 would put them on the surface, the
    message names the unit mistake; beyond 5 surface sizes the landmarks are refused anyway.

    Parameters
    ----------
    vertices : (V, 3) float
    points : (K, 3) float
    """
    v = np.asarray(vertices, dtype=np.float64)
    _check_in_box(v.min(axis=0), v.max(axis=0), np.asarray(points, dtype=np.float64),
                  name=name, file=file)


def _check_in_box(lo, hi, points, *, name, file=None):
    """`check_landmarks` with the surface's bounding box ``lo``, ``hi`` (3,) at hand."""
    if ((points >= lo) & (points <= hi)).all(axis=1).any():
        return              # a landmark in the box: the gap below is 0
    size = float(np.linalg.norm(hi - lo))

    def gap(p):
        return float(np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0), axis=1).min())

    g = gap(points)
    if g <= size:
        return
    for factor, hint in ((1e3, "the landmarks look like metres and the surface like "
                               "millimetres"),
                         (1e-3, "the landmarks look like millimetres and the surface like "
                                "metres")):
        if gap(points * factor) <= 0.1 * size:
            raise InputError(f"the {name} landmarks lie {g:.3g} from a surface only "
                             f"{size:.3g} across: {hint}", file=file, where=name,
                             fix="Give the surface and the landmarks in the same units "
                                 "(--units m|mm applies to both).")
    if g > 5 * size:
        raise InputError(f"the {name} landmarks lie {g:.3g} from a surface only {size:.3g} "
                         "across", file=file, where=name,
                         fix="Check that the landmarks belong to this muscle and use its units.")


@dataclass(frozen=True)
class Box:
    """An oriented box: the template cube fitted to a muscle (Kohout 2012 §3.2).

    Attributes
    ----------
    corner : (3,) float
        World position of the unit-cube point (0, 0, 0).
    axes : (3, 3) float
        COLUMNS are the unit x, y, z directions; z is the principal axis (origin -> insertion).
    extents : (3,) float
        Edge lengths along x, y, z.
    angle_index : int
        Which rotation of (v0, w0) won (angle = angle_index * angle_step_deg).
    angle_step_deg : float
    scores : (J,) float
        Matching error of every rotation (sum of closest distances, both areas).
    method : str
        How the axis was chosen ("attachments" or "covariance").
    """

    corner: np.ndarray
    axes: np.ndarray
    extents: np.ndarray
    angle_index: int
    angle_step_deg: float = 5.0
    scores: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    method: str = "attachments"

    def __post_init__(self):
        for name, shape in (("corner", (3,)), ("axes", (3, 3)), ("extents", (3,))):
            arr = np.array(getattr(self, name), dtype=np.float64)
            if arr.shape != shape:
                raise ValueError(f"{name} must be {shape}, got {arr.shape}")
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        s = np.array(self.scores, dtype=np.float64)
        s.flags.writeable = False
        object.__setattr__(self, "scores", s)
        object.__setattr__(self, "angle_index", int(self.angle_index))

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) affine map from unit-cube to world coordinates."""
        m = np.eye(4)
        m[:3, :3] = self.axes * self.extents
        m[:3, 3] = self.corner
        return m

    def to_world(self, unit_pts) -> np.ndarray:
        """Unit-cube points (..., 3) -> world points (..., 3)."""
        return self.corner + np.asarray(unit_pts, dtype=np.float64) @ (self.axes * self.extents).T

    def to_unit(self, world_pts) -> np.ndarray:
        """World points (..., 3) -> unit-cube coordinates (..., 3)."""
        return ((np.asarray(world_pts, dtype=np.float64) - self.corner) @ self.axes) / self.extents
