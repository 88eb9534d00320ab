"""Numpy oracle of `motion.wrapping.wrapped_rows`: OpenSim's applyWrapObjects on dual numbers.

The same algorithm as the package's compiled kernel (the steps are documented there), written
independently on `Dual` arrays (forward-mode derivatives along D directions) and vectorised
over rows: each row carries its own current path as an index array, and every wrap computation
runs on all rows that need it, with masks; all eligible segments of all rows go through the
wrap-line function (`cylinder`, `sphere`, `ellipsoid`, `torus` beside this file) in one call.
``wrap_rows`` takes the package's `motion.wrapping.batch.WrapSlot` list.
"""
from __future__ import annotations

import numpy as np

from . import dual as ad
from .dual import Dual
from motion.wrapping.cylinder_line import ELLIPSOID_METHODS
from motion.wrapping.wrapped_rows import CYLINDER, ELLIPSOID, SPHERE

from .cylinder import INSIDE_RADIUS, MANDATORY_WRAP, NO_WRAP, WRAPPED, cylinder_wrap_line
from .ellipsoid import ellipsoid_wrap_line
from .sphere import sphere_wrap_line
from .torus import torus_wrap_line

__all__ = ["wrap_rows", "line_function"]

_CONVERGED = 0.0005  # m, OpenSim's length-change criterion between passes


_AXES = {(0, 1): "x", (0, -1): "-x", (1, 1): "y", (1, -1): "-y", (2, 1): "z", (2, -1): "-z"}


def line_function(slot, n_rows: int):
    """(numpy wrap-line function, options) of a `motion.wrapping.batch.WrapSlot`; options that
    differ per row are (N,) arrays (cylinder radius and length) or must be equal in all rows."""
    quadrant = _AXES.get((slot.axis, slot.sign), "all")
    prm = np.broadcast_to(np.asarray(slot.params, dtype=float), (n_rows, 3))
    if slot.kind == CYLINDER:
        return cylinder_wrap_line, dict(radius=prm[:, 0], length=prm[:, 1], quadrant=quadrant,
                                        adjust_tangents=bool(slot.adjust))
    first = prm[0]
    assert np.all(prm == first), "the numpy oracle takes one size per call for this kind"
    if slot.kind == SPHERE:
        return sphere_wrap_line, dict(radius=float(first[0]), quadrant=quadrant)
    if slot.kind == ELLIPSOID:
        return ellipsoid_wrap_line, dict(dimensions=first.copy(), quadrant=quadrant,
                                         method=ELLIPSOID_METHODS[slot.method])
    return torus_wrap_line, dict(inner_radius=float(first[0]), outer_radius=float(first[1]), quadrant=quadrant)


def _apply_rt(rot: Dual, v: Dual) -> Dual:
    """R^T v for stacks: rot (F, 3, 3), v (F, 3); d(R^T v) = dR^T v + R^T dv."""
    rot, v = ad.lift(rot), ad.lift(v)
    return Dual(np.einsum("fij,fi->fj", rot.v, v.v),
                np.einsum("fijd,fi->fjd", rot.d, v.v) + np.einsum("fij,fid->fjd", rot.v, v.d))


def _apply_r(rot: Dual, v: Dual) -> Dual:
    """R v for stacks: rot (F, 3, 3), v (F, 3); d(R v) = dR v + R dv."""
    rot, v = ad.lift(rot), ad.lift(v)
    return Dual(np.einsum("fij,fj->fi", rot.v, v.v),
                np.einsum("fijd,fj->fid", rot.d, v.v) + np.einsum("fij,fjd->fid", rot.v, v.d))


def _subset(x: Dual, sel) -> Dual:
    return Dual(x.v[sel], x.d[sel])


def _concat(parts: list) -> Dual:
    """Duals (n_i, ...) stacked along the leading axis."""
    n_d = ad.dsize(*parts)
    return Dual(np.concatenate([p.v for p in parts]),
                np.concatenate([np.broadcast_to(p.d, p.v.shape + (n_d,)) for p in parts]))


def _gather(nodes: list, ids: np.ndarray) -> Dual:
    """Per-frame node positions: nodes[k] Dual (F, 3), ids (F,) -> Dual (F, 3) (id -1: node 0).

    Copies frame rows node by node (a path has few distinct nodes at one position of its
    current path) rather than stacking every node's (F, 3, D) derivatives first."""
    safe = np.where(ids >= 0, ids, 0)
    uniq = np.unique(safe)
    if len(uniq) == 1:
        return nodes[uniq[0]]
    nf = ids.shape[0]
    n_d = ad.dsize(*[nodes[k] for k in uniq])
    v = np.empty((nf, 3))
    d = np.empty((nf, 3, n_d))
    for k in uniq:
        rows = safe == k
        v[rows] = nodes[k].v[rows]
        d[rows] = np.broadcast_to(nodes[k].d, (nf, 3, n_d))[rows]
    return Dual(v, d)


