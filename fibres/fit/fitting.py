"""Fitting the template cube to a muscle: principal axis and oriented bounding box (OBB).

Kohout et al. (GRAPP 2012) §3.2. The principal axis passes through the centroid of the surface
vertices; its direction is the vector from the centroid of the origin landmarks to the centroid
of the insertion landmarks or, when the attachments do not define it well, the eigenvector of
the largest eigenvalue of the vertex covariance matrix (eq. 1-2). Two vectors v0, w0 complete
an orthonormal frame; they are rotated about the axis in steps of 5 degrees and for each frame
the minimal box of the vertices aligned with it is built. The winner is the box whose template
attachment areas, mapped into the box, best match the user's landmarks: for every template area
point the distance to the closest landmark of the same attachment, summed over both areas.

All rotations are evaluated at once: (J, V) projections of the vertices that can be extreme
(`fibres.fit.support_screen`), (J, K_template, K_landmarks) distances.

Ties in the oblique-axis iteration (`principal_frame` with e.g. the pennate template). When
the landmarks are symmetric about the attachment line (two rings of landmarks around the
tips), two rotations 180 degrees apart match equally well and their scores differ by
rounding only (~1e-16 relative), yet they shift the axis to opposite sides. Rotations whose
score is within `ROTATION_TIE` (relative) of the best count as tied, and the tie is broken by
the muscle's shape, invariant under any rigid motion of the input: (1) the rotation whose
cross-section offset (the template's insertion band relative to its origin band, mapped into
the box) points farthest towards the muscle's bulk -- the offset of the vertex centroid from
the line through the origin-landmark centroid along the attachment vector -- where these
differ by more than `ROTATION_TIE` x offset x muscle size; else (2) the same with the
vertex-order moment ``sum_k (k + 1) (V_k - c)`` (the sign rule of the cross-section
reference in `fibres.decompose`, which rides along with the vertices); else (3) the lowest
rotation index.

Axis rule (``axis="auto"``): the attachment direction is used unless the two landmark
centroids are closer than ``AUTO_MIN_SEPARATION`` (1/4) of the surface's extent along its
covariance axis; then the covariance axis is used, oriented from origin to insertion. The
extent along any unit axis is at most the diagonal of the surface's bounding box, so where
the centroids are at least 1/4 of that diagonal apart (most muscles) the covariance is not
computed at all: the rule's answer is the same.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..errors import InputError
from .box import Box, _check_in_box, check_landmarks  # noqa: F401 - re-exported
from .support_screen import polygon_screen
from ..template.templates import Template, get_template

__all__ = ["Box", "PrincipalFrame", "principal_frame", "fit_box", "check_landmarks",
           "template_offset", "reference_frame", "AUTO_MIN_SEPARATION", "ROTATION_TIE"]

AUTO_MIN_SEPARATION = 0.25
#: relative margin on the bounding-box diagonal that bounds the covariance extent: the
#: computed extent ``ptp(d @ axis)`` exceeds the true one by rounding only (~1e-15
#: relative), so ``dist >= AUTO_MIN_SEPARATION * diagonal * (1 + _AUTO_SURE)`` decides
#: "attachments" exactly as the extent would, without the covariance and its eigenvectors
_AUTO_SURE = 1e-9
_MAX_OBLIQUE_ITERATIONS = 200
#: relative score margin within which rotations of the oblique-axis iteration are tied
#: (module docstring): far above rounding (1e-16), far below real score differences
ROTATION_TIE = 1e-9
_AXES = ("attachments", "covariance", "auto")


class PrincipalFrame(NamedTuple):
    """Centroid (3,), unit principal axis u (3,) and the reference cross-section axes v0, w0
    (3,) with (v0, w0, u) right-handed orthonormal; ``method`` is "attachments" or
    "covariance"."""

    centroid: np.ndarray
    axis: np.ndarray
    v0: np.ndarray
    w0: np.ndarray
    method: str


def _as_set(points, name):
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim == 1 and pts.shape == (3,):
        pts = pts[None]
    if pts.ndim != 2 or pts.shape[1:] != (3,):
        raise InputError(f"the {name} landmarks must be (K, 3), got shape {pts.shape}",
                         where=name, fix="Give three coordinates per landmark.")
    if len(pts) == 0:
        raise InputError(f"the {name} landmark set is empty", where=name,
                         fix="Give at least one landmark of the attachment area.")
    if not np.isfinite(pts).all():
        raise InputError(f"the {name} landmarks contain NaN or infinite values", where=name,
                         fix="Give finite coordinates.")
    return pts


def cross3(a, b):
    """Cross product of (..., 3) arrays: numpy's formula component by component (bit for bit
    ``np.cross``, without its overhead for single vectors)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.ndim == 1 and b.ndim == 1:  # two vectors: Python floats, the same operations
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _norm(x) -> float:
    """``np.linalg.norm`` of a real 1D array without its overhead: its formula, the square
    root of ``x.dot(x)`` of the contiguous ``x.ravel()`` (the same number)."""
    x = x.ravel()
    return math.sqrt(x.dot(x))


