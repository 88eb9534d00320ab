"""Signed distance to a closed triangle surface, soft-blended over the nearest triangles.

For `fibres.containment` (and tests): exact point-triangle distances (Ericson, Real-Time
Collision Detection 2005, §5.1.5, closest point on a triangle by its Voronoi regions), blended
over the nearest triangles with soft-min weights ``w_t = exp(-(d_t - d_min) / tau)``, which
keeps distance and direction continuous where two walls are equally near (the medial surface
of a concave valley, where the single closest triangle jumps from one wall to the other):

- distance ``D = sum w d / sum w``;
- sign of ``sum w (x - c_t) . n_t`` (c_t the closest point of triangle t, n_t its unit outward
  normal): the pseudo-normal test of Baerentzen & Aanaes (IEEE TVCG 11(3), 2005) with unit
  face weights -- at an edge or a vertex all faces sharing it tie and vote together;
- outward direction ``n = normalise(sign sum w (x - c_t) + tau sum w n_t)`` (the shortest
  path's direction, the face normal for a point on the surface).

Weights fade to exactly 0 between ``delta = (KAPPA - 1) tau`` and ``KAPPA tau`` (smoothstep),
so only triangles within ``d_min + KAPPA tau`` count.

Search. Triangles are binned in a uniform grid by their bounding boxes (cells ~1.5 mean edges,
at least reach / 8, at most ~1 cell per 2 triangles, one empty layer all round); empty cells
are labelled inside or outside: those face-connected to the border through empty cells are
outside, and every other face-connected component of empty cells takes the side of its first
cell's centre, by ray parity to the grid's border (the segment between the centres of two
face-adjacent empty cells would cross the surface inside one of them, so a component is all
inside or all outside; outside pockets enclosed by surface cells exist in narrow folds). With ``watch`` below `reach`
(`fibres.containment`: only points outside or within a thin band inside matter) a point in a
surface cell is classified by ray parity first (`_column_inside`); an inside one looks for
triangles within ``watch`` only (``watch = 0``: not at all, ``s = -inf``). A point in an empty
inside cell is inside; if no surface cell touches its cell it is deeper than one cell
(``s = -inf``; so ``watch`` must not exceed the cell size), otherwise it looks for triangles
within ``watch`` only. An inside point with no triangle within ``watch`` gets ``s = -inf``;
one with a triangle within ``watch`` (< `reach`) looks again within ``d_min + KAPPA tau``
(every triangle of its blend);
one with a distance gets the negative sign whatever the blend's vote (not with ``offset``:
`SurfaceGrid.signed_distance`, whose signed normal offset is signed by itself). Other points visit rings of cells
around their own until the ring's distance exceeds the current bound ``min(d_min + KAPPA tau,
reach)``, skipping empty cells, far cells (whole slabs and rows of the ring when one
coordinate alone is too far) and triangles too far by a lower bound (the distance
to the triangle's plane and, within it, to its bounding circle). Compiled with numba; the numpy
fallback tests every triangle (the same formulas; equal where both report a distance).
"""
from __future__ import annotations

import numpy as np

from .grid_kernels import (_bounds_loop, _edge_loop, _flood, _grid_loop, _label_loop, _put,
                           _shapes_loop, _triangle_shape)

__all__ = ["SurfaceGrid", "surface_distance", "KAPPA"]

#: triangles farther than d_min + KAPPA tau get no weight in the blend
KAPPA = 8.0
#: ``offset`` mode: the normal offset within OFFSET_NEAR tau of the surface, the signed
#: distance beyond OFFSET_FAR tau, smoothstep between (the blend's vote, which signs the
#: distance, and the exact inside test disagree only within ~0.9 tau: tests)
OFFSET_NEAR, OFFSET_FAR = 2.0, 4.0
#: grid cell size in mean edge lengths
CELL_EDGES = 1.5

#: queries of at most this many points make only the triangle shapes they visit
_LAZY_POINTS = 2

_KERNELS = []


