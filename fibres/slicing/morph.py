"""Slice-by-slice morphing of the fitted template into the muscle (Kohout et al. 2012, §3.3).

A plane perpendicular to the principal axis cuts the template box in a rectangle and the
muscle surface in a contour; after the rectangle <-> contour correspondence
(`fibres.slicing.correspondence`), a fibre point ``F`` on that plane has mean value coordinates
``lambda`` with respect to the subdivided rectangle ``Q`` (Hormann & Floater 2006) and is
moved to ``sum_i lambda_i P_i`` on the contour.

Slabs instead of one plane per point. The paper cuts "not only all fibre poly-line points
lying on the cutting plane but also those in its close proximity", so that the number of
slices is the resolution, not fibres x resolution. Here the surface is cut at S fixed
heights (fractions of the box height, `slice_fractions`); a point at height ``w`` between
planes ``s`` and ``s+1`` is mapped with both planes' correspondences and the two in-plane
results are blended linearly in ``w``, and the point keeps its own height ``w``. This makes
the result continuous in the point's height (a nearest-plane rule would jump between
planes), exact for points lying on a plane (the parallel template at the default slice
fractions puts every point on a plane, i.e. exactly the paper's sweep), and it costs one
MVC evaluation per point and neighbouring plane (`fibres.slicing.mvc.mvc_map`, all uses in one
call).
Plans. `slice_maps` makes the paper's choices, made continuous (start at the soft closest
contour point to ``Q0``, split points at the perimeter-ratio positions,
`fibres.slicing.correspondence`)
and records them as material points of the surface; `anchored_maps` re-inserts
those points, carried along with a deformed copy, as start and split points, which keeps
the correspondence continuous in the vertex positions (`fibres.plan`).

The two end planes are inset by `END_INSET` of the height (a plane through the extreme
vertex cuts a degenerate section); points beyond them use the end plane's mapping at their
own height, so fibres still reach the ends of the box. On a flat end (a cap) that is exact;
at a pointed end the end points can lie outside the surface by about the size of the end
plane's section, measured ~1e-4 of the muscle length (0.02 mm on a 200 mm spindle) -- the
attachment filter (§3.4, on by default) replaces those ends anyway.
"""
from __future__ import annotations

import numpy as np

from .contours import anchored_loops, bridge_loops, clockwise_contour
from .correspondence import (ARC_GAP, ARC_WINDOW, SOFT_FLOOR, SOFT_SPREAD, anchor_kernel,
                             correspond_continuous, insert_points, rectangle, smooth_split_points,
                             soft_start, split_chain, split_fractions)
from .mvc import mvc_map, planes
from ..plan import rest_geometry, rest_loop_counts
from .planes import MeshTopology, Sections

__all__ = ["END_INSET", "slice_fractions", "slice_maps", "anchored_maps", "morph_local"]

#: Inset of the first and last slicing planes, as a fraction of the box height.
END_INSET = 1e-4


def slice_fractions(resolution: int) -> np.ndarray:
    """Default slicing heights as fractions of the box height: ``resolution + 1`` planes.

    ``linspace(0, 1, resolution + 1)`` with the ends moved inside by `END_INSET`, i.e. one
    plane per point of a fibre of the parallel template (Kohout 2012: "the minimal number
    of slices used is equal to the specified resolution").

    Parameters
    ----------
    resolution : int
        Segments per fibre (R >= 1).

    Returns
    -------
    (S,) float, S = R + 1
    """
    if resolution < 1:
        raise ValueError(f"resolution must be >= 1, got {resolution}")
    f = np.linspace(0.0, 1.0, int(resolution) + 1)
    f[0], f[-1] = END_INSET, 1.0 - END_INSET
    return f


