"""Action lines of an OpenSim model: path lengths and exact moment arms, vectorised over frames.

For every path force (muscle, ligament, path actuator): the current path per frame (active
points, and the wrap tangent points of `motion.wrapping.wrapped_rows` when the path has wrap objects),
its length L (F,) and the moment arms r = -dL/dq (F, C) by forward-mode derivatives (chain rule
through the body transforms, moving points and couplers; no finite differences).

Moment-arm convention (INTERFACE.md): r_k = -dL/dq_k. For a coordinate that is not the dependent
of a coupler, the derivative is total (dependent coordinates follow their couplers): this is
what OpenSim's ``computeMomentArm`` returns for paths without wrapping. For a dependent
coordinate it is the partial derivative (the dependent coordinate moved alone), and for a locked
coordinate the partial derivative as if it were unlocked — the same as the references'
``neg_dLdq_fd`` column. Where a path does not span a coordinate the moment arm is exactly 0.0
and ``spanned`` is False; spanned coordinates are those of the joints between the bodies the
path touches (points and wrap objects), those driving conditional and moving points, and the
independent coordinates of couplers whose dependent is spanned (as OpenSim's reference script).

OpenSim's ``computeMomentArm`` equals -dL/dq for unwrapped paths and differs from it where a path
wraps (0.05-4 mm: OpenSim neglects the motion of the tangent points) and at BallJoint /
EllipsoidJoint coordinates (OpenSim works with angular velocities there: its "moment arm" about
an Euler-angle coordinate is the torque per unit tension about the mobilizer axis, not -dL/dq).
This module returns -dL/dq only, the documented contract; it does not imitate those two
OpenSim-specific quantities.

Speed: per model and path selection an index plan is built once and cached (`_plan`): all
unwrapped paths' points stacked, sorted by body, grouped in (body, path) pairs, and the
(pair, spanned coordinate) terms of dL/dq. When no selected path wraps, the body twists come
straight from the joint chain (no (F, B, C, 4, 4) derivative array). A numba kernel walks the
active points of every path per frame (`motion.wrapping.path_points._polyline_kernel`; a numpy
oracle of it is in ``tests/motion/polyline_oracle.py``). Wrapped paths go through
`motion.wrapping.batch.wrap_paths`: paths with the same kinds of wraps share one call of the
compiled wrap kernel (`motion.wrapping.wrapped_rows`, rows = path x frame), each carrying
derivatives only along its own spanned coordinates.
Timings against OpenSim 4.6: ``python bench/lines.py`` (``bench/README.md``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..osim.kinematics import _pose_twists, body_pose_derivatives, motion_coordinates
from ..osim.model import Model, Path
from .path_points import (_moving_local, _point_set, _point_set_active, _polyline_kernel,
                          path_points)

__all__ = ["ActionLines", "action_lines", "spanned_coordinates", "coordinates_spanned", "polyline_length",
           "MIXED_PASSES"]

#: m: a path whose drawn length exceeds OpenSim's length by more than this mixes wrapping passes
MIXED_PASSES = 0.001


@dataclass(frozen=True, eq=False)
class ActionLines:
    """Lengths, moment arms and current path points of a model's path forces.

    Attributes
    ----------
    lengths : (F, M) float
        Path lengths (m).
    moment_arms : (F, M, C) float
        r = -dL/dq (m for rotational coordinates); exactly 0.0 where not ``spanned``.
    spanned : (M, C) bool
    muscle_names : (M,) tuple of str
    coordinate_names : (C,) tuple of str
    coordinate_status : (C,) tuple of str
        "independent", "dependent" (of a coupler) or "locked".
    time : (F,) float
    q : (F, C) float
        Coordinate values used (after locking, clamping, couplers and weld assembly).
    points : (F, M, K, 3) float
        Current path points in ground (active points and wrap tangent points), padded with NaN.
    point_mask : (F, M, K) bool
        True where ``points`` holds a point of the current path.
    point_labels : (M, K) tuple of tuples of str
        Point names ('' for padding; wrap tangent points as the wrap helper labels them).
        ``points`` is stored by point (node), not in path order: where a path wraps, its tangent
        points stand after the defined points.
    point_order : (F, M, K) int
        The current path in path order per frame, as indices into axis K of ``points``, padded
        with -1. ``ordered_points`` applies it.
    drawn_lengths : (F, M) float
        Length of the path OpenSim draws (the tangent points of its last wrapping pass,
        `motion.wrapping.batch.drawn_lengths`). Equal to ``lengths`` except on paths over
        several wrap objects whose later passes moved a tangent point: OpenSim 4.6's length
        keeps the first pass' positions there (`motion.wrapping.wrapped_rows`), so it and its
        -dL/dq (``moment_arms``) differ from the drawn path and from OpenSim's
        ``computeMomentArm`` (measured: docs/decisions.md, "Paths over wrap objects in series").
        Default: ``lengths``.
    """

    lengths: np.ndarray
    moment_arms: np.ndarray
    spanned: np.ndarray
    muscle_names: tuple
    coordinate_names: tuple
    coordinate_status: tuple
    time: np.ndarray
    q: np.ndarray
    points: np.ndarray
    point_mask: np.ndarray
    point_labels: tuple
    point_order: np.ndarray
    drawn_lengths: np.ndarray | None = None

    def __post_init__(self):
        if self.drawn_lengths is None:
            object.__setattr__(self, "drawn_lengths", self.lengths)
        for key in ("lengths", "moment_arms", "spanned", "time", "q", "points", "point_mask",
                    "point_order", "drawn_lengths"):
            arr = getattr(self, key)
            if not (isinstance(arr, np.ndarray) and arr.flags.owndata and not arr.flags.writeable):
                arr = np.array(arr, copy=True)       # a read-only array owning its data is kept as is
                arr.setflags(write=False)
            object.__setattr__(self, key, arr)
        n_frames, n_paths = self.lengths.shape
        n_coords = len(self.coordinate_names)
        if self.moment_arms.shape != (n_frames, n_paths, n_coords):
            raise ValueError(f"moment_arms must be (F, M, C) = {(n_frames, n_paths, n_coords)}")
        if self.spanned.shape != (n_paths, n_coords) or len(self.muscle_names) != n_paths:
            raise ValueError("spanned must be (M, C) and muscle_names (M,)")

    @property
    def ordered_points(self) -> np.ndarray:
        """(F, M, K, 3) the current path points in path order per frame, NaN-padded at the end."""
        idx = np.where(self.point_order >= 0, self.point_order, 0)
        out = np.take_along_axis(self.points, idx[..., None], axis=2)
        return np.where((self.point_order >= 0)[..., None], out, np.nan)

    def polyline(self, muscle: str) -> list:
        """The current path of one muscle per frame: a list of F arrays (K_f, 3) in path order."""
        m = self.muscle_names.index(muscle)
        pts, order = self.ordered_points[:, m], self.point_order[:, m]
        return [pts[f, order[f] >= 0] for f in range(pts.shape[0])]

    def mixes_passes(self) -> np.ndarray:
        """(M,) bool: paths whose OpenSim length is more than `MIXED_PASSES` shorter than their
        drawn path in some frame (``drawn_lengths``)."""
        return np.any(self.drawn_lengths - self.lengths > MIXED_PASSES, axis=0)

    def length(self, muscle: str) -> np.ndarray:
        """(F,) length of one path."""
        return self.lengths[:, self.muscle_names.index(muscle)]

    def moment_arm(self, muscle: str, coordinate: str) -> np.ndarray:
        """(F,) moment arm of one path about one coordinate."""
        return self.moment_arms[:, self.muscle_names.index(muscle), self.coordinate_names.index(coordinate)]


def _ancestor_joints(model: Model, body: str) -> set:
    parent = {j.child: j for j in model.joints}
    out = set()
    while body in parent:
        j = parent[body]
        out.add(j.name)
        body = j.parent
    return out


def spanned_coordinates(model: Model, path: Path) -> np.ndarray:
    """(C,) bool: the coordinates ``path`` spans (see the module docstring)."""
    bodies = {p.body for p in path.points} | {model.wrap_object(w.wrap_object).body for w in path.wraps}
    chains = [_ancestor_joints(model, b) for b in bodies]
    joints = set().union(*chains) - set.intersection(*chains) if chains else set()
    names = {c for j in model.joints if j.name in joints for c in j.coordinates}
    for p in path.points:
        if p.kind == "conditional":
            names.add(p.coordinate)
        elif p.kind == "moving":
            names.update(c for c in p.moving_coordinates if c is not None)
    changed = True
    while changed:
        changed = False
        for cp in model.couplers:
            if cp.dependent in names and not set(cp.independent) <= names:
                names.update(cp.independent)
                changed = True
    return np.array([c in names for c in model.coordinate_names], dtype=bool)


def coordinates_spanned(model: Model, path_names) -> tuple:
    """Names of the coordinates, in model order, that any of the paths ``path_names`` spans
    (`spanned_coordinates`; no motion needed)."""
    span = np.zeros(len(model.coordinate_names), dtype=bool)
    for name in path_names:
        span |= spanned_coordinates(model, model.path(name))
    return tuple(n for n, s in zip(model.coordinate_names, span) if s)


def polyline_length(points: np.ndarray, active: np.ndarray, d_points: np.ndarray | None = None) -> tuple:
    """Length of the polyline through the active points, and its derivative.

    Parameters
    ----------
    points : (F, P, 3) float
    active : (F, P) bool
        Inactive points are skipped (each active point joins the next active one).
    d_points : (F, P, C, 3) float, optional

    Returns
    -------
    length : (F,) float
    d_length : (F, C) float or None
    """
    n_frames, n_points = active.shape
    idx = np.where(active, np.arange(n_points), n_points)
    # next active point after i: running minimum from the right, shifted by one
    nxt = np.minimum.accumulate(idx[:, ::-1], axis=1)[:, ::-1]
    nxt = np.concatenate([nxt[:, 1:], np.full((n_frames, 1), n_points)], axis=1)
    valid = active & (nxt < n_points)
    nxt_c = np.minimum(nxt, n_points - 1)
    rows = np.arange(n_frames)[:, None]
    seg = points[rows, nxt_c] - points                           # (F, P, 3)
    seg_len = np.linalg.norm(seg, axis=-1)
    length = np.where(valid, seg_len, 0.0).sum(axis=1)
    if d_points is None:
        return length, None
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = np.where((valid & (seg_len > 0))[..., None], seg / np.where(seg_len > 0, seg_len, 1.0)[..., None], 0.0)
    d_seg = d_points[rows, nxt_c] - d_points                     # (F, P, C, 3)
    d_length = np.einsum("fpi,fpci->fc", unit, d_seg)
    return length, d_length


def _body_twists(tf: np.ndarray, dtf: np.ndarray) -> tuple:
    """Angular and linear velocity of every body per unit coordinate rate.

    ``dR/dq_k = [omega_k]x R`` and ``v_k = dt/dq_k``, so a point fixed in body b moves as
    ``dp/dq_k = omega_k x (p - t_b) + v_k``. Returns omega, v : (F, B, C, 3).
    """
    w = dtf[..., :3, :3] @ np.swapaxes(tf[:, :, None, :3, :3], -1, -2)       # (F, B, C, 3, 3)
    omega = 0.5 * np.stack([w[..., 2, 1] - w[..., 1, 2], w[..., 0, 2] - w[..., 2, 0],
                            w[..., 1, 0] - w[..., 0, 1]], axis=-1)
    return omega, dtf[..., :3, 3]


def _twists(tf: np.ndarray, dtf: np.ndarray, bodies: np.ndarray, coords: np.ndarray) -> np.ndarray:
    """(F, U, 6) [omega, v] of the (body, coordinate) pairs ``bodies``, ``coords`` (see `_body_twists`)."""
    omega, v = _body_twists(tf[:, bodies], dtf[:, bodies, coords][:, :, None])
    return np.concatenate([omega[:, :, 0], v[:, :, 0]], axis=-1)


@dataclass(frozen=True, eq=False)
class _Plan:
    """Index arrays for the unwrapped paths of one model and path selection (built once, cached).

    Attributes
    ----------
    unwrapped, wrapped : (M_u,), (M_w,) int
        Indices into the selection.
    points : `motion.wrapping.path_points._PointSet` of the unwrapped paths (grid (M_u, K), N points
        sorted by body, then path).
    slot_point : (M_u K + 1,) int
        Point index n of each grid slot; N for padding slots and for the extra last slot.
    starts : (J,) int
        Start of every (body, path) run among the N points.
    twist_body, twist_coord : (U,) int
        The (body, coordinate) twists needed, grouped by body.
    groups : tuple of (twist slice, pair slice, (J_b,) selection index of the pairs' paths,
        (C_b,) coordinates) per moving body: the coordinates any of its paths span.
    pair_of : (N,) int
        The (body, path) pair of each point.
    terms : tuple of four (T,) int arrays
        (pair, twist, path in selection, coordinate) of each spanned term, bodies ascending.
    moving : tuple of (path in selection, point index n, PathPoint)
    spanned : (M, C) bool
    """

    unwrapped: np.ndarray
    wrapped: np.ndarray
    points: object
    slot_point: np.ndarray
    starts: np.ndarray
    twist_body: np.ndarray
    twist_coord: np.ndarray
    groups: tuple
    pair_of: np.ndarray
    terms: tuple
    moving: tuple
    spanned: np.ndarray


def _plan(model: Model, chosen: list) -> _Plan:
    """The `_Plan` of ``chosen`` paths of ``model``, made once per model (`Model.cached`)."""
    return model.cached(("action-line plan",) + tuple(p.name for p in chosen),
                        lambda: _make_plan(model, chosen))


def _make_plan(model: Model, chosen: list) -> _Plan:
    n_coords = len(model.coordinates)
    spanned = np.array([spanned_coordinates(model, path) for path in chosen], dtype=bool).reshape(len(chosen), n_coords)
    unwrapped = np.array([m for m, p in enumerate(chosen) if not p.wraps], dtype=np.int64)
    ps = _point_set(model, [chosen[m] for m in unwrapped])
    n_paths, n_slots = ps.shape
    slot_point = np.full(n_paths * n_slots + 1, len(ps.flat), dtype=np.int64)
    slot_point[ps.flat] = np.arange(len(ps.flat))
    path_of = unwrapped[ps.flat // max(n_slots, 1)] if len(ps.flat) else np.zeros(0, np.int64)   # (N,)
    pair_key = ps.bodies * max(len(chosen), 1) + path_of
    starts = np.flatnonzero(np.r_[True, pair_key[1:] != pair_key[:-1]]) if len(pair_key) else np.zeros(0, np.int64)
    pair_body, pair_path = ps.bodies[starts], path_of[starts]
    groups, tw_b, tw_c = [], [], []
    for b in np.unique(pair_body):
        j = np.flatnonzero(pair_body == b)
        coords = np.flatnonzero(spanned[pair_path[j]].any(axis=0))
        if b == 0 or not len(coords):             # ground does not move
            continue
        groups.append((slice(len(tw_b), len(tw_b) + len(coords)), slice(j[0], j[-1] + 1), pair_path[j], coords))
        tw_b += [int(b)] * len(coords)
        tw_c += coords.tolist()
    terms = [(j, tw.start + i, m, c) for tw, pairs, paths, coords in groups
             for j, m in zip(range(pairs.start, pairs.stop), paths) for i, c in enumerate(coords) if spanned[m, c]]
    terms = tuple(np.array([t[i] for t in terms], dtype=np.int64) for i in range(4))
    pair_of = np.cumsum(np.isin(np.arange(len(pair_key)), starts)) - 1
    moving = tuple((int(path_of[n]), n, pt) for n, pt in ps.moving)
    spanned.setflags(write=False)               # shared by every result of this plan
    return _Plan(unwrapped, np.array([m for m, p in enumerate(chosen) if p.wraps], dtype=np.int64), ps,
                 slot_point, starts, np.array(tw_b, dtype=np.int64), np.array(tw_c, dtype=np.int64),
                 tuple(groups), pair_of.astype(np.int64), terms, moving, spanned)


def _unwrapped_paths(plan: _Plan, model: Model, q_used, jac, tf, twist, out: tuple) -> None:
    """Lengths, dL/dq (spanned entries), points, mask and order of all unwrapped paths at once,
    written into their rows of ``out`` = (lengths (F, M), dldq (F, M, C), points (F, M, K, 3)
    NaN-filled, mask (F, M, K) False, order (F, M, K) -1) for a block of frames; ``twist``
    (F, U, 6) are the body twists ``plan.twist_body``, ``plan.twist_coord``.

    dL/dq_k = sum_i g_i . dp_i/dq_k with g_i = (unit vector of the segment arriving at point i)
    - (unit vector of the segment leaving it); rigid points contribute through their body's
    twist: g . (omega x (p - t) + v) = omega . ((p - t) x g) + v . g, summed per (body, path)
    pair first, then one product per pair and spanned coordinate; moving points add
    g . R dp_body/dq. The compiled kernel (`motion.wrapping.path_points._polyline_kernel`) does the
    polyline part (its numpy oracle is in ``tests/motion/polyline_oracle.py``).
    """
    lengths, dldq, points, mask, order = out
    ps = plan.points
    n_slots = ps.shape[1]
    locals_ = [_moving_local(pt, model, q_used, jac) for _, pt in ps.moving]     # few moving points
    moving_loc = np.stack([x[0] for x in locals_], axis=1) if locals_ else np.zeros((len(q_used), 0, 3))
    act = _point_set_active(ps, q_used)
    g_moving = np.empty_like(moving_loc)
    _polyline_kernel()(tf, ps.bodies, ps.loc, np.array([n for n, _ in ps.moving], dtype=np.int64), moving_loc,
                       act, plan.slot_point, n_slots, plan.pair_of, twist, *plan.terms, plan.unwrapped,
                       lengths, g_moving, dldq, points, mask, order)
    for i, (m, n, _) in enumerate(plan.moving):
        gr = np.einsum("fk,fkj->fj", g_moving[:, i], tf[:, ps.bodies[n], :3, :3])     # g . R
        dldq[:, m] += np.einsum("fj,fcj->fc", gr, locals_[i][1])


def _wrap_module():
    try:
        from . import batch as path_wrapping
    except ImportError as exc:       # clearly marked: never measure a wrapped path without its wraps
        raise NotImplementedError("this path has wrap objects but motion.wrapping.batch is not available; "
                                  "refusing to return an unwrapped (wrong) length") from exc
    return path_wrapping


FRAME_BLOCK = 512   # frames per block in `action_lines` (bounds memory, keeps arrays vectorised)


def _block(model: Model, chosen: list, plan: _Plan, q: np.ndarray, out: tuple, drawn: np.ndarray) -> tuple:
    """One block of frames: fills its rows of ``out`` (see `_unwrapped_paths`; lengths and dldq
    also for the wrapped paths) and the wrapped paths' columns of ``drawn`` (drawn lengths);
    returns q_used and the wrapped paths' (points, mask, labels, order)."""
    if len(plan.wrapped):                    # the wrap helper works with d tf (F, B, C, 4, 4)
        tf, dtf, q_used, jac = body_pose_derivatives(model, q)
        twist = _twists(tf, dtf, plan.twist_body, plan.twist_coord) if len(plan.unwrapped) else None
    else:                                    # body twists directly (no (F, B, C, 4, 4) array)
        tf, twist, q_used, jac = _pose_twists(model, q)
        twist = twist[:, plan.twist_body, plan.twist_coord]
    lengths, dldq = out[:2]
    if len(plan.unwrapped):
        _unwrapped_paths(plan, model, q_used, jac, tf, twist, out)
    per_path = []
    if len(plan.wrapped):
        paths = [chosen[m] for m in plan.wrapped]
        pps = [path_points(path, model, q_used, tf, jac=jac, d_tf_ground_body=dtf) for path in paths]
        # derivatives only along the coordinates each path spans (the others are 0 by definition)
        cols = [np.flatnonzero(plan.spanned[m]) for m in plan.wrapped]
        results = _wrap_module().wrap_paths(paths, model, [pp.points for pp in pps], [pp.active for pp in pps],
                                            [pp.d_points for pp in pps], tf, dtf, cols)
        for m, c, (length, d_length, pts, msk, labels, ordr, drawn_m) in zip(plan.wrapped, cols, results):
            lengths[:, m] = length
            drawn[:, m] = drawn_m
            dldq[:, m, c] = d_length
            per_path.append((pts, msk, labels, ordr))
    return q_used, per_path


