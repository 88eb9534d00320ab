"""Wrapped paths, compiled: OpenSim's GeometryPath::applyWrapObjects on rows (path x frame).

Contract: `wrap_compiled_rows` returns, for rows whose wraps have the same kinds (WrapCylinder,
WrapSphere, WrapEllipsoid, WrapTorus, alone or in series), each row's length and dL/dq along its
own directions, the current path as node order, and the reported node positions, by OpenSim
4.6's algorithm step for step:

- The current path starts as the active path points (conditional points may be inactive).
- Wrap objects are applied in PathWrapSet order. For each one, its two tangent points are
  first removed from the current path; an inactive wrap object stops there.
- The range ``(start, end)`` of defined points is narrowed to the first and last *active*
  points in it; every segment of the current path between those two is tried, except one
  joining the two tangent points of one wrap object, in the wrap object's frame.
- The first segment whose wrap is ``mandatoryWrap`` wins at once; otherwise among ``wrapped``
  segments the one whose length grows least.
- The winner's tangent points are inserted after the segment's first point; the length adds
  the arc between them and the straight distances elsewhere.
- With two or more wrap objects the pass is repeated (up to 8 times) until the length changes
  by less than 0.5 mm; after the first pass, if the first object did not wrap and the second
  found a point inside it, their order is swapped (and wrap object 0's points removed).
- Lengths and reported points use each tangent point's ground position as first read in the
  state (OpenSim caches ``Point::getLocationInGround`` at Stage::Position), while the wrapping
  and the arcs use the latest pass: with several wrap objects OpenSim's length mixes passes,
  and so does this.
- Not reproduced: when a range holds no active point OpenSim abandons the remaining wrap
  objects of that pass; here only that wrap object is skipped (such a range is a model error).

The segment over one object: `motion.wrapping.cylinder_line` (and torus: through the cylinder),
`motion.wrapping.sphere_torus_line`, `motion.wrapping.ellipsoid_line`. A numpy implementation of
the same algorithm on dual numbers is the oracle in ``tests/motion/wrap_oracle/``
(``tests/motion/test_compiled_wraps.py`` compares them on real models).

Method: one module-level numba kernel (`_rows_kernel`) runs every row once per derivative
direction with complex-step numbers (the value and one directional derivative); the values,
hence every branch, are the same in each run. It is compiled (and cached on disk) in two
variants told apart by the type of its ``wkind`` argument: None when every wrap object is a
cylinder, the kinds array otherwise; `_line` is a numba overload that gives the first variant
the cylinder's line alone, so that a cylinder-only model never compiles the other kinds (see
``all_kinds`` of `wrap_compiled_rows`; numbers in ``docs/decisions.md``). Scratch arrays are
allocated once per call. The ellipsoid's fan (`motion.wrapping.ellipsoid_line`), linear in the
direction once its two 3 x 3 sums are known, is kept in a small memo keyed by its real inputs,
so that the directions of a row compute it once.
"""
from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import overload

from .cylinder_line import INSIDE_RADIUS, MANDATORY_WRAP, NO_WRAP, STEP, WRAPPED, vnorm, vsub, wrap_line
from .ellipsoid_line import ellipsoid_line
from .sphere_torus_line import sphere_line, torus_line

__all__ = ["wrap_compiled_rows", "CYLINDER", "SPHERE", "ELLIPSOID", "TORUS"]

CYLINDER, SPHERE, ELLIPSOID, TORUS = 0, 1, 2, 3     # wrap object kinds as the kernel takes them

_CONVERGED = 0.0005                  # m, OpenSim's length-change criterion between passes
_NO, _INSIDE, _WRAPPED, _MANDATORY = NO_WRAP, INSIDE_RADIUS, WRAPPED, MANDATORY_WRAP


@njit(cache=True, error_model="numpy")
def _see(k, node, seen, ok):
    """OpenSim's Point::getLocationInGround cache: the first read of a node is kept."""
    if not ok[k]:
        for i in range(3):
            seen[k, i] = node[k, i]
        ok[k] = True