def _clockwise_all(sections: Sections, chosen, topology: MeshTopology, *, anchors=True):
    """The chosen loops, clockwise and concatenated, with each vertex's mesh edge, its
    material anchor (`_vertex_anchors`; zeros without ``anchors``), the contour sizes and
    offsets, and the section index of each vertex."""
    n_s = chosen.size
    lo = sections.loop_start[chosen]
    m = sections.loop_start[chosen + 1] - lo
    offs = np.concatenate([[0], np.cumsum(m)])
    sl = np.repeat(np.arange(n_s), m)
    j = np.arange(offs[-1]) - offs[sl]
    raw = sections.points[lo[sl] + j]
    nx = raw[offs[sl] + (j + 1) % m[sl]]
    flip = np.add.reduceat(raw[:, 0] * nx[:, 1] - nx[:, 0] * raw[:, 1], offs[:-1]) > 0
    idx = np.where(flip[sl], lo[sl] + m[sl] - 1 - j, lo[sl] + j)
    pts = sections.points[idx]
    edge = sections.edge[idx]
    if anchors:
        av, aw = _vertex_anchors(sections, topology, idx)
    else:
        av = np.zeros((idx.size, 4), dtype=np.int64)
        aw = np.zeros((idx.size, 4))
    # (a contour of 3 vertices needs no refinement: the four correspondence points are
    # inserted into it, `_insert_and_subdivide`)
    return pts, edge, av, aw, m, offs, idx


def _vertex_anchors(sections: Sections, topology: MeshTopology, idx):
    """Material anchors of section points ``idx``: their mesh edge's two end vertices and
    weights ``1 - t, t``, padded to 4 (vertices repeated, weights 0)."""
    t = sections.t[idx]
    ends = topology.edges[sections.edge[idx]]
    av = np.concatenate([ends, ends], axis=-1)
    z = np.zeros_like(t)
    return av, np.stack([1.0 - t, t, z, z], axis=-1)


def slice_maps(sections: Sections, chosen, extents, *, topology: MeshTopology):
    """Correspondence of every plane (Kohout 2012 §3.3, continuous rule): contour ``P``,
    subdivided rectangle ``Q``.

    The start ``P0`` is the (soft) closest point of the contour to ``Q0``
    (`fibres.slicing.correspondence.soft_start`) and the split points lie at the arc fractions of
    the rectangle's corners after it, i.e. where the paper's error
    ``sum_j (side_j - k length_j)^2`` vanishes; the four points are inserted into the
    contour as vertices (`fibres.slicing.correspondence.correspond_continuous` per plane; why not
    the paper's vertex snapping: see `fibres.slicing.correspondence`). All planes at once on the
    concatenated contours, step by step on arrays (`_slice_maps_steps`).

    Parameters
    ----------
    sections : Sections
    chosen : (S,) int
        Loop per plane (`fibres.slicing.contours.choose_loops`); -1 where nothing was cut.
    extents : (3,) float
        Box extents; the rectangle is ``[0, ex] x [0, ey]``.
    topology : MeshTopology

    Returns
    -------
    P, Q : tuple of (m_s + 4, 2) float arrays
    choice : (S, 4) int64
        Mesh edge of the contour vertex nearest to each of the four points (start, first
        points of parts 2-4) along its segment.
    anchors : ((S, 4, 4) int64, (S, 4, 4) float)
        The four points as material points of the mesh: vertex indices and weights
        (``X = sum_k w_k V_k``, the two mesh edges' end points of the contour segment
        carrying the point, so ``X`` lies on the section exactly), for `anchored_maps`
        on deformed copies.
    notes : tuple of str
    """
    chosen = np.asarray(chosen, dtype=np.int64)
    if (chosen < 0).any():
        s = int(np.flatnonzero(chosen < 0)[0])
        raise ValueError(f"slice {s} at height {sections.heights[s]:.6g} cuts no contour")
    return _slice_maps_steps(sections, chosen, extents, topology=topology)


def _degenerate(P_all, Q_all, ok, pts, offs, extents):
    """The planes whose inserted points are out of order (a contour of zero length),
    corresponded afresh one by one (`correspond_continuous`)."""
    rect = rectangle(float(extents[0]), float(extents[1]))
    P_all, Q_all = list(P_all), list(Q_all)
    for s in np.flatnonzero(~ok):
        P_all[s], Q_all[s], _, _ = correspond_continuous(pts[offs[s]:offs[s + 1]], rect)
    return tuple(P_all), tuple(Q_all)