class _GroundCache:
    """OpenSim's Point::getLocationInGround cache, per frame and node.

    A tangent point's ground position is cached (Stage::Position) the first time it is read
    in a realised state; later ``setLocation`` calls in further passes of applyWrapObjects
    change the point's location property -- which the wrapping itself uses -- but not the
    cached ground position, which path lengths, length changes and reported points use. With
    two or more wrap objects whose tangent points move between passes, OpenSim's length is
    therefore built from first-pass positions and last-pass arc lengths; this reproduces it.
    """

    def __init__(self, nodes: list, n_points: int):
        nf = nodes[0].v.shape[0]
        self.seen = list(nodes)
        self.ok = np.zeros((nf, len(nodes)), dtype=bool)
        self.ok[:, :n_points] = True   # defined points never move within a state

    def see(self, nodes: list, ids: np.ndarray, mask: np.ndarray):
        """Read nodes ``ids`` (F,) in the frames of ``mask``: cache first reads."""
        fr = np.arange(ids.shape[0])
        safe = np.where(ids >= 0, ids, 0)
        first = mask & (ids >= 0) & ~self.ok[fr, safe]
        if not first.any():
            return
        for k in np.unique(safe[first]):
            m = first & (safe == k)
            self.seen[k] = ad.where(m[:, None], nodes[k], self.seen[k])
        self.ok[fr[first], safe[first]] = True


def _remove(order: np.ndarray, count: np.ndarray, ids: tuple, frames: np.ndarray):
    """Remove node ids from the order rows of ``frames`` (keeping order)."""
    order = order.copy()
    drop = np.isin(order, ids) & frames[:, None]
    keep = (order >= 0) & ~drop
    key = np.where(keep, 0, 1)
    perm = np.argsort(key, axis=1, kind="stable")
    new = np.take_along_axis(np.where(keep, order, -1), perm, axis=1)
    return new, keep.sum(axis=1)


def _insert_after(order: np.ndarray, count: np.ndarray, pos: np.ndarray, ids: tuple, frames):
    """Insert two node ids after column ``pos`` in the rows of ``frames``."""
    nf, nk = order.shape
    out = order.copy()
    cols = np.arange(nk)[None, :]
    shifted = np.full_like(order, -1)
    shifted[:, 2:] = order[:, :-2]
    p = pos[:, None]
    new = np.where(cols <= p, order, shifted)
    new = np.where(cols == p + 1, ids[0], new)
    new = np.where(cols == p + 2, ids[1], new)
    out[frames] = new[frames]
    return out, count + 2 * frames


