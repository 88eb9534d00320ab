"""Wrapped paths in few compiled passes: paths with the same kind of wraps share one call.

Contract: `wrap_paths` returns, for each path, its length, dL/dq along its own coordinates, its
current points, mask, labels and node order, by OpenSim 4.6's applyWrapObjects
(`motion.wrapping.wrapped_rows`); `wrap_path` does it for one path along all coordinates (the
moving surfaces use it). `WrapSlot` and `wrap_spec` describe one PathWrap for the kernel.

Method. The kernel runs rows (path x frame); a call has a fixed sequence of wrap kinds, so
paths are grouped by the *signature* of their wraps (per PathWrap: the kind, quadrant,
tangent re-adjustment, ellipsoid method and whether the object is active); the paths of one
group become rows of one call:

- defined points are padded to the group's largest point count with inactive points (the
  current path skips inactive points, so padding never enters it);
- each path's derivative directions are its own spanned coordinates (``columns``), padded with
  zeros to the group's largest count (the algorithm is linear in the directions, so a
  direction may mean a different coordinate in each row);
- per-row arrays carry what differs inside a group: wrap frames and their derivatives, the
  PathWrap ranges, and the objects' sizes (radii, dimensions).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cylinder_line import ELLIPSOID_METHODS, quadrant_axis_sign
from .wrapped_rows import CYLINDER, ELLIPSOID, SPHERE, TORUS, wrap_compiled_rows

__all__ = ["wrap_paths", "wrap_path", "WrappedPath", "group_rows", "WrapSlot", "wrap_range", "wrap_spec",
           "drawn_lengths"]

_KINDS = {"cylinder": CYLINDER, "sphere": SPHERE, "ellipsoid": ELLIPSOID, "torus": TORUS}


@dataclass(frozen=True)
class WrapSlot:
    """One wrap of a path (PathWrapSet entry), for every row (frame, or frame of one of several
    batched paths).

    ``kind``: CYLINDER, SPHERE, ELLIPSOID or TORUS (`motion.wrapping.wrapped_rows`); ``params``
    (N, 3) or (3,) the object's size per row (cylinder: radius, length; sphere: radius;
    ellipsoid: the semi-axes; torus: inner, outer radius; unused entries 0); ``axis``,
    ``sign`` its quadrant (`motion.wrapping.cylinder_line.quadrant_axis_sign`); ``adjust`` the
    cylinder's tangent re-adjustment; ``method`` the ellipsoid's (index into
    ``ELLIPSOID_METHODS``); ``tf`` (N, 4, 4) the wrap frame in ground and ``dtf`` (N, D, 4, 4) its
    derivatives; ``start``, ``end`` (N,) the 0-based range of defined points it may act on.
    """

    kind: int
    params: np.ndarray
    axis: int
    sign: int
    adjust: bool
    method: int
    active: bool
    tf: np.ndarray
    dtf: np.ndarray
    start: np.ndarray
    end: np.ndarray


def drawn_lengths(drawn, order, arc, n_points: int) -> np.ndarray:
    """(F,) length of a drawn path: straight pieces between the nodes ``drawn`` (F, N, 3) in the
    path order ``order`` (F, N), and ``arc`` (F, W) between the two tangent points of one wrap
    object (nodes ``n_points + 2 w``, ``+ 1``): OpenSim's calcLengthAfterPathComputation on
    the positions of the last wrapping pass."""
    order = np.asarray(order)
    a, b = order[:, :-1], order[:, 1:]
    pieces = (a >= 0) & (b >= 0)
    pa = np.take_along_axis(drawn, np.where(pieces, a, 0)[..., None], axis=1)
    pb = np.take_along_axis(drawn, np.where(pieces, b, 0)[..., None], axis=1)
    over = pieces & (a >= n_points) & (b == a + 1) & ((a - n_points) % 2 == 0)
    w = np.where(over, (a - n_points) // 2, 0)
    piece = np.where(over, np.take_along_axis(arc, w, axis=1), np.linalg.norm(pb - pa, axis=-1))
    return np.where(pieces, piece, 0.0).sum(axis=1)


def wrap_range(path_wrap, n_points: int) -> tuple:
    """0-based (start, end) of a PathWrap's range (OpenSim: 1-based, -1 = first / last point)."""
    start = 0 if path_wrap.range[0] < 1 else path_wrap.range[0] - 1
    end = n_points - 1 if path_wrap.range[1] < 1 else path_wrap.range[1] - 1
    return start, min(end, n_points - 1)