def _slice_maps_steps(sections: Sections, chosen, extents, *, topology: MeshTopology):
    """`slice_maps` step by step on arrays."""
    rect = rectangle(float(extents[0]), float(extents[1]))
    pts, edge, _, _, m, offs, idx = _clockwise_all(sections, chosen, topology, anchors=False)
    # start (soft closest point to Q0) and the split points at the perimeter ratios (S, 4)
    seg, tk, point = soft_start(pts, m, offs, rect[0], fractions=split_fractions(rect))
    # ... optionally smoothed along the axis (off by default, `SPLIT_SMOOTHING`; see there)
    seg, tk, point = smooth_split_points(pts, m, offs, seg, tk, point)
    P, Q, offs2, ok = _insert_and_subdivide(pts, m, offs, seg, tk, point, rect)
    P_all, Q_all = planes(P, offs2), planes(Q, offs2)    # views of P, Q (`fibres.slicing.mvc`)
    if not ok.all():                          # cannot happen: the points are in arc order
        P_all, Q_all = _degenerate(P_all, Q_all, ok, pts, offs, extents)
    # material anchors: the point (1 - tau) X_j + tau X_{j+1} on the face between the two
    # contour vertices' mesh edges, each X = (1 - t) V_a + t V_b
    g = offs[:-1, None] + seg
    nx = offs[:-1, None] + (seg + 1) % m[:, None]
    av0, aw0 = _vertex_anchors(sections, topology, idx[g])
    av1, aw1 = _vertex_anchors(sections, topology, idx[nx])
    v = np.concatenate([av0[..., :2], av1[..., :2]], axis=-1)
    w = np.concatenate([(1.0 - tk)[..., None] * aw0[..., :2], tk[..., None] * aw1[..., :2]],
                       axis=-1)
    return P_all, Q_all, edge[np.where(tk < 0.5, g, nx)], (v, w), ()


def _insert_and_subdivide(pts, m, offs, seg, tk, point, rect):
    """Insert the start and split points into the contours, roll each contour to its start
    and subdivide the rectangle like it.

    Parameters
    ----------
    pts : (K, 2) float
        Clockwise contours back to back (``offs`` (S+1,), lengths ``m`` (S,)).
    seg, tk : (S, 4) int, float
        Segment and position along it of the start (column 0) and the split points.
    point : (S, 4, 2) float
    rect : (4, 2) float

    Returns
    -------
    P, Q : (K + 4 S, 2) float
        Back to back, ``P[offs2[s]]`` the start of plane ``s``.
    offs2 : (S + 1,) int64
    ok : (S,) bool
        False where the inserted points are not in start, split order (a contour of zero
        length); those planes' P, Q are placeholders.
    """
    new, index = insert_points(pts, m, offs, seg, tk, point)
    m2 = m + 4
    offs2 = np.concatenate([[0], np.cumsum(m2)])
    start = index[:, 0]
    split = (index[:, 1:] - start[:, None]) % m2[:, None]
    ok = (0 < split[:, 0]) & (split[:, 0] < split[:, 1]) & (split[:, 1] < split[:, 2])
    P, Q, _, _ = _roll_and_subdivide(new, m2, offs2, start, np.where(ok[:, None], split, 1),
                                     rect)
    return P, Q, offs2, ok