def _covariance_axis(vertices, centroid, d=None):
    """Eigenvector of the largest eigenvalue of the vertex covariance (Kohout 2012 eq. 1-2);
    ``d`` is ``vertices - centroid`` when at hand."""
    d = _centred(vertices, centroid) if d is None else d
    cov = d.T @ d / max(len(d) - 1, 1)  # Kohout 2012 eq. 1-2
    evals, evecs = np.linalg.eigh(cov)
    return evecs[:, -1]


def _frame_for(u, v_ref):
    """(v0, w0) completing u to a right-handed orthonormal frame (v0 from ``v_ref``)."""
    if v_ref is None:
        ref = np.eye(3)[int(np.argmin(np.abs(u)))]
    else:
        ref = np.asarray(v_ref, dtype=np.float64)
        if abs(ref @ u) > 0.999 * _norm(ref):
            ref = np.eye(3)[int(np.argmin(np.abs(u)))]
    v0 = ref - (ref @ u) * u
    v0 /= _norm(v0)
    return v0, cross3(u, v0)


def _boxes(vertices, c, u, v0, w0, theta, *, blas=False):
    """Minimal boxes of the vertices in the frames rotated by ``theta`` (J,) about u.

    The centred vertices ``d = vertices - c`` are projected on v0, w0 and u as
    ``(d_x v_x + d_y v_y) + d_z v_z`` (a fixed order), or with ``blas`` as ``d @ v0`` etc.
    (numpy's matrix products; the oblique-axis iteration of `principal_frame` keeps these,
    its axis depends on the extents). Only vertices that can be extreme in some direction of
    the cross-section enter the (J, V') projections (`_support_candidates`); the others
    cannot change a minimum or maximum, so the boxes are exactly those of all vertices.
    Compiled: everything after the BLAS projections, or everything, in one pass
    (numpy).

    Parameters
    ----------
    vertices : (V, 3) float
    c, u, v0, w0 : (3,) float
    theta : (J,) float

    Returns axes (J, 3, 3) (columns x, y, z), corner (J, 3), extents (J, 3)."""
    n_rot = len(theta)
    f64 = np.float64
    c, u, v0, w0 = (np.ascontiguousarray(x, dtype=f64) for x in (c, u, v0, w0))
    vertices = np.asarray(vertices, dtype=f64)
    if blas:
        d = _centred(vertices, c)
        a, b, z = d @ v0, d @ w0, d @ u                               # (V,)
    if not blas:
        d = vertices - c                                              # (V, 3)
        a, b, z = ((d[:, 0] * e[0] + d[:, 1] * e[1]) + d[:, 2] * e[2] for e in (v0, w0, u))
    xs = np.cos(theta)[:, None] * v0 + np.sin(theta)[:, None] * w0    # (J, 3)
    ys = cross3(u, xs)                                                # (J, 3)
    keep = _polygon_screen(a, b)
    a, b = a[keep], b[keep]
    px = np.cos(theta)[:, None] * a + np.sin(theta)[:, None] * b      # (J, V')
    py = -np.sin(theta)[:, None] * a + np.cos(theta)[:, None] * b     # (J, V')
    x_lo, x_hi, y_lo, y_hi = px.min(axis=1), px.max(axis=1), py.min(axis=1), py.max(axis=1)
    lo = np.stack([x_lo, y_lo, np.full(n_rot, z.min())], axis=1)
    ext = np.stack([x_hi, y_hi, np.full(n_rot, z.max())], axis=1) - lo
    axes = np.stack([xs, ys, np.broadcast_to(u, xs.shape)], axis=2)
    corner = c + np.einsum("jkl,jl->jk", axes, lo)
    return axes, corner, ext


