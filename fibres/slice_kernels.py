"""Compiled loops of `fibres.slicing.slice_mesh` (the planar sections of Kohout et al.,
GRAPP 2012, §3.3).

Each gives the integers and does the arithmetic of the array version it replaces
(`fibres.slicing._crossings_numpy`, the lexsort of `fibres.slicing._loop_order`, the
gathers at the end of `fibres.slicing.slice_mesh`), so the sections are the same bit for
bit; `_slice_pass` runs the three in one call (no arrays handed back and forth).
"""
from __future__ import annotations

import numpy as np

__all__ = []


def _crossings_loop(d, faces, neighbours, h):  # pragma: no cover - compiled by numba
    n_t = faces.shape[0]
    n_s = h.size
    fs0 = np.empty(n_t, dtype=np.int64)
    n_f = np.empty(n_t, dtype=np.int64)
    pair_start = np.zeros(n_t, dtype=np.int64)
    total = 0
    # first plane at or above each vertex (binary search: ``searchsorted(h, x, side="left")``);
    # that is monotone in x, so a face's first plane at or above its lowest / highest vertex
    # is the min / max over its corners
    first = np.empty(d.size, dtype=np.int64)
    for i in range(d.size):
        x = d[i]
        lo, hi = 0, n_s
        while lo < hi:
            mid = (lo + hi) // 2
            if h[mid] < x:
                lo = mid + 1
            else:
                hi = mid
        first[i] = lo
    for f in range(n_t):
        a0, a1, a2 = first[faces[f, 0]], first[faces[f, 1]], first[faces[f, 2]]
        s0 = min(min(a0, a1), a2)
        lo = max(max(a0, a1), a2)
        fs0[f] = s0
        n = lo - s0
        n_f[f] = n
        if n > 0:
            pair_start[f] = total
            total += n
    node_face = np.empty(total, dtype=np.int64)
    node_slice = np.empty(total, dtype=np.int64)
    down = np.empty(total, dtype=np.int64)
    nxt = np.empty(total, dtype=np.int64)
    above = np.empty(3, dtype=np.bool_)
    for f in range(n_t):
        for q in range(n_f[f]):
            node = pair_start[f] + q
            s = fs0[f] + q
            node_face[node] = f
            node_slice[node] = s
            for k in range(3):
                above[k] = d[faces[f, k]] > h[s]
            dn = 0                          # first k: k above, k+1 below (argmax rule)
            for k in range(3):
                if above[k] and not above[(k + 1) % 3]:
                    dn = k
                    break
            up = 0                          # first k: k below, k+1 above
            for k in range(3):
                if not above[k] and above[(k + 1) % 3]:
                    up = k
                    break
            down[node] = dn
            nbr = neighbours[f, up]
            nxt[node] = pair_start[nbr] + s - fs0[nbr]
    return node_face, node_slice, down, nxt


def _loop_order_loop(nxt, node_slice, n_s):  # pragma: no cover - compiled by numba
    n = nxt.size
    seen = np.zeros(n, dtype=np.bool_)
    walk = np.empty(n, dtype=np.int64)
    cyc_start = np.empty(n + 1, dtype=np.int64)
    n_cyc = 0
    k = 0
    for start in range(n):
        if seen[start]:
            continue
        cyc_start[n_cyc] = k
        n_cyc += 1
        node = start
        while not seen[node]:
            seen[node] = True
            walk[k] = node
            k += 1
            node = nxt[node]
    cyc_start[n_cyc] = n
    # stable bucketing of the loops by plane
    count = np.zeros(n_s + 1, dtype=np.int64)
    for c in range(n_cyc):
        count[node_slice[walk[cyc_start[c]]] + 1] += cyc_start[c + 1] - cyc_start[c]
    for s in range(n_s):
        count[s + 1] += count[s]
    order = np.empty(n, dtype=np.int64)
    first = np.empty(n_cyc, dtype=np.int64)
    for c in range(n_cyc):
        s = node_slice[walk[cyc_start[c]]]
        first[c] = count[s]
        for i in range(cyc_start[c], cyc_start[c + 1]):
            order[count[s]] = walk[i]
            count[s] += 1
    loop_start = np.empty(n_cyc + 1, dtype=np.int64)
    loop_start[:n_cyc] = np.sort(first)
    loop_start[n_cyc] = n
    return order, loop_start


def _points_loop(order, node_face, node_slice, down, faces, face_edges, local_t,
                 h):  # pragma: no cover - compiled by numba
    """The section points of `slice_mesh` in loop order: (points (Q, 2), edge (Q,), t (Q,),
    plane (Q,)) -- the array version's gathers and formulas, node by node."""
    n = order.size
    pts = np.empty((n, 2))
    edge = np.empty(n, dtype=np.int64)
    t_out = np.empty(n)
    plane = np.empty(n, dtype=np.int64)
    for q in range(n):
        node = order[q]
        f = node_face[node]
        s = node_slice[node]
        dn = down[node]
        a = faces[f, dn]                                    # above end of the edge
        b = faces[f, dn + 1 if dn < 2 else 0]              # below end
        da = local_t[2, a]
        t = (h[s] - da) / (local_t[2, b] - da)
        ua, va = local_t[0, a], local_t[1, a]
        pts[q, 0] = ua + t * (local_t[0, b] - ua)
        pts[q, 1] = va + t * (local_t[1, b] - va)
        t_out[q] = 1.0 - t if a > b else t                  # t measured from edges[:, 0]
        edge[q] = face_edges[f, dn]
        plane[q] = s
    return pts, edge, t_out, plane


def _slice_pass(d, faces, neighbours, face_edges, local_t,
                h):  # pragma: no cover - compiled by numba
    """`_crossings_loop`, `_loop_order_loop` and `_points_loop` in one call: the section
    points (K, 2), their edges (K,) and edge parameters (K,) in loop order, the loop
    starts (L + 1,) and each loop's plane (L,)."""
    node_face, node_slice, down, nxt = _crossings_loop(d, faces, neighbours, h)
    order, loop_start = _loop_order_loop(nxt, node_slice, h.size)
    pts, edge, t, plane = _points_loop(order, node_face, node_slice, down, faces, face_edges,
                                       local_t, h)
    n_loops = loop_start.size - 1
    loop_slice = np.empty(n_loops, dtype=np.int64)
    for k in range(n_loops):
        loop_slice[k] = plane[loop_start[k]]
    return pts, edge, t, loop_start, loop_slice


_KERNELS = []


def kernels():
    """(`_crossings_loop`, `_loop_order_loop`, `_points_loop`, `_slice_pass`) compiled with
    numba, or None."""
    return None  # numpy (no compiled kernels: docs/decisions.md, issue 13)