def _roll_and_subdivide(pts, m, offs, start, split, rect):
    """Roll each concatenated contour to its start and subdivide the rectangle like it.

    Parameters
    ----------
    pts : (K, 2) float
        Clockwise contours back to back (``offs`` (S+1,), lengths ``m`` (S,)).
    start : (S,) int
        Local index of ``P0`` in each contour.
    split : (S, 3) int or None
        Split of each rolled chain; None: minimise it (`split_chain`, per plane).
    rect : (4, 2) float

    Returns
    -------
    P, Q : (K, 2) float
        Rolled contours and subdivided rectangles, back to back.
    roll : (K,) int
        ``P = pts[roll]``.
    split : (S, 3) int64
    """
    n_s = m.size
    sl = np.repeat(np.arange(n_s), m)
    j = np.arange(offs[-1]) - offs[sl]
    roll = offs[sl] + (start[sl] + j) % m[sl]
    P = pts[roll]
    nxt = offs[sl] + (j + 1) % m[sl]
    seg = np.hypot(*(P[nxt] - P).T)
    cum = np.cumsum(seg)
    base = np.concatenate([[0.0], cum])[offs[:-1]]
    c_incl = cum - base[sl]                         # arc length from P0 to P_{j+1}
    c_excl = c_incl - seg                           # ... to P_j
    if split is None:
        sides = np.hypot(*(np.roll(rect, -1, axis=0) - rect).T)
        split = np.stack([split_chain(seg[offs[s]:offs[s + 1]], sides) for s in range(n_s)])
    split = np.asarray(split, dtype=np.int64)
    # subdivide each rectangle side like its part (same length ratios)
    bounds = np.concatenate([np.zeros((n_s, 1), np.int64), split, m[:, None]], axis=1)
    arc = np.concatenate([np.zeros((n_s, 1)), c_excl[offs[:-1, None] + split],
                          c_incl[offs[1:] - 1, None]], axis=1)
    sp = split[sl]
    part = (j >= sp[:, 0]).astype(np.int64) + (j >= sp[:, 1]) + (j >= sp[:, 2])
    b0, b1 = bounds[sl, part], bounds[sl, part + 1]
    a0, a1 = arc[sl, part], arc[sl, part + 1]
    span = a1 - a0
    frac = np.where(span > 0, (c_excl - a0) / np.where(span > 0, span, 1.0),
                    (j - b0) / (b1 - b0))
    Q = rect[part] + frac[:, None] * (rect[(part + 1) % 4] - rect[part])
    return P, Q, roll, split