def _support_candidates(a, b):
    """Indices (V',) int64, increasing, of the 2D points a, b (V,) that can attain a minimum
    or maximum of a projection ``cos(t) a + sin(t) b`` for some angle t (a superset of the
    convex hull's vertices; `fibres.fit.support_screen`: three polygons)."""
    return _polygon_screen(a, b)


def _polygon_screen(a, b):
    """`_support_candidates` by the polygons of `fibres.fit.support_screen`."""
    spread = max(float(np.ptp(a)), float(np.ptp(b))) if a.size else 0.0
    return polygon_screen(a, b, spread)


def _centred(vertices, c):
    """(V, 3) ``vertices - c``, bit for bit."""
    return vertices - c


def _closest_sum(area, landmarks):
    """Sum over area points of the distance to the closest landmark: area (J, Ka, 3)."""
    d2 = 0.0
    for c in range(3):      # component-wise: a reduction over the size-3 axis is slow
        dc = area[:, :, c, None] - landmarks[:, c]                      # (J, Ka, K)
        d2 = d2 + dc * dc
    return np.sqrt(d2).min(axis=2).sum(axis=1)


def _scores(template, axes, corner, ext, origin, insertion):
    """Matching error (J,) of the template areas mapped into each box (Kohout 2012 §3.2).

    Compiled: mapping and closest-landmark distances in one pass per area
    (`_mapped_nearest_loop`, same operations and order, no (J, Ka, 3) temporaries)."""
    scale = axes * ext[:, None, :]                                    # (J, 3, 3)

    def mapped(area):  # corner + sum_l area[k, l] scale[j, :, l], in the order of numpy's
        a = np.asarray(area, dtype=np.float64)[None, :, None, :]  # einsum (0 + 2) + 1
        s = scale[:, None]
        return corner[:, None] + ((a[..., 0] * s[..., 0] + a[..., 2] * s[..., 2])
                                  + a[..., 1] * s[..., 1])

    t_ori = mapped(template.origin_area)
    t_ins = mapped(template.insertion_area)
    return _closest_sum(t_ori, origin) + _closest_sum(t_ins, insertion)


def _thetas(step):
    n_rot = max(int(np.floor(360.0 / step + 1e-9)), 1)
    return np.deg2rad(step * np.arange(n_rot))


def template_offset(template) -> np.ndarray:
    """(2,) cross-section offset (x, y) of the template's insertion-area centroid from its
    origin-area centroid, in unit-cube units (zero for every default template but pennate)."""
    return np.array(template.offset)             # made with the template (`Template.offset`)