def _path_length(order, nodes, arcs, n_points, n_wraps, cache) -> Dual:
    """Length of every frame's current path (OpenSim calcLengthAfterPathComputation)."""
    nf, nk = order.shape
    total = None
    for j in range(nk - 1):
        a, b = order[:, j], order[:, j + 1]
        valid = (a >= 0) & (b >= 0)
        if not valid.any():
            break
        same_wrap = (a >= n_points) & (b == a + 1) & ((a - n_points) % 2 == 0)
        cache.see(nodes, a, valid & ~same_wrap)
        cache.see(nodes, b, valid & ~same_wrap)
        seg = ad.norm(_gather(cache.seen, b) - _gather(cache.seen, a))
        if n_wraps:
            w = np.clip((a - n_points) // 2, 0, n_wraps - 1)
            arc_v = np.stack([x.v for x in arcs], axis=1)[np.arange(nf), w]
            arc_d = np.stack([x.d for x in arcs], axis=1)[np.arange(nf), w]
            seg = ad.where(same_wrap, Dual(arc_v, arc_d), seg)
        seg = ad.where(valid, seg, 0.0)
        total = seg if total is None else total + seg
    if total is None:
        total = Dual(np.zeros(nf))
    return total


def wrap_rows(points, active, d_points, slots) -> tuple:
    """OpenSim's applyWrapObjects on N independent rows (see the module docstring).

    Parameters
    ----------
    points : (N, P, 3) float; active : (N, P) bool; d_points : (N, P, D, 3) float
        Defined path points in ground per row (padding points: inactive), their derivatives
        along D directions (per row any meaning: the algebra is linear in them).
    slots : sequence of `WrapSlot` in PathWrapSet order.

    Returns
    -------
    length : Dual (N,) with (N, D) derivatives
    order : (N, P + 2 W) int
        Current path as node indices (nodes ``P + 2 w``, ``P + 2 w + 1``: wrap w's tangent points).
    mask : (N, P + 2 W) bool
    seen : list of Dual (N, 3)
        Node positions as OpenSim reports them (first reads of the ground-position cache).
    arcs : list of Dual (N,)
        Arc length per wrap (valid where its tangent points are in the path).
    """
    nf, n_points = points.shape[:2]
    n_coords = d_points.shape[2]
    n_wraps = len(slots)
    n_nodes = n_points + 2 * n_wraps
    with np.errstate(all="ignore"):
        nodes = [Dual(points[:, k], np.moveaxis(d_points[:, k], 1, 2)) for k in range(n_points)]
        nan = Dual(np.full((nf, 3), np.nan), np.zeros((nf, 3, n_coords)))
        nodes += [nan] * (2 * n_wraps)
        arcs = [Dual(np.zeros(nf), np.zeros((nf, n_coords)))] * n_wraps
        cache = _GroundCache(nodes, n_points)

        # initial current path: active points, compacted
        order = np.full((nf, n_nodes), -1)
        key = np.where(active, 0, 1)
        perm = np.argsort(key, axis=1, kind="stable")
        order[:, :n_points] = np.where(np.take_along_axis(active, perm, 1), perm, -1)
        count = active.sum(axis=1)

        setups = []
        for slot in slots:
            rot = Dual(slot.tf[:, :3, :3], np.moveaxis(slot.dtf[:, :, :3, :3], 1, 3))
            origin = Dual(slot.tf[:, :3, 3], np.moveaxis(slot.dtf[:, :, :3, 3], 1, 2))
            setups.append((slot, rot, origin, line_function(slot, nf)))

        wrap_order = np.tile(np.arange(n_wraps), (nf, 1))
        running = np.ones(nf, dtype=bool)
        last_length = np.full(nf, np.inf)
        max_iter = 1 if n_wraps < 2 else 8
        length = _path_length(order, nodes, arcs, n_points, n_wraps, cache)
        for kk in range(max_iter):
            if n_wraps == 0 or not running.any():
                break
            result = np.zeros((nf, n_wraps), dtype=int)
            for i in range(n_wraps):
                for w in range(n_wraps):
                    frames = running & (wrap_order[:, i] == w)
                    if not frames.any():
                        continue
                    ids = (n_points + 2 * w, n_points + 2 * w + 1)
                    order, count = _remove(order, count, ids, frames)
                    slot, rot, origin, line = setups[w]
                    if not slot.active:
                        continue
                    order, count, nodes, arcs, res = _wrap_one(
                        w, frames, order, count, nodes, arcs, active, rot, origin, slot, line, n_points, cache)
                    result[frames, i] = res[frames]
            length = _path_length(order, nodes, arcs, n_points, n_wraps, cache)
            conv = running & (np.abs(length.v - last_length) < _CONVERGED)
            last_length = np.where(running, length.v, last_length)
            running = running & ~conv
            if kk == 0 and n_wraps > 1:
                swap = running & (result[:, 0] == NO_WRAP) & (result[:, 1] == INSIDE_RADIUS)
                if swap.any():
                    first = wrap_order[:, 0].copy()
                    wrap_order[swap, 0] = wrap_order[swap, 1]
                    wrap_order[swap, 1] = first[swap]
                    # OpenSim then removes wrap object 0's points from the path
                    ids = (n_points, n_points + 1)
                    order, count = _remove(order, count, ids, swap)
        # the final length is what OpenSim caches: the last pass's path
        length = _path_length(order, nodes, arcs, n_points, n_wraps, cache)

    mask = np.zeros((nf, n_nodes), dtype=bool)
    fr = np.repeat(np.arange(nf)[:, None], n_nodes, axis=1)
    ok = order >= 0
    mask[fr[ok], order[ok]] = True
    # reported points are what OpenSim's getLocationInGround returns: the cached positions
    return length, order, mask, cache.seen, arcs


def _wrap_one(w, frames, order, count, nodes, arcs, active, rot, origin, slot, line, n_points, cache):
    """Try wrap ``w`` on every eligible segment of the frames' current paths; insert the best."""
    nf, nk = order.shape
    n_coords = nodes[0].d.shape[-1]
    # first / last active defined point in the range, and their positions in the current path
    rng = np.arange(n_points)[None, :]
    act = active & (rng >= slot.start[:, None]) & (rng <= slot.end[:, None])
    has = act.any(axis=1)
    jfwd = np.argmax(act, axis=1)
    jrev = n_points - 1 - np.argmax(act[:, ::-1], axis=1)
    pos_s = np.argmax(order == jfwd[:, None], axis=1)
    pos_e = np.argmax(order == jrev[:, None], axis=1)
    frames = frames & has

    result = np.zeros(nf, dtype=int)
    found_mand = np.zeros(nf, dtype=bool)
    best = np.zeros(nf, dtype=bool)
    best_pos = np.zeros(nf, dtype=int)
    min_change = np.full(nf, np.inf)
    best_r1 = Dual(np.zeros((nf, 3)), np.zeros((nf, 3, n_coords)))
    best_r2 = best_r1
    best_arc = Dual(np.zeros(nf), np.zeros((nf, n_coords)))
    # every eligible segment of every row in one call of the wrap function (its cost is the
    # number of numpy calls); OpenSim's order -- segments in path order, the first mandatory
    # wrap ends the search -- is applied to the results below
    cand = []
    for j in range(nk - 1):
        a, b = order[:, j], order[:, j + 1]
        same = (a >= n_points) & (b >= n_points) & ((a - n_points) // 2 == (b - n_points) // 2)
        ok = frames & (j >= pos_s) & (j < pos_e) & (a >= 0) & (b >= 0) & ~same
        sel = np.nonzero(ok)[0]
        if sel.size:
            cand.append((j, a, b, sel))
    if cand:
        rows = np.concatenate([c[3] for c in cand])
        pa = _concat([_subset(_gather(nodes, a), sel) for _, a, _, sel in cand])
        pb = _concat([_subset(_gather(nodes, b), sel) for _, _, b, sel in cand])
        r_s, o_s = _subset(rot, rows), _subset(origin, rows)
        fn, opts = line
        opts = {k: (v[rows] if k in ("radius", "length") and np.ndim(v) else v) for k, v in opts.items()}
        code_all, r1_all, r2_all, arc_all = fn(_apply_rt(r_s, pa - o_s), _apply_rt(r_s, pb - o_s), **opts)
        r1g_all = _apply_r(r_s, r1_all) + o_s
        r2g_all = _apply_r(r_s, r2_all) + o_s
    start = 0
    for j, a, b, sel in cand:
        part = np.arange(start, start + sel.size)
        start += sel.size
        keep = ~found_mand[sel]
        if not keep.any():
            continue
        sel, part = sel[keep], part[keep]
        code, arc = code_all[part], _subset(arc_all, part)
        r1g, r2g = _subset(r1g_all, part), _subset(r2g_all, part)
        result[sel] = code
        mand = code == MANDATORY_WRAP
        wrapped = code == WRAPPED
        # GeometryPath::calcPathLengthChange (only for "wrapped") reads the end points' cached
        # ground positions
        if wrapped.any():
            m = np.zeros(nf, dtype=bool)
            m[sel[wrapped]] = True
            cache.see(nodes, a, m)
            cache.see(nodes, b, m)
        sa = _subset(_gather(cache.seen, a), sel)
        sb = _subset(_gather(cache.seen, b), sel)
        change = (ad.norm(r1g - sa) + arc + ad.norm(sb - r2g) - ad.norm(sb - sa)).v
        take = mand | (wrapped & (change < min_change[sel]))
        tsel = sel[take]
        if tsel.size:
            best[tsel] = True
            best_pos[tsel] = j
            min_change[tsel] = np.where(mand[take], min_change[tsel], change[take])
            best_r1 = ad.scatter(best_r1, tsel, _subset(r1g, take))
            best_r2 = ad.scatter(best_r2, tsel, _subset(r2g, take))
            best_arc = ad.scatter(best_arc, tsel, _subset(arc, take))
        found_mand[sel[mand]] = True
    ins = frames & best
    if ins.any():
        order, count = _insert_after(order, count, best_pos, (n_points + 2 * w, n_points + 2 * w + 1), ins)
        nodes = list(nodes)
        arcs = list(arcs)
        nodes[n_points + 2 * w] = ad.where(ins[:, None], best_r1, nodes[n_points + 2 * w])
        nodes[n_points + 2 * w + 1] = ad.where(ins[:, None], best_r2, nodes[n_points + 2 * w + 1])
        arcs[w] = ad.where(ins, best_arc, arcs[w])
    return order, count, nodes, arcs, result
