"""The current action lines of the muscle surfaces as polylines per frame (`motion.surface.wrap`).

A path without wrap objects is its active path points in path order (ConditionalPathPoints
dropped where inactive, NaN-padded); a wrapped path is the path OpenSim draws: its tangent points
from the last wrapping pass (`motion.wrapping.batch.WrappedPath.drawn`), and the arc over every
wrap object between its two tangent points (cylinder: the helix, i.e. the geodesic; sphere: the great
circle in the direction the path arrives; ellipsoid: the great circle of the scaled unit sphere
mapped back; torus: the chord). With each polyline come the anchor positions (the path points
that are always present) and which entries are ConditionalPathPoints, which the binding uses
to match arc length piece by piece and to round the corners the samples slide past.
"""
from __future__ import annotations

import numpy as np

__all__ = ["path_polylines", "current_polylines"]

_ARC_POINTS = 24


def _compact(points: np.ndarray, mask: np.ndarray):
    """Points (F, K, 3) where ``mask`` (F, K), moved to the front in order, NaN-padded; and the
    original index of every slot (F, K) (-1 for padding)."""
    perm = np.argsort(~mask, axis=1, kind="stable")
    out = np.take_along_axis(np.where(mask[..., None], points, np.nan), perm[..., None], axis=1)
    ids = np.where(np.take_along_axis(mask, perm, axis=1), perm, -1)
    return out, ids


def _anchor_positions(path, ids: np.ndarray) -> np.ndarray | None:
    """(F, K) positions in each frame's polyline of the path points that are always present
    (fixed and moving points: not conditional), or None when they are only the two ends."""
    keep = [k for k, p in enumerate(path.points) if p.kind != "conditional"]
    if len(keep) < 3 or keep[0] != 0 or keep[-1] != len(path.points) - 1:
        return None
    hit = ids[:, :, None] == np.asarray(keep)[None, None, :]       # (F, N, K)
    if not np.all(hit.any(axis=1)):
        return None
    return np.argmax(hit, axis=1)


def _conditional(path, ids: np.ndarray) -> np.ndarray:
    """(F, N) bool: polyline entries (ids from `_compact`/`_path_polyline_ids`) that are
    ConditionalPathPoints of ``path``."""
    kinds = np.array([p.kind == "conditional" for p in path.points] + [False])
    ids = np.asarray(ids)
    return kinds[np.where((ids >= 0) & (ids < len(path.points)), ids, -1)]


def current_polylines(model, motion, names, lines, tf_ground_body, q_used=None) -> dict:
    """Mapping path name -> ((F, N, 3) current polyline with wrap arcs, NaN-padded;
    (F, K) anchor positions or None; (F, N) bool, the points that are ConditionalPathPoints)."""
    out = {}
    table = getattr(lines, "muscle_names", None) if lines is not None else None
    for name in names:
        path = model.path(name)
        if table is not None and name in table and not path.wraps:
            m = table.index(name)
            pts, ids = _compact(np.asarray(lines.points)[:, m, :len(path.points)],
                                np.asarray(lines.point_mask)[:, m, :len(path.points)])
            out[name] = (pts, _anchor_positions(path, ids), _conditional(path, ids))
    missing = [n for n in names if n not in out]
    if missing:
        from ..osim.kinematics import body_pose_derivatives
        from ..wrapping.path_points import path_points

        # positions only: the polylines need no derivatives (the wrap kernel then runs each row
        # once instead of once per coordinate)
        if q_used is None:
            tf, _, q_used, _ = body_pose_derivatives(model, motion, derivatives=False)
        else:       # the poses and assembled coordinates the caller has
            tf = np.asarray(tf_ground_body, dtype=float)
        for name in missing:  # loop over paths (few)
            path = model.path(name)
            pp = path_points(path, model, q_used, tf)
            if path.wraps:
                from ..wrapping.batch import wrap_path

                wrapped = wrap_path(path, model, pp.points, pp.active, None, tf, None)
                pts, ids = _path_polyline_ids(model, wrapped, tf)
            else:
                pts, ids = _compact(pp.points, np.asarray(pp.active, dtype=bool))
            out[name] = (pts, _anchor_positions(path, ids), _conditional(path, ids))
    return out