def principal_frame(vertices, origin, insertion, *, axis: str = "auto", v_ref=None,
                    template=None, angle_step_deg: float = 5.0,
                    angle_index: int | None = None,
                    prepared: Prepared | None = None) -> PrincipalFrame:
    """The muscle's principal axis and reference frame (Kohout 2012 §3.2).

    Parameters
    ----------
    vertices : (V, 3) float
        Surface vertices.
    origin, insertion : (K, 3) float
        Landmarks of the attachment areas.
    axis : {"auto", "attachments", "covariance"}, keyword-only
        How to choose the direction (module docstring); it always points from the origin
        towards the insertion.
    v_ref : (3,) float, optional
        Direction whose projection perpendicular to the axis becomes v0 (a plan passes the
        rest-pose v0 carried along with the muscle). Default: the world axis least aligned
        with u.
    template : Template or str, optional
        Oblique templates (attachment centroids not above one another, e.g. pennate): the
        attachment direction is the box's z axis plus the template's cross-section offset
        scaled by the box, ``D = ez u + ex dx x + ey dy y``; with a template the axis solves
        this by fixed-point iteration ``u <- normalise(D - ex dx x - ey dy y)`` (boxes built
        as in `fit_box`). Without a template (or with a centred one) u = D / |D|, as in the
        paper.
    angle_step_deg : float, keyword-only
        Rotation step of the box search used by the iteration.
    angle_index : int, optional
        Use this rotation instead of searching (re-deriving a planned box).
    prepared : Prepared, optional
        `prepare` of exactly these vertices when at hand (speed only: the same frame).

    Returns
    -------
    PrincipalFrame
    """
    if axis not in _AXES:
        raise ValueError(f"axis must be one of {_AXES}, got {axis!r}")
    vertices = np.asarray(vertices, dtype=np.float64)
    vt = _transposed(vertices) if prepared is None else prepared.vt
    return _principal_frame(vertices, vt, _as_set(origin, "origin"),
                            _as_set(insertion, "insertion"), axis=axis, v_ref=v_ref,
                            template=template, angle_step_deg=angle_step_deg,
                            angle_index=angle_index, prepared=prepared)


def reference_frame(frame: PrincipalFrame, v_ref, template=None) -> PrincipalFrame | None:
    """``frame`` with v0, w0 taken from ``v_ref`` -- what `principal_frame` returns for the
    same inputs with this ``v_ref`` -- or None where the axis itself depends on v_ref (an
    oblique template with the attachment axis: the fixed-point iteration searches rotations
    of v0), which then needs `principal_frame` again.

    Parameters
    ----------
    frame : PrincipalFrame
        From `principal_frame` (any ``v_ref``).
    v_ref : (3,) float or None
    template : Template or str, optional
        The template ``frame`` was computed with.

    Returns
    -------
    PrincipalFrame or None
    """
    if template is not None and frame.method == "attachments":
        if not isinstance(template, Template):
            template = get_template(template)
        if template.oblique:
            return None
    v0, w0 = _frame_for(frame.axis, v_ref)
    return PrincipalFrame(frame.centroid, frame.axis, v0, w0, frame.method)


def _transposed(vertices):
    """(3, V) C-contiguous copy of (V, 3) vertices: reductions over the vertices then run
    along contiguous rows (over axis 0 of (V, 3) they are ~10-50x slower)."""
    return np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)


class Prepared(NamedTuple):
    """Arrays of one vertex set that several stages of a decomposition use (`prepare`)."""

    vt: np.ndarray        # (3, V) C-contiguous transposed vertices (`_transposed`)
    lo: np.ndarray        # (3,) coordinate-wise minimum
    hi: np.ndarray        # (3,) coordinate-wise maximum
    centroid: np.ndarray  # (3,) mean of the vertices


def prepare(vertices) -> Prepared:
    """The transposed vertices, their bounds and centroid, made once for the stages of a
    decomposition that would each make them (`principal_frame`, `fit_box`, the attachment
    filter, the containment grid): the same arrays, bit for bit."""
    vertices = np.asarray(vertices, dtype=np.float64)
    vt, centroid = _transposed(vertices), vertices.mean(axis=0)
    return Prepared(vt, vt.min(axis=1), vt.max(axis=1), centroid)