def anchored_maps(sections: Sections, chosen, extents, anchors_uv, *,
                  topology: MeshTopology, plan=None, material: bool = False):
    """Correspondence of every plane with a plan's start and split points carried along.

    A plan's four correspondence points of each plane (start ``P0`` and the first points
    of parts 2-4) are material points of the rest surface. On a deformed copy each is
    projected along the axis onto its plane (``anchors_uv``); the plane's loop is the one
    carrying them (`fibres.slicing.contours.anchored_loops`, not the per-frame choice ``chosen``
    where a plane cuts several loops); each anchor is placed on the contour at a soft
    closest point and the split points are put in order by a continuous rule
    (`fibres.slicing.soft_anchor._soft_anchor_loop`); the points are inserted into the contour
    and serve as ``P0`` and the split points. No choice is re-made per frame, so the
    result depends continuously (piecewise smoothly) on the vertex positions -- no vertex
    snapping, no re-minimised split, no fresh fallback (except for a contour of zero
    length) -- which a finite difference across a plan needs.

    Parameters
    ----------
    sections : Sections
    chosen : (S,) int
    extents : (3,) float
    anchors_uv : (S, 4, 2) float
        Projected anchors, in the plane frame.
    topology : MeshTopology
    plan : DecompositionPlan, optional
        The plan whose anchors these are. Given, a plane that cut a single loop on the
        rest pose (`fibres.plan.rest_loop_counts`) but cuts several now keeps its whole
        section: all its loops are bridged into one contour (`fibres.slicing.contours.bridge_loops`),
        continuous through splits, merges and islands (without it, only loops that the
        anchors move onto are bridged). Measured on LHDL bend sweeps: largest/median
        1-degree step, morph only, glut_med 8.9 -> 5.0, iliacus 17.8 -> 14.5.
    material : bool
        With ``plan``: match the anchors by rest-pose position and normal instead of in
        the plane (every contour point is a material point of the surface, with a
        rest-pose position and normal, `fibres.plan.rest_geometry`). Follows the material
        where a projected anchor is ambiguous (a thin sheet's two faces), but measured
        less smooth on the LHDL iliacus (h/2h agreement 0.90 against 0.99), so off.

    Returns
    -------
    P, Q : tuple of (m_s, 2) float arrays
    notes : tuple of str
    """
    chosen = np.asarray(chosen, dtype=np.int64)
    if (chosen < 0).any():
        s = int(np.flatnonzero(chosen < 0)[0])
        raise ValueError(f"slice {s} at height {sections.heights[s]:.6g} cuts no contour")
    anchors_uv = np.ascontiguousarray(anchors_uv, dtype=float)
    if material and plan is None:
        raise ValueError("material matching needs the plan")
    if not material:
        chosen, changed, carrier = anchored_loops(sections, chosen, anchors_uv, carriers=True)
    else:
        rest, rest_n, ax, nax = rest_geometry(plan)
        e = topology.edges[sections.edge]
        tt = sections.t[:, None]
        chosen, changed, carrier = anchored_loops(
            sections, chosen, ax, points=(1.0 - tt) * rest[e[:, 0]] + tt * rest[e[:, 1]],
            carriers=True)
    rect = rectangle(float(extents[0]), float(extents[1]))
    pts, _, av, aw, m, offs, _ = _clockwise_all(sections, chosen, topology, anchors=material)
    notes = []
    none = np.zeros(0, dtype=np.int64)
    extra = [none] * chosen.size
    for s in np.flatnonzero((carrier != chosen[:, None]).any(axis=1)):
        extra[s] = np.setdiff1d(carrier[s], [chosen[s]])
    if plan is not None:
        # the whole section where the rest plane cut one loop (continuous through splits
        # and merges), see `fibres.plan.rest_loop_counts`
        single = np.flatnonzero((rest_loop_counts(plan) == 1)
                                & (np.bincount(sections.loop_slice, minlength=chosen.size) > 1))
        for s in single:
            extra[s] = np.setdiff1d(sections.loops_of_slice(int(s)), [chosen[s]])
    if any(x.size for x in extra):
        pts, av, aw, m, offs, bridge_notes = _bridged(sections, chosen, extra, topology,
                                                      pts, av, aw, m, offs, material)
        notes += bridge_notes
    if not material:
        X, NX = pts, np.zeros((pts.shape[0], 1))
        ax, nax = anchors_uv, np.zeros(anchors_uv.shape[:2] + (1,))
    else:
        X = np.einsum("kn,knd->kd", aw, rest[av])
        NX = np.einsum("kn,knd->kd", aw, rest_n[av])
    notes = [f"slice {s}: used the loop carrying the plan's anchors" for s in
             np.flatnonzero(changed)] + notes
    nominal = split_fractions(rect)                # rest-like arc fractions of Q1..Q3
    seg, tk, point, moved = anchor_kernel()(
        np.ascontiguousarray(pts), np.ascontiguousarray(X), np.ascontiguousarray(NX),
        m.astype(np.int64), offs.astype(np.int64), np.ascontiguousarray(ax),
        np.ascontiguousarray(nax), nominal, ARC_GAP, ARC_WINDOW, SOFT_SPREAD, SOFT_FLOOR)
    P, Q, offs2, ok = _insert_and_subdivide(pts, m, offs, seg, tk, point, rect)
    P_all, Q_all = planes(P, offs2), planes(Q, offs2)    # views of P, Q (`fibres.slicing.mvc`)
    for s in np.flatnonzero(moved & ok):
        notes.append(f"slice {s}: planned split points out of order; moved to the nearest "
                     "ordered positions")
    if not ok.all():
        P_all, Q_all = list(P_all), list(Q_all)
        for s in np.flatnonzero(~ok):   # a contour of zero length: nothing to order
            notes.append(f"slice {s}: degenerate contour; start/split points chosen afresh")
            P_all[s], Q_all[s], _, _ = correspond_continuous(pts[offs[s]:offs[s + 1]], rect)
        P_all, Q_all = tuple(P_all), tuple(Q_all)
    return P_all, Q_all, tuple(notes)