def _arc_points(kind, radii, t1, t2, before, u):
    """Points (F, A, 3) strictly between tangent points t1, t2 (F, 3) in the wrap frame."""
    if kind == "cylinder":
        r = radii[0]
        phi1, phi2 = np.arctan2(t1[:, 1], t1[:, 0]), np.arctan2(t2[:, 1], t2[:, 0])
        d_in = t1 - before
        turn = np.sign(t1[:, 0] * d_in[:, 1] - t1[:, 1] * d_in[:, 0])
        turn = np.where(turn == 0, 1.0, turn)
        span = np.where(turn > 0, np.mod(phi2 - phi1, 2 * np.pi), -np.mod(phi1 - phi2, 2 * np.pi))
        phi = phi1[:, None] + u[None] * span[:, None]
        z = t1[:, None, 2] + u[None] * (t2[:, 2] - t1[:, 2])[:, None]
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
    if kind in ("sphere", "ellipsoid"):
        s1, s2, sb = t1 / radii, t2 / radii, before / radii
        n1 = np.linalg.norm(s1, axis=-1, keepdims=True)
        a = s1 / n1
        b = s2 / np.linalg.norm(s2, axis=-1, keepdims=True)
        axis = np.cross(a, b)
        sin = np.linalg.norm(axis, axis=-1)
        cos = np.sum(a * b, axis=-1)
        angle = np.arctan2(sin, cos)
        axis = axis / np.maximum(sin, 1e-15)[:, None]
        # the path arrives along d_in; if it points against the short way, go the long way
        d_in = s1 - sb
        forward = np.sum(d_in * np.cross(axis, a), axis=-1) >= 0
        axis = np.where(forward[:, None], axis, -axis)
        angle = np.where(forward, angle, 2 * np.pi - angle)
        phi = u[None] * angle[:, None]
        c, s = np.cos(phi)[..., None], np.sin(phi)[..., None]
        ax = axis[:, None]
        pts = a[:, None] * c + np.cross(ax, a[:, None]) * s + ax * np.sum(ax * a[:, None], -1, keepdims=True) * (1 - c)
        rad = n1[:, None] + u[None, :, None] * (np.linalg.norm(s2, axis=-1, keepdims=True)[:, None] - n1[:, None])
        return pts * rad * radii
    return t1[:, None] + u[None, :, None] * (t2 - t1)[:, None]  # torus: chord


def path_polylines(model, wrapped, tf_ground_body, *, arc_points: int = _ARC_POINTS) -> np.ndarray:
    """A wrapped path's current polyline per frame, with the arcs over the wrap objects.

    Parameters
    ----------
    model : motion.Model
    wrapped : motion.wrapping.batch.WrappedPath
    tf_ground_body : (F, B, 4, 4) float

    Returns
    -------
    (F, N, 3) float
        Points in path order, NaN-padded at the end.
    """
    return _path_polyline_ids(model, wrapped, tf_ground_body, arc_points=arc_points)[0]


def _path_polyline_ids(model, wrapped, tf_ground_body, *, arc_points: int = _ARC_POINTS):
    """`path_polylines`, plus what each point of the polyline is (second return value)."""
    order = np.asarray(wrapped.order)
    pts = np.asarray(wrapped.drawn)
    nf, nk = order.shape
    valid = order >= 0
    ordered = np.take_along_axis(pts, np.where(valid, order, 0)[..., None], axis=1)
    ordered = np.where(valid[..., None], ordered, np.nan)
    n_wraps = len(wrapped.wrap_objects)
    if n_wraps == 0:
        return ordered, np.where(valid, order, -1)
    n_points = pts.shape[1] - 2 * n_wraps
    u = np.linspace(0.0, 1.0, arc_points + 2)[1:-1]
    slots = np.full((nf, nk, 1 + arc_points, 3), np.nan)
    slots[:, :, 0] = ordered
    prev = np.concatenate([ordered[:, :1], ordered[:, :-1]], axis=1)
    nxt_node = np.concatenate([order[:, 1:], np.full((nf, 1), -1)], axis=1)
    for w, name in enumerate(wrapped.wrap_objects):  # loop over wrap objects (few)
        first = (order == n_points + 2 * w) & (nxt_node == n_points + 2 * w + 1)
        if not first.any():
            continue
        wo = model.wrap_object(name)
        tf = np.asarray(tf_ground_body)[:, model.body_index(wo.body)] @ np.asarray(wo.tf_body_wrap)
        f_idx, k_idx = np.nonzero(first)
        tfw = tf[f_idx]
        to_local = lambda p: np.einsum("fji,fj->fi", tfw[:, :3, :3], p - tfw[:, :3, 3])  # noqa: E731
        t1 = to_local(ordered[f_idx, k_idx])
        t2 = to_local(ordered[f_idx, k_idx + 1])
        before = to_local(prev[f_idx, k_idx])
        if wo.kind == "cylinder":
            radii = np.array([wo.radius, wo.radius, wo.length])
        elif wo.kind == "sphere":
            radii = np.full(3, wo.radius)
        elif wo.kind == "ellipsoid":
            radii = np.asarray(wo.dimensions, dtype=float)
        else:
            radii = np.ones(3)
        arc = _arc_points(wo.kind if wo.kind != "torus" else "torus", radii, t1, t2, before, u)
        slots[f_idx, k_idx, 1:] = np.einsum("fij,faj->fai", tfw[:, :3, :3], arc) + tfw[:, None, :3, 3]
    flat = slots.reshape(nf, -1, 3)
    node = np.full((nf, nk, 1 + arc_points), -1)
    node[:, :, 0] = np.where(valid, order, -1)
    node = node.reshape(nf, -1)
    keep = np.isfinite(flat).all(axis=-1)
    perm = np.argsort(~keep, axis=1, kind="stable")
    return (np.take_along_axis(flat, perm[..., None], axis=1),
            np.where(np.take_along_axis(keep, perm, axis=1), np.take_along_axis(node, perm, axis=1), -1))