def wrap_spec(wrap_object, method: str, single: bool) -> tuple:
    """(kind, params (3,), axis, sign, adjust, method index) of a wrap object as a path uses it.

    ``single``: the path's only wrap (OpenSim then skips the cylinder's tangent re-adjustment,
    ``WrapResult::singleWrap``; a torus' internal cylinder always re-adjusts)."""
    kind = wrap_object.kind
    if kind not in _KINDS:
        raise ValueError(f"unknown wrap object kind {kind!r}")
    axis, sign = quadrant_axis_sign(wrap_object.quadrant)
    if kind == "cylinder":
        params = (wrap_object.radius, wrap_object.length, 0.0)
    elif kind == "sphere":
        params = (wrap_object.radius, 0.0, 0.0)
    elif kind == "ellipsoid":
        params = tuple(np.asarray(wrap_object.dimensions, dtype=float))
        if method not in ELLIPSOID_METHODS:
            raise ValueError(f"method must be one of {ELLIPSOID_METHODS}, got {method!r}")
    else:
        params = (wrap_object.inner_radius, wrap_object.outer_radius, 0.0)
    m = ELLIPSOID_METHODS.index(method) if kind == "ellipsoid" else 0
    return (_KINDS[kind], np.array(params, dtype=float), axis, sign, kind == "cylinder" and not single, m)


def _statics(model, path) -> tuple:
    """Per PathWrap of ``path``, what does not change with the pose (kept with the model,
    `Model.cached`): (body index, tf_body_wrap, `wrap_spec`, `wrap_range`, active)."""
    def make():
        out = []
        for pw in path.wraps:
            wo = model.wrap_object(pw.wrap_object)
            out.append((model.body_index(wo.body), np.asarray(wo.tf_body_wrap, dtype=float),
                        wrap_spec(wo, pw.method, len(path.wraps) == 1), wrap_range(pw, len(path.points)),
                        bool(wo.active)))
        return tuple(out)
    return model.cached(("wrap statics", path.name), make)


def _all_kinds(model) -> bool:
    """A path of ``model`` wraps over an object that is no cylinder: every call then runs the
    kernel compiled for all kinds (`wrap_compiled_rows`' ``all_kinds``), so that a model
    compiles one variant; otherwise the calls' own kinds choose (cylinders only: the cheap
    variant, which never compiles the other kinds)."""
    return model.cached("wrap kinds", lambda: any(model.wrap_object(pw.wrap_object).kind != "cylinder"
                                                  for path in model.paths for pw in path.wraps))


def _signature(model, path) -> tuple:
    """Hashable description of a path's wraps: what must be equal to share one call."""
    return tuple((kind, axis, sign, adjust, method, active)
                 for _, _, (kind, _, axis, sign, adjust, method), _, active in _statics(model, path))


@dataclass(frozen=True)
class WrappedPath:
    """A path after wrapping, per frame.

    Node layout: nodes ``0..P-1`` are the defined path points, nodes ``P + 2 w`` and
    ``P + 2 w + 1`` the first and second tangent points of the path's wrap ``w``.

    Attributes
    ----------
    length : (F,) float
        Path length (m).
    d_length : (F, C) float
        dL/dq, exact (the derivative of the algorithm OpenSim runs).
    points : (F, N, 3) float
        Node positions in ground as OpenSim reports them (NaN where a node is absent).
    mask : (F, N) bool
        Node is part of the current path.
    order : (F, N) int
        The current path in order as node indices, padded with -1.
    labels : (N,) str
        Point names, and ``"<wrap object>:1"`` / ``":2"`` for tangent points.
    kinds : (N,) str
        ``"point"`` or ``"wrap"``.
    arc : (F, W) float
        Arc length on each wrap object (0 where it does not wrap).
    wrap_objects : (W,) str
    drawn : (F, N, 3) float
        Node positions of OpenSim's last wrapping pass (NaN where absent): the tangent points
        the arcs belong to, so the path drawn through them is one continuous curve. They equal
        ``points`` except on paths over several wrap objects whose later passes moved a tangent
        point; there OpenSim's length and ``points`` keep the first pass' positions
        (`motion.wrapping.wrapped_rows`) and the drawn path is longer (`drawn_length`).
    """

    length: np.ndarray
    d_length: np.ndarray
    points: np.ndarray
    mask: np.ndarray
    order: np.ndarray
    labels: tuple
    kinds: tuple
    arc: np.ndarray
    wrap_objects: tuple
    drawn: np.ndarray

    def __post_init__(self):
        for name in ("length", "d_length", "points", "mask", "order", "arc", "drawn"):
            arr = np.array(getattr(self, name), copy=True)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "labels", tuple(self.labels))
        object.__setattr__(self, "kinds", tuple(self.kinds))

    @property
    def drawn_length(self) -> np.ndarray:
        """(F,) length of the drawn path (`drawn_lengths`); equals ``length`` except where
        OpenSim's length mixes passes (see ``drawn``)."""
        return drawn_lengths(self.drawn, self.order, self.arc, len(self.kinds) - 2 * len(self.wrap_objects))

    @property
    def ordered_points(self) -> np.ndarray:
        """(F, N, 3) the current path's points in path order, NaN-padded at the end."""
        idx = np.where(self.order >= 0, self.order, 0)
        out = np.take_along_axis(self.points, idx[..., None], axis=1)
        return np.where((self.order >= 0)[..., None], out, np.nan)