def _kernels():
    """Compiled kernels (numba) as a dict, or None (then numpy)."""
    if not _KERNELS:
        try:
            import numba
        except ImportError:                                     # pragma: no cover - optional
            _KERNELS.append(None)
        else:
            import types

            jit = numba.njit(cache=True, nogil=True)
            # the query calls the compiled helpers: numba resolves globals at compile time
            inline = numba.njit(inline="always", nogil=True)
            glb = dict(globals(), _closest_point=jit(_closest_point), _unit=inline(_unit),
                       _flood=jit(_flood), _triangle_shape=inline(_triangle_shape),
                       _put=inline(_put))
            glb["_blend"] = jit(types.FunctionType(_blend.__code__, glb, "_blend"))
            glb["_shape"] = inline(types.FunctionType(_shape.__code__, glb, "_shape"))
            glb["_shapes"] = jit(types.FunctionType(_shapes_loop.__code__, glb, "_shapes_loop"))
            glb["_owns"] = jit(_owns)
            glb["_crossings"] = jit(types.FunctionType(_crossings.__code__, glb, "_crossings"))
            glb["_column_inside"] = jit(types.FunctionType(_column_inside.__code__, glb,
                                                           "_column_inside"))

            def bound(fn):
                return jit(types.FunctionType(fn.__code__, glb, fn.__name__))

            _KERNELS.append({"edges": jit(_edge_loop), "grid": bound(_grid_loop),
                             "label": bound(_label_loop), "query": bound(_query_loop),
                             "reps": bound(_reps_inside),
                             "bounds": jit(_bounds_loop)})
    return _KERNELS[0]


def _closest_point(ax, ay, az, bx, by, bz, cx, cy, cz, px, py, pz):
    """Closest point of triangle (a, b, c) to p (Ericson 2005, §5.1.5), scalar."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return ax + v * abx, ay + v * aby, az + v * abz
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz)
    den = 1.0 / (va + vb + vc)
    v, w = vb * den, vc * den
    return (ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w)


def _shape(t, v, faces, nrm, centre, radius, ready):  # pragma: no cover - compiled by numba
    """`_triangle_shape` of triangle t on its first use by a distance search (``ready[t]``):
    the inside tests never need the shapes."""
    if ready[t]:
        return
    ready[t] = 1
    _triangle_shape(t, v, faces, nrm, centre, radius)


def _owns(w, ex, ey):  # pragma: no cover - compiled by numba
    """Whether a point with edge function w counts as inside that (counter-clockwise) edge:
    w > 0, or on it and the edge is a "top-left" one (each shared edge counted once)."""
    return w > 0.0 or (w == 0.0 and (ey > 0.0 or (ey == 0.0 and ex < 0.0)))


def _crossings(px, py, pz, ci, cj, ck, axis, sgn, n_cells, end, v, faces, start, items,
               dims, stamp, p):  # pragma: no cover - compiled by numba
    """Whether the segment from the point along axis direction ``sgn`` to the coordinate
    ``end`` crosses the surface an odd number of times: it counts the triangles binned in the
    ``n_cells`` cells it passes from the point's cell (ci, cj, ck) on; every triangle it can
    cross has its bounding box, so is binned, there. Ties on shared edges are counted once (a
    top-left rule in the projection); triangles parallel to it graze it (not counted)."""
    ny, nz = dims[1], dims[2]
    pos = (px, py, pz)
    u, w = (axis + 1) % 3, (axis + 2) % 3
    pu, pw, pa = pos[u], pos[w], pos[axis]
    odd = False
    for m in range(n_cells):
        i = ci + sgn * m if axis == 0 else ci
        j = cj + sgn * m if axis == 1 else cj
        k = ck + sgn * m if axis == 2 else ck
        q = (i * ny + j) * nz + k
        for e in range(start[q], start[q + 1]):
            t = items[e]
            if n_cells > 1:   # (in one cell each triangle comes once)
                if stamp[t] == p:
                    continue
                stamp[t] = p
            a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
            au, aw, bu, bw, cu, cw = v[a, u], v[a, w], v[b, u], v[b, w], v[c, u], v[c, w]
            d = (bu - au) * (cw - aw) - (bw - aw) * (cu - au)
            if d == 0.0:
                continue                             # parallel to the ray: it grazes it
            w0 = (bu - pu) * (cw - pw) - (bw - pw) * (cu - pu)
            w1 = (cu - pu) * (aw - pw) - (cw - pw) * (au - pu)
            w2 = (au - pu) * (bw - pw) - (aw - pw) * (bu - pu)
            sg = 1.0 if d > 0.0 else -1.0
            if not (_owns(sg * w0, sg * (cu - bu), sg * (cw - bw))
                    and _owns(sg * w1, sg * (au - cu), sg * (aw - cw))
                    and _owns(sg * w2, sg * (bu - au), sg * (bw - aw))):
                continue
            h = (w0 * v[a, axis] + w1 * v[b, axis] + w2 * v[c, axis]) / d
            if (sgn > 0 and pa < h <= end) or (sgn < 0 and end <= h < pa):
                odd = not odd
    return odd


def _column_inside(px, py, pz, ci, cj, ck, v, faces, start, items, label, dims, lo, cell,
                   stamp, p):  # pragma: no cover - compiled by numba
    """Inside test of a point in a surface cell by ray parity: along the axis direction
    (+-x, +-y, +-z) whose first labelled empty cell is nearest, the segment from the point to
    that cell's centre plane crosses the surface an even number of times iff both ends are on
    the same side (`_crossings`; a crossing in the empty cell would have put a triangle
    there)."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    cc = (ci, cj, ck)
    best, axis, sgn = 1 << 30, 2, 1
    for ax in range(3):
        for sg in (-1, 1):
            n_steps = 1
            while n_steps < best:
                i = ci + sg * n_steps if ax == 0 else ci
                j = cj + sg * n_steps if ax == 1 else cj
                k = ck + sg * n_steps if ax == 2 else ck
                if label[(i * ny + j) * nz + k] != 1:   # the border layer is empty
                    break
                n_steps += 1
            if n_steps < best:
                best, axis, sgn = n_steps, ax, sg
    end = lo[axis] + (cc[axis] + sgn * best + 0.5) * cell
    odd = _crossings(px, py, pz, ci, cj, ck, axis, sgn, best, end, v, faces, start, items,
                     dims, stamp, p)
    i = ci + sgn * best if axis == 0 else ci
    j = cj + sgn * best if axis == 1 else cj
    k = ck + sgn * best if axis == 2 else ck
    return odd == (label[(i * ny + j) * nz + k] == 2)   # inside: outside end and odd


