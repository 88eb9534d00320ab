"""Several wrapped paths in one pass: paths with the same kind of wraps share every array step.

Contract: `wrap_paths` returns, for each path, what `motion.wrapping.path.wrap_path` returns
for it alone (length, dL/dq along the path's own coordinates, current points, mask, labels,
order) -- the same algorithm on the same numbers, row by row. Groups whose wraps are all
WrapCylinders run the compiled kernel `motion.wrapping.cylinder_paths` (equal to the numpy
`wrap_rows` to rounding); the others run `wrap_rows`.

Method. `motion.wrapping.path.wrap_rows` runs OpenSim's applyWrapObjects on independent rows,
and its cost is dominated by the number of numpy calls, not by the number of rows (the
compiled kernel pays per row, and shares the rows' preparation, `group_rows`). Paths are
therefore grouped by the *signature* of their wraps (per PathWrap: the wrap-line function,
its options other than a cylinder's radius and length, and whether the object is active);
the paths of one group become rows (path, frame) of one call:

- defined points are padded to the group's largest point count with inactive points (the
  current path skips inactive points, so padding never enters it);
- each path's derivative directions are its own spanned coordinates (``columns``), padded with
  zeros to the group's largest count (the wrap algebra is linear in the directions, so a
  direction may mean a different coordinate in each row);
- per-row arrays carry what differs inside a group: wrap frames and their derivatives, the
  PathWrap ranges, and cylinder radii and lengths.

The module also holds what describes one wrap for the row-level algorithm (`WrapSlot`,
`line_function`: the wrap-line function and options of a wrap object, `wrap_range`).

On the RajagopalLaiUhlrich2023 walk (42 wrapped paths, 46 cylinder wraps) the 42 per-path
passes become 5 group passes (see ``bench/lines.py`` and ``docs/decisions.md``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cylinder import cylinder_wrap_line
from .cylinder_paths import wrap_cylinder_rows
from .ellipsoid import ellipsoid_wrap_line
from .sphere import sphere_wrap_line
from .torus import torus_wrap_line

__all__ = ["wrap_paths", "group_rows", "WrapSlot", "wrap_range", "line_function"]

@dataclass(frozen=True)
class WrapSlot:
    """One wrap of a path (PathWrapSet entry), for every row (frame, or frame of one of several
    batched paths).

    ``fn(p1, p2, **opts, **{k: v[rows]})`` is the wrap object's wrap-line function in its own
    frame; ``row_opts`` hold per-row option arrays (N,) (cylinder radius and length of batched
    paths); ``tf`` (N, 4, 4) the wrap frame in ground and ``dtf`` (N, D, 4, 4) its derivatives;
    ``start``, ``end`` (N,) the 0-based range of defined points the wrap may act on.
    """

    fn: object
    opts: dict
    row_opts: dict
    active: bool
    tf: np.ndarray
    dtf: np.ndarray
    start: np.ndarray
    end: np.ndarray


def wrap_range(path_wrap, n_points: int) -> tuple:
    """0-based (start, end) of a PathWrap's range (OpenSim: 1-based, -1 = first / last point)."""
    start = 0 if path_wrap.range[0] < 1 else path_wrap.range[0] - 1
    end = n_points - 1 if path_wrap.range[1] < 1 else path_wrap.range[1] - 1
    return start, min(end, n_points - 1)


def line_function(wrap_object, method: str, single: bool):
    """(wrap-line function, options) of a wrap object; ``single``: the path's only wrap (OpenSim
    then skips the cylinder's tangent re-adjustment, ``WrapResult::singleWrap``)."""
    kind = wrap_object.kind
    if kind == "cylinder":
        return cylinder_wrap_line, dict(radius=float(wrap_object.radius),
                                        length=float(wrap_object.length),
                                        quadrant=wrap_object.quadrant,
                                        adjust_tangents=not single)
    if kind == "sphere":
        return sphere_wrap_line, dict(radius=float(wrap_object.radius), quadrant=wrap_object.quadrant)
    if kind == "ellipsoid":
        return ellipsoid_wrap_line, dict(dimensions=np.asarray(wrap_object.dimensions, dtype=float),
                                         quadrant=wrap_object.quadrant, method=method)
    if kind == "torus":
        return torus_wrap_line, dict(inner_radius=float(wrap_object.inner_radius),
                                     outer_radius=float(wrap_object.outer_radius),
                                     quadrant=wrap_object.quadrant)
    raise ValueError(f"unknown wrap object kind {kind!r}")