def _size(vt):
    """Diagonal of the axis-aligned bounding box of (3, V) vertices."""
    return _norm(vt.max(axis=1) - vt.min(axis=1))


def _principal_frame(vertices, vt, origin, insertion, *, axis, v_ref, template,
                     angle_step_deg, angle_index, prepared=None):
    """`principal_frame` on vertices (V, 3), the same transposed ``vt`` (3, V) and checked
    landmark sets; ``prepared``: `prepare` of these vertices when at hand."""
    if prepared is None:
        centroid, size = vertices.mean(axis=0), _size(vt)
    else:
        centroid, size = prepared.centroid, _norm(prepared.hi - prepared.lo)   # `_size`

    direction = insertion.mean(axis=0) - origin.mean(axis=0)
    dist = _norm(direction)
    if dist <= 1e-9 * max(size, 1e-300):
        raise InputError("the origin and insertion landmarks have the same centroid",
                         where="origin/insertion",
                         fix="Give the two attachment areas of the muscle (origin on one bone, "
                             "insertion on the other).")
    method = axis
    if axis == "auto" and dist >= AUTO_MIN_SEPARATION * size * (1.0 + _AUTO_SURE):
        method = "attachments"  # the extent along any unit axis is at most the box diagonal
    elif axis in ("covariance", "auto"):
        d = _centred(vertices, centroid)
        cov_axis = _covariance_axis(vertices, centroid, d)
        if axis == "auto":
            length = float(np.ptp(d @ cov_axis))
            method = "covariance" if dist < AUTO_MIN_SEPARATION * length else "attachments"
    if method == "attachments":
        u = direction / dist
    else:
        u = cov_axis if cov_axis @ direction >= 0 else -cov_axis
    v0, w0 = _frame_for(u, v_ref)
    if template is not None and method == "attachments":
        if not isinstance(template, Template):
            template = get_template(template)
        if template.oblique:
            off = template.offset
            theta = _thetas(float(angle_step_deg))
            if angle_index is not None:
                theta = theta[[int(angle_index) % len(theta)]]
            for it in range(_MAX_OBLIQUE_ITERATIONS):
                axes, corner, ext = _boxes(vertices, centroid, u, v0, w0, theta, blas=True)
                j = _best_rotation(_scores(template, axes, corner, ext, origin, insertion),
                                   axes, ext, off, origin, direction, vertices, centroid)
                if it == 3:  # the rotation has settled: keep it, iterate on the axis only
                    theta = theta[[j]]
                new = direction - ext[j, 0] * off[0] * axes[j, :, 0] \
                    - ext[j, 1] * off[1] * axes[j, :, 1]
                new /= _norm(new)
                done = _norm(new - u) < 1e-12
                u = new
                v0, w0 = _frame_for(u, v_ref)
                if done:
                    break
    return PrincipalFrame(centroid, u, v0, w0, method)


def _best_rotation(scores, axes, ext, off, origin, direction, vertices, centroid) -> int:
    """Index of the best-scoring rotation of the oblique-axis iteration with the tie rule of
    the module docstring. scores (J,), axes (J, 3, 3), ext (J, 3), off (2,), origin (K, 3),
    direction (3,) (the attachment vector), vertices (V, 3), centroid (3,)."""
    tied = np.flatnonzero(scores <= scores.min() * (1.0 + ROTATION_TIE) + 1e-300)
    if tied.size == 1:
        return int(tied[0])
    shift = (ext[tied, 0, None] * off[0] * axes[tied, :, 0]
             + ext[tied, 1, None] * off[1] * axes[tied, :, 1])                # (J', 3)
    reach = float(np.linalg.norm(shift, axis=1).max()) * float(np.ptp(vertices, axis=0).max())
    # (1) towards the bulk: the centroid's offset from the attachment line
    rel = centroid - origin.mean(axis=0)
    bulk = rel - (rel @ direction) / (direction @ direction) * direction
    # (2) the vertex-order moment sum_k (k + 1) (V_k - c), which rides along with the vertices
    dt = _transposed(vertices) - centroid[:, None]                               # (3, V)
    k = np.arange(1.0, dt.shape[1] + 1.0)
    moment = np.array([np.dot(k, dt[c]) for c in range(3)])  # coordinates
    for ref, scale in ((bulk, reach), (moment, reach * np.sqrt(k @ k))):  # two rules
        along = shift @ ref
        keep = along >= along.max() - ROTATION_TIE * scale
        tied, shift = tied[keep], shift[keep]
        if tied.size == 1:
            break
    return int(tied[0])