def _reps_inside(reps, v, faces, start, items, dims, lo, cell, label,
                 comp):  # pragma: no cover - numba
    """Inside test of the centres of the cells ``reps`` (flat indices) by ray parity along
    +x to the grid's (empty, outside) border layer (`_crossings`); each cell of component
    ``comp`` then labelled 3 (inside) or 2 (outside) in place. Returns the tests (R,)."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    stamp = np.full(faces.shape[0], -1, np.int32)
    out = np.zeros(reps.shape[0], np.bool_)
    for r in range(reps.shape[0]):
        q = reps[r]
        ci, rest = q // (ny * nz), q % (ny * nz)
        cj, ck = rest // nz, rest % nz
        px = lo[0] + (ci + 0.5) * cell
        py = lo[1] + (cj + 0.5) * cell
        pz = lo[2] + (ck + 0.5) * cell
        out[r] = _crossings(px, py, pz, ci, cj, ck, 0, 1, nx - ci, lo[0] + nx * cell, v,
                            faces, start, items, dims, stamp, r)
    for q in range(comp.shape[0]):
        if comp[q] >= 0:
            label[q] = 3 if out[comp[q]] else 2
    return out


def _query_loop(points, v, faces, nrm, centre, radius, ready, lazy, lo, cell, dims, start,
                items, label, labelled, reach, watch, tau, kappa, offset, out_s,
                out_n):  # pragma: no cover - numba
    """The grid search of the module docstring, then `_blend`, for every point. The
    triangles' shapes (`_shape`; ``ready`` (T + 1,): per triangle, then all) are made when
    the first point needs a distance search: all at once, or with ``lazy`` (few points)
    only those the searches visit."""
    n_tri = faces.shape[0]
    nx, ny, nz = dims[0], dims[1], dims[2]
    # made on first need: per triangle the last search that met it (p, -2 - p: the two
    # passes of point p's search; n + p: its parity test)
    stamp = np.full(0, -1, np.int32)
    n_pts = points.shape[0]
    cap = 4096
    bd, bx, by, bz = np.empty(cap), np.empty(cap), np.empty(cap), np.empty(cap)
    bt = np.empty(cap, np.int64)
    keep = kappa * tau
    for p in range(points.shape[0]):
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        ci = int(np.floor((px - lo[0]) / cell))
        cj = int(np.floor((py - lo[1]) / cell))
        ck = int(np.floor((pz - lo[2]) / cell))
        lim = reach
        enclosed = False
        if 0 <= ci < nx and 0 <= cj < ny and 0 <= ck < nz:
            q = (ci * ny + cj) * nz + ck
            if labelled and label[q] == 3:       # an enclosed empty cell: inside
                enclosed = True
                lim = watch
                deep = watch <= 0.0  # no surface cell around: deeper than one cell
                if not deep:
                    deep = True
                    for di in range(-1, 2):
                        for dj in range(-1, 2):
                            for dk in range(-1, 2):
                                if label[((ci + di) * ny + cj + dj) * nz + ck + dk] == 1:
                                    deep = False
                if deep:
                    out_s[p] = -np.inf
                    out_n[p, 0] = out_n[p, 1] = out_n[p, 2] = 0.0
                    continue
            elif labelled and watch < reach and label[q] == 1:
                if stamp.shape[0] == 0:
                    stamp = np.full(n_tri, -1, np.int32)
                if _column_inside(px, py, pz, ci, cj, ck, v, faces, start, items, label,
                                  dims, lo, cell, stamp, n_pts + p):
                    if watch <= 0.0:
                        out_s[p] = -np.inf      # inside (ray parity): no distance wanted
                        out_n[p, 0] = out_n[p, 1] = out_n[p, 2] = 0.0
                        continue
                    enclosed = True             # inside: look within `watch` only
                    lim = watch
        # an inside point that looks within a short `watch` only: triangles rejected by
        # their vertex box, shapes made only for those found within it (few points of a
        # band need them, and making every shape costs more than the whole search)
        narrow = enclosed and watch < reach
        if 0 <= ci < nx and 0 <= cj < ny and 0 <= ck < nz and not narrow:
            if not lazy and ready[n_tri] == 0:   # a distance search: every shape, once
                _shapes(v, faces, nrm, centre, radius)
                ready[:] = 1
            seed, near = -1, np.inf   # seed the bound: the own cell's nearest centroid's
            for e in range(start[q], start[q + 1]):   # triangle, measured exactly
                t = items[e]
                if lazy and ready[t] == 0:
                    _shape(t, v, faces, nrm, centre, radius, ready)
                ex, ey, ez = px - centre[t, 0], py - centre[t, 1], pz - centre[t, 2]
                e2 = ex * ex + ey * ey + ez * ez
                if e2 < near:
                    seed, near = t, e2
            if seed >= 0:
                a, b, c = faces[seed, 0], faces[seed, 1], faces[seed, 2]
                qx, qy, qz = _closest_point(v[a, 0], v[a, 1], v[a, 2], v[b, 0], v[b, 1],
                                            v[b, 2], v[c, 0], v[c, 1], v[c, 2], px, py, pz)
                dx, dy, dz = px - qx, py - qy, pz - qz
                lim = min(lim, np.sqrt(dx * dx + dy * dy + dz * dz) + keep)
        if not lazy and not narrow and ready[n_tri] == 0:   # (a point beyond the grid's box)
            _shapes(v, faces, nrm, centre, radius)
            ready[:] = 1
        if stamp.shape[0] == 0:
            stamp = np.full(n_tri, -1, np.int32)
        lim0 = lim
        # a narrow search whose point is farther than lim from its cell's six neighbours
        # (by the ring's own gap tests, which prune their slabs and rows) visits no cell of
        # ring 1: it skips the ring at once
        skip1 = narrow
        if narrow:
            for dd in range(-1, 3, 2):
                gx = max(lo[0] + (ci + dd) * cell - px, px - lo[0] - (ci + dd + 1) * cell, 0.0)
                gy = max(lo[1] + (cj + dd) * cell - py, py - lo[1] - (cj + dd + 1) * cell, 0.0)
                gz = max(lo[2] + (ck + dd) * cell - pz, pz - lo[2] - (ck + dd + 1) * cell, 0.0)
                if not (gx * gx > lim * lim and gy * gy > lim * lim and gz * gz > lim * lim):
                    skip1 = False
        for attempt in range(2):  # inside points: a second pass when one within watch
            mark = p if attempt == 0 else -2 - p  # (a fresh stamp for the pass)
            best = np.inf
            nb = 0
            r = 0
            while (r - 1) * cell <= lim:
                if r == 1 and skip1 and attempt == 0:
                    r = 2
                    continue
                for di in range(-r, r + 1):
                    i = ci + di
                    if i < 0 or i >= nx:
                        continue
                    gx = max(lo[0] + i * cell - px, px - lo[0] - (i + 1) * cell, 0.0)
                    if gx * gx > lim * lim:   # every cell of this slab is too far
                        continue
                    for dj in range(-r, r + 1):
                        j = cj + dj
                        if j < 0 or j >= ny:
                            continue
                        gy = max(lo[1] + j * cell - py, py - lo[1] - (j + 1) * cell, 0.0)
                        if gy * gy > lim * lim:   # every cell of this row is too far
                            continue
                        step = 1 if (abs(di) == r or abs(dj) == r or r == 0) else 2 * r
                        for k in range(ck - r, ck + r + 1, step):
                            if k < 0 or k >= nz:
                                continue
                            q = (i * ny + j) * nz + k
                            if start[q] == start[q + 1]:
                                continue
                            gz = max(lo[2] + k * cell - pz, pz - lo[2] - (k + 1) * cell, 0.0)
                            if gx * gx + gy * gy + gz * gz > lim * lim:
                                continue
                            for e in range(start[q], start[q + 1]):
                                t = items[e]
                                if stamp[t] == mark:
                                    continue
                                stamp[t] = mark
                                a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
                                if narrow:   # lower bound: the vertex box
                                    if (min(v[a, 0], v[b, 0], v[c, 0]) > px + lim
                                            or max(v[a, 0], v[b, 0], v[c, 0]) < px - lim
                                            or min(v[a, 1], v[b, 1], v[c, 1]) > py + lim
                                            or max(v[a, 1], v[b, 1], v[c, 1]) < py - lim
                                            or min(v[a, 2], v[b, 2], v[c, 2]) > pz + lim
                                            or max(v[a, 2], v[b, 2], v[c, 2]) < pz - lim):
                                        continue
                                else:
                                    if lazy and ready[t] == 0:
                                        _shape(t, v, faces, nrm, centre, radius, ready)
                                    # lower bound: the plane distance h and the in-plane
                                    # distance beyond the bounding circle (centre in the
                                    # plane, radius r)
                                    ex = px - centre[t, 0]
                                    ey = py - centre[t, 1]
                                    ez = pz - centre[t, 2]
                                    e2 = ex * ex + ey * ey + ez * ez
                                    h = ex * nrm[t, 0] + ey * nrm[t, 1] + ez * nrm[t, 2]
                                    w = max(np.sqrt(max(e2 - h * h, 0.0)) - radius[t], 0.0)
                                    if h * h + w * w > lim * lim:
                                        continue
                                qx, qy, qz = _closest_point(v[a, 0], v[a, 1], v[a, 2], v[b, 0],
                                                            v[b, 1], v[b, 2], v[c, 0], v[c, 1],
                                                            v[c, 2], px, py, pz)
                                dx, dy, dz = px - qx, py - qy, pz - qz
                                d = np.sqrt(dx * dx + dy * dy + dz * dz)
                                if d > lim:
                                    continue
                                if narrow and ready[t] == 0:     # its normal, for the blend
                                    _shape(t, v, faces, nrm, centre, radius, ready)
                                if nb == cap:  # drop what can no longer count
                                    m = 0
                                    for u in range(nb):
                                        if bd[u] <= best + keep:
                                            bd[m], bx[m], by[m], bz[m], bt[m] = \
                                                bd[u], bx[u], by[u], bz[u], bt[u]
                                            m += 1
                                    nb = m
                                    if nb == cap:
                                        raise ValueError("more than 4096 triangles tie")
                                bd[nb], bx[nb], by[nb], bz[nb], bt[nb] = d, dx, dy, dz, t
                                nb += 1
                                if d < best:
                                    best = d
                                    lim = min(best + keep, lim)
                r += 1
            # the first pass of an inside point looked within `watch` only; a point
            # found nearer needs every triangle within best + KAPPA tau of the blend
            if not (enclosed and watch < reach and best < lim0 < best + keep):
                break
            lim = best + keep
        if nb == 0:   # no triangle: `_blend`'s empty blend, without the call
            out_s[p] = -np.inf
            out_n[p, 0] = out_n[p, 1] = out_n[p, 2] = 0.0
            continue
        _blend(bd, bx, by, bz, bt, nb, best, nrm, tau, kappa, out_s, out_n, p, offset)
        if enclosed and not offset and np.isfinite(out_s[p]):
            out_s[p] = -abs(out_s[p])


def _unit(x, y, z):  # pragma: no cover - compiled by numba (inlined)
    """(x, y, z) scaled to unit length (unchanged if zero)."""
    g = np.sqrt(x * x + y * y + z * z)
    if g > 0.0:
        return x / g, y / g, z / g
    return x, y, z


def _blend(bd, bx, by, bz, bt, nb, best, nrm, tau, kappa, out_s, out_n, p,
           offset):  # pragma: no cover
    """Soft-min blend (module docstring) of buffered triangles into out_s[p], out_n[p]:
    distances bd, point minus closest point (bx, by, bz), normal rows bt of nrm; with
    ``offset`` the blended normal offset and face normal near the surface instead
    (`SurfaceGrid.signed_distance`)."""
    sw = sd = vx = vy = vz = nx = ny = nz = sg = 0.0
    for u in range(nb):
        delta = bd[u] - best
        if delta > kappa * tau:
            continue
        w = np.exp(-delta / tau)
        f = (kappa * tau - delta) / tau
        if f < 1.0:
            w *= f * f * (3.0 - 2.0 * f)
        t = bt[u]
        sw += w
        sd += w * bd[u]
        vx += w * bx[u]
        vy += w * by[u]
        vz += w * bz[u]
        nx += w * nrm[t, 0]
        ny += w * nrm[t, 1]
        nz += w * nrm[t, 2]
        sg += w * (bx[u] * nrm[t, 0] + by[u] * nrm[t, 1] + bz[u] * nrm[t, 2])
    if sw == 0.0:
        out_s[p] = -np.inf
        out_n[p, 0] = out_n[p, 1] = out_n[p, 2] = 0.0
        return
    sign = 1.0 if sg > 0.0 else (-1.0 if sg < 0.0 else 0.0)
    dist = sd / sw
    gx = (sign * vx + tau * nx) / sw
    gy = (sign * vy + tau * ny) / sw
    gz = (sign * vz + tau * nz) / sw
    gx, gy, gz = _unit(gx, gy, gz)
    if offset:  # near the surface the normal offset and normal, far out the distance
        lam = min(max((dist - OFFSET_NEAR * tau) / ((OFFSET_FAR - OFFSET_NEAR) * tau), 0.0),
                  1.0)
        lam = lam * lam * (3.0 - 2.0 * lam)
        nx, ny, nz = _unit(nx, ny, nz)
        out_s[p] = (1.0 - lam) * sg / sw + lam * sign * dist
        gx, gy, gz = _unit((1.0 - lam) * nx + lam * gx, (1.0 - lam) * ny + lam * gy,
                           (1.0 - lam) * nz + lam * gz)
    else:
        out_s[p] = sign * dist
    out_n[p, 0], out_n[p, 1], out_n[p, 2] = gx, gy, gz


def _closest_points(tri, p):
    """Closest points (..., 3) of triangles tri (..., 3, 3) to points p (..., 3), broadcast:
    the cases of `_closest_point` in the same order (np.select keeps the first true case)."""
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c

    def dot(x, y):
        return x[..., 0] * y[..., 0] + x[..., 1] * y[..., 1] + x[..., 2] * y[..., 2]

    d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), dot(ab, cp), \
        dot(ac, cp)
    vc, vb, va = d1 * d4 - d3 * d2, d5 * d2 - d1 * d6, d3 * d6 - d5 * d4
    with np.errstate(divide="ignore", invalid="ignore"):
        v_ab = d1 / (d1 - d3)
        w_ac = d2 / (d2 - d6)
        w_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        den = 1.0 / (va + vb + vc)
        inner = a + ab * (vb * den)[..., None] + ac * (vc * den)[..., None]
        picks = [a, b, a + v_ab[..., None] * ab, c, a + w_ac[..., None] * ac,
                 b + w_bc[..., None] * (c - b)]
    cases = [(d1 <= 0) & (d2 <= 0), (d3 >= 0) & (d4 <= d3),
             (vc <= 0) & (d1 >= 0) & (d3 <= 0), (d6 >= 0) & (d5 <= d6),
             (vb <= 0) & (d2 >= 0) & (d6 <= 0), (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)]
    shape = np.broadcast_shapes(a.shape, p.shape)
    return np.select([np.broadcast_to(k[..., None], shape) for k in cases],
                     [np.broadcast_to(x, shape) for x in picks], np.broadcast_to(inner, shape))


def _unit_normals(tri):
    n = np.cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :])
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(length > 0, n / np.where(length > 0, length, 1.0), 0.0)


def _blend_numpy(d, diff, nrm, tau, kappa, offset=False):
    """`_blend` for n points at once: d (n, T) distances (inf: not a candidate), diff
    (n, T, 3) point minus closest point, nrm (n, T, 3) unit normals."""
    best = d.min(axis=1)
    delta = d - np.where(np.isfinite(best), best, 0.0)[:, None]
    use = delta <= kappa * tau
    dl = np.where(use, delta, 0.0)
    f = (kappa * tau - dl) / tau
    w = np.where(use, np.exp(-dl / tau) * np.where(f < 1.0, f * f * (3.0 - 2.0 * f), 1.0), 0.0)
    diff = np.where(use[..., None], diff, 0.0)
    sw = w.sum(axis=1)
    ok = sw > 0
    safe = np.where(ok, sw, 1.0)
    dist = (w * np.where(use, d, 0.0)).sum(axis=1) / safe
    v = np.einsum("nt,ntk->nk", w, diff) / safe[:, None]
    nn = np.einsum("nt,ntk->nk", w, nrm) / safe[:, None]
    vote = np.einsum("nt,ntk,ntk->n", w, diff, nrm)
    sign = np.sign(vote)

    def unit(x):
        norm = np.linalg.norm(x, axis=1, keepdims=True)
        return np.where(norm > 0, x / np.where(norm > 0, norm, 1.0), x)

    g = unit(sign[:, None] * v + tau * nn)
    s = sign * dist
    if offset:
        lam = np.clip((dist - OFFSET_NEAR * tau) / ((OFFSET_FAR - OFFSET_NEAR) * tau), 0, 1)
        lam = lam * lam * (3.0 - 2.0 * lam)
        s = (1.0 - lam) * vote / safe + lam * s
        g = unit((1.0 - lam)[:, None] * unit(nn) + lam[:, None] * g)
    return np.where(ok, s, -np.inf), np.where(ok[:, None], g, 0.0)


class SurfaceGrid:
    """A closed surface prepared for signed-distance queries (module docstring).

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (T, 3) int
        Closed, consistently and outward wound.
    reach : float
        Points with no triangle within this distance get ``s = -inf``.
    cell : float, optional
        Grid cell size (default ``max(CELL_EDGES x mean edge, reach / 8)``); the result does
        not depend on it, only the speed.
    mean_edge : float, optional
        The faces' mean edge length when already known (else measured here).
    labelled : bool
        Label the empty cells inside/outside (module docstring); without the labels every
        point is searched up to `reach` (cheaper to build when few points are queried).
    bounds : ((3,) float, (3,) float), optional
        The vertices' coordinate-wise minimum and maximum when already known.
    """

    def __init__(self, vertices, faces, *, reach: float, cell: float | None = None,
                 labelled: bool = True, mean_edge: float | None = None, bounds=None):
        self.vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.reach = float(reach)
        self.kernels = _kernels()
        v, f = self.vertices, self.faces
        if self.kernels is None:
            self.cell = cell
            return
        if cell is None:
            if mean_edge is None:
                mean_edge = self.kernels["edges"](v, f)
            cell = max(CELL_EDGES * mean_edge, reach / 8.0)
        lo, hi = self.kernels["bounds"](v) if bounds is None else (
            np.asarray(bounds[0], dtype=np.float64), np.asarray(bounds[1], dtype=np.float64))
        # at most ~2 cells per 4 triangles: coarser cells for fine meshes (building the grid
        # costs ~T + cells; with ray parity the searches stay short; measured 60K-vertex
        # bench mesh 14.7 -> 8 ms per contain call, 1K-15K and LHDL within noise)
        cell = max(float(cell), float(np.prod(hi - lo + 3 * cell) / (0.5 * len(f) + 1.0))
                   ** (1 / 3), 1e-12)
        self.cell, self.lo = cell, lo - cell          # one empty (outside) layer all round
        self.dims = np.floor((hi - lo) / cell).astype(np.int64) + 3
        self.start, self.items = self.kernels["grid"](v, f, self.lo, cell, self.dims)
        n_tri = len(f)  # per-triangle shapes, made on first use (`_shape`, `_query_loop`)
        self.nrm, self.centre = np.empty((n_tri, 3)), np.empty((n_tri, 3))
        self.radius, self.ready = np.empty(n_tri), np.zeros(n_tri + 1, np.int8)
        self.labelled, self.label = False, np.zeros(1, np.int8)
        if labelled:
            label, comp, reps = self.kernels["label"](self.start, self.dims)
            if len(reps):  # each enclosed component: inside or out by its first cell's centre
                # (ray parity: the sign of the distance there, a vote of the nearest
                # triangles' normals with unit weights, can be wrong at a mesh vertex; measured
                # on the LHDL psoas bent 10.2 degrees: an inside component labelled outside)
                self.kernels["reps"](reps, v, f, self.start, self.items, self.dims,
                                     self.lo, cell, label, comp)
            self.labelled, self.label = True, label

    def signed_distance(self, points, *, tau: float, watch: float | None = None,
                        offset: bool = False, lazy: bool | None = None):
        """(s (n,), outward direction (n, 3)) of points (n, 3); ``watch``: how far a point
        inside looks (default `reach`; a point in an empty inside cell with no surface cell
        around is deeper than a cell and gets ``-inf`` whatever ``watch``). ``watch < reach``:
        points in surface cells are classified by ray parity up their grid column
        (`_column_inside`) first; ``watch = 0``: only points OUTSIDE get a distance, every
        inside point ``-inf``. The numpy fallback ignores ``watch`` (every point is measured).

        ``offset``: instead of the signed blended distance and the shortest path's
        direction, the blended signed normal offset ``sum w (x - c_t) . n_t / sum w`` and the
        blended face normal ``sum w n_t`` (normalised). Both are continuous everywhere,
        through the surface too, where the signed distance's magnitude stays about tau / 7
        above 0 (the mean over near ties) while its sign flips, and where the signed share of
        ``sum w (x - c_t)`` flips too; on a flat piece of surface the offset is the exact
        signed distance (every coplanar triangle has the same normal offset).

        ``lazy``: make the triangles' shapes (normals, bounding circles) only for the
        triangles the searches visit (default: for at most `_LAZY_POINTS` points), instead
        of all at the first search; cheaper when the searches stay near few triangles."""
        x = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        watch = self.reach if watch is None else float(watch)
        if self.kernels is not None:
            s, n = np.empty(len(x)), np.empty((len(x), 3))
            self.kernels["query"](x, self.vertices, self.faces, self.nrm, self.centre,
                                  self.radius, self.ready,
                                  len(x) <= _LAZY_POINTS if lazy is None else bool(lazy), self.lo,
                                  self.cell, self.dims, self.start, self.items, self.label,
                                  self.labelled, self.reach, watch, float(tau), KAPPA,
                                  bool(offset), s, n)
            return s, n
        return _brute(x, self.vertices, self.faces, self.reach, float(tau), offset=bool(offset))


def _brute(x, vertices, faces, reach, tau, chunk=32, offset=False):
    """The blend over every triangle within ``reach`` (numpy, chunks of points)."""
    tri = vertices[faces]                                                    # (T, 3, 3)
    nrm = _unit_normals(tri)[None]
    s, n = np.empty(len(x)), np.empty((len(x), 3))
    for a in range(0, len(x), chunk):  # chunks of points: (chunk, T) pairs at a time
        diff = x[a:a + chunk, None] - _closest_points(tri[None], x[a:a + chunk, None])
        d = np.sqrt(np.einsum("ntk,ntk->nt", diff, diff))
        d = np.where(d <= reach, d, np.inf)
        s[a:a + chunk], n[a:a + chunk] = _blend_numpy(d, diff, nrm, tau, KAPPA, offset)
    return s, n


def surface_distance(points, vertices, faces, *, reach: float, softness: float):
    """Signed distance of points to a closed surface (positive outside) and the outward
    direction of the shortest path, soft-blended over the nearest triangles (module
    docstring; Ericson 2005 §5.1.5, Baerentzen & Aanaes 2005).

    Parameters
    ----------
    points : (..., 3) float
    vertices : (V, 3) float
    faces : (T, 3) int
        Closed, consistently and outward wound.
    reach : float, keyword-only
        Points with no triangle within this distance get ``-inf`` (taken as inside).
    softness : float, keyword-only
        Soft-min width tau of the blend.

    Returns
    -------
    s : (...) float
        Signed distance (``-inf``: no triangle within `reach`).
    n : (..., 3) float
        Unit outward direction (0 where ``s = -inf``).
    """
    for name, value in (("reach", reach), ("softness", softness)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive number, got {value!r}")
    pts = np.asarray(points, dtype=np.float64)
    s, n = SurfaceGrid(vertices, faces, reach=reach).signed_distance(pts, tau=softness)
    return s.reshape(pts.shape[:-1]), n.reshape(pts.shape)