# options that may differ between the rows of one call (the function accepts (N,) arrays)
_ROW_OPTIONS = {cylinder_wrap_line: ("radius", "length")}


def _signature(model, path) -> tuple:
    """Hashable description of a path's wraps: what must be equal to share one call."""
    out = []
    for pw in path.wraps:
        wo = model.wrap_object(pw.wrap_object)
        fn, opts = line_function(wo, pw.method, len(path.wraps) == 1)
        fixed = tuple(sorted((k, tuple(np.ravel(v)) if isinstance(v, np.ndarray) else v)
                             for k, v in opts.items() if k not in _ROW_OPTIONS.get(fn, ())))
        out.append((fn, fixed, bool(wo.active)))
    return tuple(out)


def wrap_paths(paths, model, points, active, d_points, tf_ground_body, d_tf_ground_body, columns) -> list:
    """Wrap several paths on every frame (OpenSim 4.6's algorithm, as `wrap_path`).

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
    order (F, K_m)) per path, with ``K_m = P_m + 2 W_m`` nodes numbered as `wrap_path` does.
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
    """The rows (path, frame) of paths of one signature, as `motion.wrapping.path.wrap_rows` takes
    them: points (N, P_max, 3), active (N, P_max), d_points (N, P_max, D_max, 3), the number of
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
    slots = []
    for w, pw in enumerate(paths[0].wraps):
        tf_w = np.empty((n_rows, 4, 4))
        dtf_w = np.zeros((n_rows, d_max, 4, 4))
        start = np.empty(n_rows, dtype=np.int64)
        end = np.empty(n_rows, dtype=np.int64)
        row_opts = {}
        for g, (path, cols) in enumerate(zip(paths, columns)):
            rows = slice(g * n_frames, (g + 1) * n_frames)
            wo = model.wrap_object(path.wraps[w].wrap_object)
            b = model.body_index(wo.body)
            fn, opts = line_function(wo, path.wraps[w].method, len(path.wraps) == 1)
            tf_w[rows] = tf[:, b] @ wo.tf_body_wrap
            dtf_w[rows, :len(cols)] = dtf[:, b][:, cols] @ wo.tf_body_wrap
            start[rows], end[rows] = wrap_range(path.wraps[w], len(path.points))
            for key in _ROW_OPTIONS.get(fn, ()):
                row_opts.setdefault(key, np.empty(n_rows))[rows] = opts.pop(key)
        slots.append(WrapSlot(fn, opts, row_opts, bool(wo.active), tf_w, dtf_w, start, end))
    n_dirs = np.repeat(np.array([len(c) for c in columns], dtype=np.int64), n_frames)
    return pts, act, dpts, n_dirs, slots


def _wrap_group(paths, model, points, active, d_points, tf, dtf, columns) -> list:
    """One pass for paths of one signature (compiled for cylinders, `wrap_rows` otherwise);
    results split back per path."""
    n_frames = tf.shape[0]
    p_max = max(len(p.points) for p in paths)
    pts, act, dpts, n_dirs, slots = group_rows(paths, model, points, active, d_points, tf, dtf, columns)
    n_rows, d_max = len(n_dirs), dpts.shape[2]
    if all(slot.fn is cylinder_wrap_line for slot in slots):
        length_v, d_length, order, mask, node_v = wrap_cylinder_rows(pts, act, dpts, n_dirs, slots)
    else:
        from .path import wrap_rows      # here: motion.wrapping.path imports WrapSlot from this module
        length, order, mask, seen, _ = wrap_rows(pts, act, dpts, slots)
        node_v = np.stack([n.v for n in seen], axis=1)                   # (N, P_max + 2 W, 3)
        length_v, d_length = length.v, np.broadcast_to(length.d, (n_rows, d_max))
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
                        np.where(msk[..., None], node_v[rows][:, keep], np.nan), msk, tuple(labels), ordr))
    return results