@njit(cache=True, error_model="numpy")
def _path_length(order, node, seen, ok, arc, n_points):
    """Length of the current path (calcLengthAfterPathComputation), reading the cache."""
    total = 0j
    for j in range(order.shape[0] - 1):
        a, b = order[j], order[j + 1]
        if a < 0 or b < 0:
            break
        if a >= n_points and b == a + 1 and (a - n_points) % 2 == 0:
            total += arc[(a - n_points) // 2]
        else:
            _see(a, node, seen, ok)
            _see(b, node, seen, ok)
            total += vnorm((seen[b, 0] - seen[a, 0], seen[b, 1] - seen[a, 1], seen[b, 2] - seen[a, 2]))
    return total


@njit(cache=True, error_model="numpy")
def _remove(order, i0, i1):
    """Drop node ids i0, i1 from the current path, keeping the order."""
    c = 0
    for j in range(order.shape[0]):
        if order[j] >= 0 and order[j] != i0 and order[j] != i1:
            order[c] = order[j]
            c += 1
    for j in range(c, order.shape[0]):
        order[j] = -1


@njit(cache=True, error_model="numpy")
def _to_wrap(node, k, f):
    """R^T (p_k - o) for the wrap frame f = [R o] (complex, 4 x 4)."""
    x, y, z = node[k, 0] - f[0, 3], node[k, 1] - f[1, 3], node[k, 2] - f[2, 3]
    return (f[0, 0] * x + f[1, 0] * y + f[2, 0] * z, f[0, 1] * x + f[1, 1] * y + f[2, 1] * z,
            f[0, 2] * x + f[1, 2] * y + f[2, 2] * z)


@njit(cache=True, error_model="numpy")
def _to_ground(r, f):
    """R r + o for the wrap frame f = [R o]."""
    return (f[0, 0] * r[0] + f[0, 1] * r[1] + f[0, 2] * r[2] + f[0, 3],
            f[1, 0] * r[0] + f[1, 1] * r[1] + f[1, 2] * r[2] + f[1, 3],
            f[2, 0] * r[0] + f[2, 1] * r[1] + f[2, 2] * r[2] + f[2, 3])


def _line(wkind, w, pa, pb, prm, axis, sign, adjust, method, memo, memo_n):
    """The segment pa -> pb (wrap frame) over wrap object w: (code, r1, r2, arc).

    Compiled only inside the kernel (`_line_kinds` gives its body by the type of ``wkind``)."""
    raise NotImplementedError("compiled only (motion.wrapping.wrapped_rows._rows_kernel)")


def _cylinder(wkind, w, pa, pb, prm, axis, sign, adjust, method, memo, memo_n):
    """`_line` when every wrap object is a cylinder (``wkind`` None)."""
    return wrap_line(pa, pb, prm[0], prm[1], axis, sign, adjust)


def _any_kind(wkind, w, pa, pb, prm, axis, sign, adjust, method, memo, memo_n):
    """`_line` for wrap objects of any kind (``wkind`` (W,) int)."""
    kind = wkind[w]
    if kind == CYLINDER:
        return wrap_line(pa, pb, prm[0], prm[1], axis, sign, adjust)
    if kind == SPHERE:
        return sphere_line(pa, pb, prm[0], axis, sign)
    if kind == ELLIPSOID:
        return ellipsoid_line(pa, pb, prm[0], prm[1], prm[2], axis, sign, method, memo, memo_n)
    return torus_line(pa, pb, prm[0], prm[1], axis, sign)


@overload(_line, jit_options={"error_model": "numpy"})
def _line_kinds(wkind, w, pa, pb, prm, axis, sign, adjust, method, memo, memo_n):
    """Typing-time choice of `_line`'s body: with ``wkind`` None only the cylinder's code is
    typed and compiled (the other kinds' functions are never compiled nor loaded)."""
    return _cylinder if isinstance(wkind, types.NoneType) else _any_kind


@njit(cache=True, error_model="numpy")
def _wrap_one(n, w, active, frame, wstart, wend, wkind, wparam, waxis, wsign, wadjust, wmethod, order, node, seen,
              ok, arc, memo, memo_n):
    """Try wrap w on every eligible segment of the current path, insert the best; its code.

    ``frame`` (4, 4) complex: the wrap frame in ground with its derivative along this direction.
    """
    n_points = active.shape[1]
    jf, jr = -1, -1
    for j in range(max(wstart[w, n], 0), min(wend[w, n], n_points - 1) + 1):
        if active[n, j]:
            if jf < 0:
                jf = j
            jr = j
    if jf < 0:
        return _NO
    pos_s, pos_e = 0, 0
    for j in range(order.shape[0] - 1, -1, -1):
        if order[j] == jf:
            pos_s = j
        if order[j] == jr:
            pos_e = j
    result = _NO
    best = -1
    min_change = np.inf
    best_r1 = best_r2 = (0j, 0j, 0j)
    best_arc = 0j
    for j in range(pos_s, min(pos_e, order.shape[0] - 1)):
        a, b = order[j], order[j + 1]
        if a < 0 or b < 0 or (a >= n_points and b >= n_points and (a - n_points) // 2 == (b - n_points) // 2):
            continue
        pa = _to_wrap(node, a, frame)
        pb = _to_wrap(node, b, frame)
        code, r1, r2, arc_ab = _line(wkind, w, pa, pb, wparam[w, n], waxis[w], wsign[w], wadjust[w], wmethod[w], memo,
                                     memo_n)
        result = code
        if code < _WRAPPED:
            continue
        g1, g2 = _to_ground(r1, frame), _to_ground(r2, frame)
        if code == _WRAPPED:     # calcPathLengthChange reads the end points' cached positions
            _see(a, node, seen, ok)
            _see(b, node, seen, ok)
        sa = (seen[a, 0], seen[a, 1], seen[a, 2])
        sb = (seen[b, 0], seen[b, 1], seen[b, 2])
        change = (vnorm(vsub(g1, sa)).real + arc_ab.real + vnorm(vsub(sb, g2)).real
                  - vnorm(vsub(sb, sa)).real)
        if code == _MANDATORY or change < min_change:
            best = j
            if code != _MANDATORY:
                min_change = change
            best_r1, best_r2, best_arc = g1, g2, arc_ab
        if code == _MANDATORY:
            break
    if best >= 0:
        k = n_points + 2 * w
        for j in range(order.shape[0] - 1, best + 2, -1):
            order[j] = order[j - 2]
        order[best + 1] = k
        order[best + 2] = k + 1
        for i in range(3):
            node[k, i] = best_r1[i]
            node[k + 1, i] = best_r2[i]
        arc[w] = best_arc
    return result


@njit(cache=True, error_model="numpy", nogil=True)
def _rows_kernel(points, active, d_points, n_dirs, wtf, wdtf, wstart, wend, wkind, wparam, waxis, wsign, wadjust,
                 wmethod, wactive, out_length, out_dlength, out_order, out_seen, out_node, out_arc):
    """applyWrapObjects on every row along every direction: length, dL, order, reported nodes,
    nodes of the last pass."""
    n_rows, n_points = active.shape
    n_wraps = wtf.shape[0]
    n_nodes = n_points + 2 * n_wraps
    order = np.empty(n_nodes, dtype=np.int64)
    node = np.empty((n_nodes, 3), dtype=np.complex128)
    seen = np.empty((n_nodes, 3), dtype=np.complex128)
    ok = np.empty(n_nodes, dtype=np.bool_)
    arc = np.empty(n_wraps, dtype=np.complex128)
    frames = np.empty((n_wraps, 4, 4), dtype=np.complex128)
    wrap_order = np.empty(n_wraps, dtype=np.int64)
    result = np.empty(n_wraps, dtype=np.int64)
    memo = np.full((8, 30), np.nan)          # the ellipsoid fan's memo (its directions share one fan)
    memo_n = np.zeros(1, dtype=np.int64)
    for n in range(n_rows):
        for e in range(max(n_dirs[n], 1)):
            has_d = e < n_dirs[n]
            for k in range(n_nodes):        # the defined points, tangent points absent (NaN)
                for i in range(3):
                    if k < n_points:
                        node[k, i] = complex(points[n, k, i], STEP * d_points[n, k, e, i] if has_d else 0.0)
                    else:
                        node[k, i] = complex(np.nan, 0.0)
                    seen[k, i] = node[k, i]
                ok[k] = k < n_points
                order[k] = -1
            for w in range(n_wraps):
                arc[w] = 0j
                wrap_order[w] = w
                for i in range(4):
                    for j in range(4):
                        frames[w, i, j] = complex(wtf[w, n, i, j], STEP * wdtf[w, n, e, i, j] if has_d else 0.0)
            c = 0
            for k in range(n_points):
                if active[n, k]:
                    order[c] = k
                    c += 1
            last = np.inf
            for kk in range(1 if n_wraps < 2 else 8):
                if n_wraps == 0:
                    break
                for i in range(n_wraps):
                    result[i] = _NO
                for i in range(n_wraps):
                    w = wrap_order[i]
                    _remove(order, n_points + 2 * w, n_points + 2 * w + 1)
                    if wactive[w]:
                        result[i] = _wrap_one(n, w, active, frames[w], wstart, wend, wkind, wparam, waxis, wsign,
                                              wadjust, wmethod, order, node, seen, ok, arc, memo, memo_n)
                length = _path_length(order, node, seen, ok, arc, n_points)
                if abs(length.real - last) < _CONVERGED:
                    break
                last = length.real
                if kk == 0 and n_wraps > 1 and result[0] == _NO and result[1] == _INSIDE:
                    wrap_order[0], wrap_order[1] = wrap_order[1], wrap_order[0]
                    _remove(order, n_points, n_points + 1)    # OpenSim removes wrap object 0's points
            length = _path_length(order, node, seen, ok, arc, n_points)
            if has_d:
                out_dlength[n, e] = length.imag / STEP
        out_length[n] = length.real
        for w in range(n_wraps):
            out_arc[n, w] = arc[w].real
        for k in range(n_nodes):
            out_order[n, k] = order[k]
            for i in range(3):
                out_seen[n, k, i] = seen[k, i].real
                out_node[n, k, i] = node[k, i].real


def wrap_compiled_rows(points, active, d_points, n_dirs, slots, all_kinds=None) -> tuple:
    """applyWrapObjects on N independent rows (see the module docstring), compiled.

    Parameters
    ----------
    points : (N, P, 3) float; active : (N, P) bool; d_points : (N, P, D, 3) float
        Defined path points in ground per row (padding points: inactive), and their derivatives
        along D directions (per row any meaning: the algorithm is linear in them).
    n_dirs : (N,) int
        Directions each row needs (its first ``n_dirs`` of D; the others are returned as 0).
    slots : sequence of `motion.wrapping.batch.WrapSlot` in PathWrapSet order.
    all_kinds : bool or None
        Run the kernel compiled for every kind even if all ``slots`` are cylinders (a model
        with other kinds elsewhere then compiles one kernel, not two). None: as ``slots`` need.
        False with a slot that is no cylinder is a ValueError.

    Returns
    -------
    length (N,), d_length (N, D), order (N, P + 2 W) int (the current path as node ids, -1
    padded; nodes ``P + 2 w`` and ``P + 2 w + 1`` are wrap w's tangent points), mask
    (N, P + 2 W) bool, seen (N, P + 2 W, 3) float (node positions as OpenSim reports them),
    arc (N, W) float (the arc over each wrap object of the final path; 0 where it does not wrap),
    latest (N, P + 2 W, 3) float (node positions of the last pass, the ones the arcs join;
    they differ from ``seen`` only where a later pass moved a tangent point).
    """
    n_rows, n_points = np.shape(active)
    n_wraps = len(slots)
    n_d = d_points.shape[2]
    wtf = np.ascontiguousarray(np.stack([s.tf for s in slots]) if slots else np.zeros((0, n_rows, 4, 4)))
    wdtf = np.ascontiguousarray(np.stack([s.dtf for s in slots]) if slots else np.zeros((0, n_rows, n_d, 4, 4)))
    wstart = np.array([s.start for s in slots], dtype=np.int64).reshape(n_wraps, n_rows)
    wend = np.array([s.end for s in slots], dtype=np.int64).reshape(n_wraps, n_rows)
    wparam = np.array([np.broadcast_to(s.params, (n_rows, 3)) for s in slots], dtype=float).reshape(n_wraps, n_rows, 3)
    wkind = np.array([s.kind for s in slots], dtype=np.int64)
    cylinders = bool(np.all(wkind == CYLINDER))
    if all_kinds is None:
        all_kinds = not cylinders
    if not all_kinds:
        if not cylinders:
            raise ValueError("all_kinds=False but a wrap object is no cylinder")
        wkind = None                        # the kernel compiled for cylinders only
    waxis = np.array([s.axis for s in slots], dtype=np.int64)
    wsign = np.array([s.sign for s in slots], dtype=np.int64)
    wadjust = np.array([s.adjust for s in slots], dtype=np.bool_)
    wmethod = np.array([s.method for s in slots], dtype=np.int64)
    wactive = np.array([s.active for s in slots], dtype=np.bool_)
    n_nodes = n_points + 2 * n_wraps
    length = np.empty(n_rows)
    d_length = np.zeros((n_rows, n_d))
    order = np.empty((n_rows, n_nodes), dtype=np.int64)
    seen = np.empty((n_rows, n_nodes, 3))
    latest = np.empty((n_rows, n_nodes, 3))
    arc = np.empty((n_rows, n_wraps))
    _rows_kernel(np.ascontiguousarray(points, dtype=float), np.ascontiguousarray(active, dtype=np.bool_),
                 np.ascontiguousarray(d_points, dtype=float), np.asarray(n_dirs, dtype=np.int64), wtf, wdtf, wstart,
                 wend, wkind, wparam, waxis, wsign, wadjust, wmethod, wactive, length, d_length, order, seen, latest,
                 arc)
    mask = np.zeros((n_rows, n_nodes), dtype=bool)
    rows, cols = np.nonzero(order >= 0)
    mask[rows, order[rows, cols]] = True
    return length, d_length, order, mask, seen, np.where(mask[:, n_points::2], arc, 0.0), latest