def _bridged(sections, chosen, extra, topology, pts, av, aw, m, offs, anchors):
    """The contours with the other loops ``extra[s]`` of each plane bridged in
    (`fibres.slicing.contours.bridge_loops`), back to back as `_clockwise_all` returns them."""
    planes = np.flatnonzero([x.size > 0 for x in extra])
    extra = [extra[s] for s in planes]
    loops = np.concatenate(extra).astype(np.int64)
    e_pts, _, e_av, e_aw, e_m, e_offs, _ = _clockwise_all(sections, loops, topology,
                                                           anchors=anchors)
    parts = [list(np.split(x, offs[1:-1])) for x in (pts, av, aw)]
    notes = []
    i = 0
    for s, ex in zip(planes, extra):
        cur_p, cur_m = parts[0][s], (parts[1][s], parts[2][s])
        for _ in ex:
            lo, hi = e_offs[i], e_offs[i + 1]
            cur_p, cur_m, gap = bridge_loops(cur_p, cur_m, e_pts[lo:hi],
                                             (e_av[lo:hi], e_aw[lo:hi]))
            i += 1
        parts[0][s], parts[1][s], parts[2][s] = cur_p, cur_m[0], cur_m[1]
        notes.append(f"slice {s}: {len(ex) + 1} loops bridged into one contour (the plan's "
                     "section)")
    m = np.array([len(x) for x in parts[0]])
    offs = np.concatenate([[0], np.cumsum(m)])
    pts, av, aw = (np.concatenate(x) for x in parts)
    return pts, av, aw, m, offs, notes


def _slice_maps_loop(sections: Sections, chosen, extents, *, topology: MeshTopology):
    """`slice_maps` one plane at a time with
    `fibres.slicing.correspondence.correspond_continuous` (reference implementation for the tests)."""
    rect = rectangle(float(extents[0]), float(extents[1]))
    n_s = len(chosen)
    P_all, Q_all, notes = [None] * n_s, [None] * n_s, []
    choice = np.full((n_s, 4), -1, dtype=np.int64)
    for s in range(n_s):
        pts, edge = clockwise_contour(sections, int(chosen[s]))
        P, Q, seg, tau = correspond_continuous(pts, rect)
        m = pts.shape[0]
        choice[s] = edge[np.where(tau < 0.5, seg, (seg + 1) % m)]
        P_all[s], Q_all[s] = P, Q
    return tuple(P_all), tuple(Q_all), choice, tuple(notes)


def morph_local(xy, w, heights, P, Q) -> np.ndarray:
    """Map template points to the muscle, plane by plane (Kohout 2012 §3.3).

    Parameters
    ----------
    xy : (M, 2) float
        In-plane template coordinates in the box frame (``x * ex, y * ey``).
    w : (M,) float
        Heights in the box frame (``z * ez``).
    heights : (S,) float
        Plane heights, S >= 2, increasing.
    P, Q : sequences of S (m_s, 2) float arrays
        Contours and subdivided rectangles of the planes (`slice_maps`).

    Returns
    -------
    (M, 2) float
        Mapped in-plane coordinates: ``sum_i lambda_i(xy; Q_s) P_s,i`` blended linearly in
        ``w`` between the two planes around ``w`` (the end planes beyond them).
    """
    xy = np.asarray(xy, dtype=float)
    w = np.asarray(w, dtype=float)
    h = np.asarray(heights, dtype=float)
    n_s = h.size
    s0 = np.clip(np.searchsorted(h, w, side="right") - 1, 0, n_s - 2)
    a = np.clip((w - h[s0]) / (h[s0 + 1] - h[s0]), 0.0, 1.0)
    # every (point, plane) use with its weight; one compiled pass over all of them
    use_lo = a < 1.0
    use_hi = a > 0.0
    idx = np.concatenate([np.flatnonzero(use_lo), np.flatnonzero(use_hi)])
    pl = np.concatenate([s0[use_lo], s0[use_hi] + 1])
    wt = np.concatenate([1.0 - a[use_lo], a[use_hi]])
    mapped = mvc_map(xy[idx], pl, Q, P, weights=wt)
    out = np.zeros_like(xy)
    n_lo = int(use_lo.sum())        # np.add.at(out, idx, mapped): each half has unique rows
    out[idx[:n_lo]] += mapped[:n_lo]
    out[idx[n_lo:]] += mapped[n_lo:]
    return out