def action_lines(model: Model, motion, *, muscles=None) -> ActionLines:
    """Lengths, moment arms and current points of the model's path forces over a motion.

    Parameters
    ----------
    model : Model
    motion : Motion-like (``time`` (F,), ``q`` (F, C), ``coordinate_names``) or (F, C) array.
    muscles : sequence of str, optional, keyword-only
        Names of the path forces to compute (default: all, in model order).

    Returns
    -------
    ActionLines
    """
    if muscles is None:
        chosen = list(model.paths)
    else:
        if isinstance(muscles, str):
            muscles = [muscles]
        unknown = [m for m in muscles if m not in model.path_names]
        if unknown:
            raise InputError(f"no path force named {unknown[0]!r} in model {model.name!r}", file=model.file,
                             where="ForceSet", fix=f"choose among {', '.join(model.path_names[:8])}"
                             + (" ..." if len(model.path_names) > 8 else ""))
        chosen = [model.path(m) for m in muscles]
    time, q = motion_coordinates(model, motion)
    n_frames, n_coords = q.shape
    plan = _plan(model, chosen)
    spanned = plan.spanned
    n_slots = plan.points.shape[1] if len(plan.unwrapped) else 0
    # wrapped paths have more nodes (their tangent points): room for all from the start
    k_max = max([len(chosen[m].points) + 2 * len(chosen[m].wraps) for m in plan.wrapped] + [n_slots])
    lengths = np.zeros((n_frames, len(chosen)))
    dldq = np.zeros((n_frames, len(chosen), n_coords))
    points = np.full((n_frames, len(chosen), k_max, 3), np.nan)
    mask = np.zeros((n_frames, len(chosen), k_max), dtype=bool)
    order = np.full((n_frames, len(chosen), k_max), -1, dtype=np.int64)
    drawn = np.zeros((n_frames, len(chosen)))
    # frames in blocks: memory stays bounded (d_tf is (F, B, C, 4, 4)) on long motions
    blocks = [_block(model, chosen, plan, q[i:i + FRAME_BLOCK],
                     tuple(a[i:i + FRAME_BLOCK] for a in (lengths, dldq, points, mask, order)),
                     drawn[i:i + FRAME_BLOCK])
              for i in range(0, max(n_frames, 1), FRAME_BLOCK)]
    q_used = blocks[0][0] if len(blocks) == 1 else np.concatenate([b[0] for b in blocks])
    per_path = [(np.concatenate([b[1][w][0] for b in blocks]), np.concatenate([b[1][w][1] for b in blocks]),
                 blocks[0][1][w][2], np.concatenate([b[1][w][3] for b in blocks]))
                for w in range(len(plan.wrapped))]
    moment_arms = np.negative(dldq, out=dldq)
    moment_arms[:, ~spanned] = 0.0                 # exactly 0.0 where not spanned
    unwrapped = np.setdiff1d(np.arange(len(chosen)), np.asarray(plan.wrapped, dtype=int))
    drawn[:, unwrapped] = lengths[:, unwrapped]
    labels = [tuple(p.name for p in path.points) for path in chosen]
    for m, (pts, msk, lab, ordr) in zip(plan.wrapped, per_path):
        k = pts.shape[1]
        points[:, m, :k] = np.where(msk[..., None], pts, np.nan)
        mask[:, m, :k] = msk
        order[:, m, :ordr.shape[1]] = ordr
        labels[m] = lab
    labels = tuple(tuple(lab) + ("",) * (k_max - len(lab)) for lab in labels)
    dep = model.dependent_coordinates
    status = tuple("dependent" if dep[i] else ("locked" if c.locked else "independent")
                   for i, c in enumerate(model.coordinates))
    for arr in (lengths, moment_arms, q_used, points, mask, order, drawn):
        if arr.flags.owndata:
            arr.setflags(write=False)            # ours alone: ActionLines keeps it without a copy
    lines = ActionLines(lengths, moment_arms, spanned, tuple(p.name for p in chosen), model.coordinate_names,
                        status, time, q_used, points, mask, labels, order, drawn)
    _warn_mixed_passes(model, lines)
    return lines


def _warn_mixed_passes(model: Model, lines: ActionLines) -> None:
    """One warning naming the paths that `ActionLines.mixes_passes`, with their largest gap."""
    gap = lines.drawn_lengths - lines.lengths
    bad = [(n, gap[:, k]) for k, n in enumerate(lines.muscle_names) if lines.mixes_passes()[k]]
    if not bad:
        return
    import warnings

    from ..osim.reader import ModelFileWarning

    listed = ", ".join(f"{n} (up to {1e3 * g.max():.1f} mm, {int((g > MIXED_PASSES).sum())} of {len(g)} frames)"
                       for n, g in bad)
    warnings.warn(f"{model.file}: OpenSim 4.6's length of path(s) over wrap objects in series is shorter than "
                  f"the path it draws: {listed}; its length keeps the tangent points of the first wrapping "
                  "pass. The action lines reproduce OpenSim's length and its -dL/dq, which can differ there from "
                  "OpenSim's computeMomentArm; the moving surfaces follow the drawn path (ActionLines.drawn_lengths)",
                  ModelFileWarning, stacklevel=3)