def wrap_path(path, model, points, active, d_points, tf_ground_body, d_tf_ground_body) -> WrappedPath:
    """Apply one path's wrap objects on every frame, as OpenSim 4.6 does.

    Parameters
    ----------
    path : motion.osim.model.Path
        The path (``path.wraps`` in PathWrapSet order).
    model : motion.osim.model.Model
    points : (F, P, 3) float
        The defined path points in ground (inactive conditional points: any finite value).
    active : (F, P) bool
    d_points : (F, P, C, 3) float or None
        Derivatives of the points with respect to the coordinates (None: lengths only, C = 0).
    tf_ground_body : (F, B, 4, 4) float
    d_tf_ground_body : (F, B, C, 4, 4) float or None

    Returns
    -------
    WrappedPath
    """
    points = np.asarray(points, dtype=float)
    active = np.asarray(active, dtype=bool)
    tf = np.asarray(tf_ground_body, dtype=float)
    if d_points is None or d_tf_ground_body is None:   # lengths only: no coordinates to follow
        d_points = np.zeros(points.shape[:2] + (0, 3))
        d_tf_ground_body = np.zeros(tf.shape[:2] + (0, 4, 4))
    d_points = np.asarray(d_points, dtype=float)
    if points.ndim != 3 or points.shape[-1] != 3 or active.shape != points.shape[:2]:
        raise ValueError(f"points must be (F, P, 3) and active (F, P); got {points.shape}, {active.shape}")
    if len(path.points) != points.shape[1]:
        raise ValueError(f"path {path.name!r} has {len(path.points)} points, got {points.shape[1]}")
    n_frames, n_points = points.shape[:2]
    n_coords = d_points.shape[2]
    pts, act, dpts, n_dirs, slots = group_rows([path], model, [points], [active], [d_points], tf,
                                               np.asarray(d_tf_ground_body, dtype=float), [np.arange(n_coords)])
    length, d_length, order, mask, seen, arc, latest = wrap_compiled_rows(pts, act, dpts, n_dirs, slots,
                                                                          _all_kinds(model) or None)
    labels = [p.name for p in path.points]
    for pw in path.wraps:
        labels += [f"{pw.wrap_object}:1", f"{pw.wrap_object}:2"]
    return WrappedPath(length=length, d_length=d_length, points=np.where(mask[..., None], seen, np.nan),
                       mask=mask, order=order, labels=tuple(labels),
                       kinds=("point",) * n_points + ("wrap",) * (2 * len(path.wraps)), arc=arc,
                       wrap_objects=tuple(pw.wrap_object for pw in path.wraps),
                       drawn=np.where(mask[..., None], latest, np.nan))


def wrap_paths(paths, model, points, active, d_points, tf_ground_body, d_tf_ground_body, columns) -> list:
    """Wrap several paths on every frame (OpenSim 4.6's algorithm, `motion.wrapping.wrapped_rows`).

    Parameters
    ----------
    paths : sequence of motion.osim.model.Path (each with at least one wrap)
    model : motion.osim.model.Model
    points, active, d_points : sequences, one per path
        (F, P_m, 3) ground points, (F, P_m) active flags, (F, P_m, C, 3) derivatives along all
        model coordinates.
    tf_ground_body : (F, B, 4, 4) float
    d_tf_ground_body : (F, B, C, 4, 4) float
    columns : sequence of (C_m,) int
        The coordinates whose derivatives each path needs (its spanned coordinates).

    Returns
    -------
    list of (length (F,), d_length (F, C_m), points (F, K_m, 3), mask (F, K_m), labels (K_m,),
    order (F, K_m), drawn length (F,), `drawn_lengths`) per path, with ``K_m = P_m + 2 W_m``
    nodes numbered as `WrappedPath`'s.
    """
    groups = {}
    for m, path in enumerate(paths):
        groups.setdefault(_signature(model, path), []).append(m)
    out = [None] * len(paths)
    for members in groups.values():
        for m, result in zip(members, _wrap_group([paths[m] for m in members], model,
                                                  [points[m] for m in members], [active[m] for m in members],
                                                  [d_points[m] for m in members], tf_ground_body,
                                                  d_tf_ground_body, [columns[m] for m in members])):
            out[m] = result
    return out