def fit_box(vertices, origin, insertion, template="parallel", *, angle_step_deg: float = 5.0,
            axis: str = "auto", v_ref=None, check_units: bool = True,
            frame: PrincipalFrame | None = None, prepared: Prepared | None = None) -> Box:
    """Fit the template cube to the muscle as the best-matching principal-axis OBB.

    Kohout et al. (GRAPP 2012) §3.2, vectorised over all rotations.

    Parameters
    ----------
    vertices : (V, 3) float
        Surface vertices (metres).
    origin, insertion : (K, 3) float
        Attachment landmarks.
    template : Template or str
        Supplies the template attachment areas compared with the landmarks.
    angle_step_deg : float, keyword-only
        Rotation step about the axis (5 degrees in the paper); rotations cover a full turn.
    axis : {"auto", "attachments", "covariance"}, keyword-only
        See `principal_frame`.
    v_ref : (3,) float, optional
        Reference for v0 (see `principal_frame`).
    check_units : bool, keyword-only
        Run `check_landmarks` on both sets (refuses unit mistakes).
    frame : PrincipalFrame, optional
        The principal frame of exactly these inputs (vertices, landmarks, ``axis``,
        ``template``, ``v_ref``, ``angle_step_deg``) when already at hand (e.g. from
        `reference_frame`); computed when None.
    prepared : Prepared, optional
        `prepare` of exactly these vertices when at hand (speed only: the same box).

    Returns
    -------
    Box
    """
    if not isinstance(template, Template):
        template = get_template(template)
    step = float(angle_step_deg)
    if not (0 < step <= 180):
        raise ValueError(f"angle_step_deg must be in (0, 180], got {angle_step_deg!r}")
    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) < 4:
        raise InputError(f"need at least 4 surface vertices (V, 3), got {vertices.shape}",
                         where="mesh", fix="Pass the muscle's closed surface.")
    origin = _as_set(origin, "origin")
    insertion = _as_set(insertion, "insertion")
    if axis not in _AXES:
        raise ValueError(f"axis must be one of {_AXES}, got {axis!r}")
    if prepared is None:
        vt = _transposed(vertices)
        lo, hi = vt.min(axis=1), vt.max(axis=1)
    else:
        vt, lo, hi = prepared.vt, prepared.lo, prepared.hi
    if check_units:
        _check_in_box(lo, hi, origin, name="origin")
        _check_in_box(lo, hi, insertion, name="insertion")
    if frame is None:
        frame = _principal_frame(vertices, vt, origin, insertion, axis=axis, v_ref=v_ref,
                                 template=template, angle_step_deg=step, angle_index=None,
                                 prepared=prepared)
    axes, corner, ext = _boxes(vertices, frame.centroid, frame.axis, frame.v0, frame.w0,
                               _thetas(step))
    size = _norm(hi - lo)
    if (ext <= 1e-12 * max(size, 1e-300)).any():
        raise InputError("the surface is flat (zero thickness)", where="mesh",
                         fix="Pass the muscle's closed volume surface.")
    scores = _scores(template, axes, corner, ext, origin, insertion)
    best = int(np.argmin(scores))
    return Box(corner[best], axes[best], ext[best], best, step, scores, frame.method)