def group_rows(paths, model, points, active, d_points, tf, dtf, columns) -> tuple:
    """The rows (path, frame) of paths of one signature, as `wrap_compiled_rows` takes them:
    points (N, P_max, 3), active (N, P_max), d_points (N, P_max, D_max, 3), the number of
    directions of each row (N,) and the `WrapSlot` list (arguments as `wrap_paths`)."""
    n_frames = tf.shape[0]
    n_paths = len(paths)
    p_max = max(len(p.points) for p in paths)
    d_max = max(len(c) for c in columns)
    n_rows = n_paths * n_frames
    pts = np.zeros((n_rows, p_max, 3))
    act = np.zeros((n_rows, p_max), dtype=bool)
    dpts = np.zeros((n_rows, p_max, d_max, 3))
    for g, (path, cols) in enumerate(zip(paths, columns)):
        rows = slice(g * n_frames, (g + 1) * n_frames)
        n_p = len(path.points)
        pts[rows, :n_p] = points[g]
        act[rows, :n_p] = active[g]
        dpts[rows, :n_p, :len(cols)] = d_points[g][:, :, cols]
    statics = [_statics(model, path) for path in paths]
    slots = []
    for w in range(len(paths[0].wraps)):
        tf_w = np.empty((n_rows, 4, 4))
        dtf_w = np.zeros((n_rows, d_max, 4, 4))
        start = np.empty(n_rows, dtype=np.int64)
        end = np.empty(n_rows, dtype=np.int64)
        params = np.empty((n_rows, 3))
        for g, cols in enumerate(columns):
            rows = slice(g * n_frames, (g + 1) * n_frames)
            b, tf_bw, (kind, params[rows], axis, sign, adjust, method), (start[rows], end[rows]), active = statics[g][w]
            np.matmul(tf[:, b], tf_bw, out=tf_w[rows])
            dtf_w[rows, :len(cols)] = dtf[:, b, cols] @ tf_bw
        slots.append(WrapSlot(kind, params, axis, sign, adjust, method, active, tf_w, dtf_w, start, end))
    n_dirs = np.repeat(np.array([len(c) for c in columns], dtype=np.int64), n_frames)
    return pts, act, dpts, n_dirs, slots


def _wrap_group(paths, model, points, active, d_points, tf, dtf, columns) -> list:
    """One compiled pass for paths of one signature; results split back per path."""
    n_frames = tf.shape[0]
    p_max = max(len(p.points) for p in paths)
    pts, act, dpts, n_dirs, slots = group_rows(paths, model, points, active, d_points, tf, dtf, columns)
    length_v, d_length, order, mask, node_v, arc, latest = wrap_compiled_rows(pts, act, dpts, n_dirs, slots,
                                                                              _all_kinds(model) or None)
    n_wraps = len(slots)
    results = []
    for g, (path, cols) in enumerate(zip(paths, columns)):
        rows = slice(g * n_frames, (g + 1) * n_frames)
        n_p = len(path.points)
        keep = np.r_[np.arange(n_p), p_max + np.arange(2 * n_wraps)]  # this path's nodes
        new_id = np.full(p_max + 2 * n_wraps + 1, -1)                    # old node -> new (-1 -> -1)
        new_id[keep] = np.arange(len(keep))
        msk = mask[rows][:, keep]
        labels = [p.name for p in path.points]
        for pw in path.wraps:
            labels += [f"{pw.wrap_object}:1", f"{pw.wrap_object}:2"]
        ordr = new_id[order[rows]][:, :len(keep)]
        results.append((length_v[rows], d_length[rows, :len(cols)],
                        np.where(msk[..., None], node_v[rows][:, keep], np.nan), msk, tuple(labels), ordr,
                        drawn_lengths(latest[rows][:, keep], ordr, arc[rows], n_p)))
    return results
