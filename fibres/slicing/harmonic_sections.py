"""Cross-sections of harmonic-field slicing: slice levels, one isoline loop per level, the
loops' frames and their samples (`fibres.slicing.harmonic`, steps 2-5 of its docstring).

Levels (`_levels`): the inner slices are evenly spaced along the isolines' centroid path,
by its length plus its turning (`bending_measure`). Loops: the longest loop of each level (`fibres.slicing.isolines`). Frames: each
loop's centroid, normal (vector area) and an axis carried from the middle loop by parallel
transport. Samples: `SAMPLES` points of equal arc length from a *seam*; the middle loop's
seam is its point towards the square's corner (0, 0), and each next loop's seam is the one
whose arc-length samples best match the previous loop's (least squares over all samples,
`_registered_seam`; Besl & McKay's closest-point registration restricted to the loop's one
degree of freedom, its cyclic shift). A seam carried by one nearest point (the earlier rule)
slid the samples of consecutive loops back and forth along them (chevrons on the surface,
docs/decisions.md); matching all samples keeps the correspondence continuous.

Each sample is an edge point of the surface (a fixed blend of two vertices), so the samples
of all levels form a sparse (L * SAMPLES, V) matrix: a material curve per sample that rides a
deformed copy of the surface.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from ..attachments.patch import cross_rows, edge_graph
from ..errors import InputError
from ..fit.box import shape_sign
from .isolines import isoline_loops_at, isoline_moments
from .planes import _stable_order

__all__ = ["SAMPLES"]

#: loop samples per level (a multiple of 4: the square's corners are samples)
SAMPLES = 64
#: candidate levels (x 2) searched for the slice levels
_CANDIDATES = 48
#: field level of the patches' rim loops
_RIM = 1e-6
#: length-equivalent of the centre line's turning in the slice spacing (`bending_measure`)
BENDING = 0.25
#: samples of the centre line for its turning
_PATH = 48
#: a patch's dead end: surface farther from the other patch than the patch's farthest point by
#: more than this share of the surface's extent from the other patch (`dead_end_levels`)
DEAD_END = 0.1
#: the words that mark a dead end's note (`dead_end_levels`), for those who look for it
DEAD_END_NOTE = "lies beyond the"


def bending_measure(s, points, weight):
    """(L,) cumulative turning of a path, as a length to add to its arc length ``s``.

    The path (``points`` (L, 3) at arc lengths ``s``, increasing) is resampled at `_PATH`
    equal steps; its direction at each sample is the central difference (one-sided at the
    ends) and the turning of each step the angle between consecutive directions. The
    cumulative turning (radians) times ``weight * S / pi`` (S the path's length) is returned
    at the given ``s``: with weight w, a half-turn counts as w of the whole length. Added to
    s it spaces the slices by length and bending together (curvature-adaptive sampling), so
    a muscle's bend gets more slices than its straight parts."""
    s = np.asarray(s, float)
    total = s[-1]
    if total <= 0:
        return np.zeros_like(s)
    t = np.linspace(0.0, total, _PATH)
    c = np.stack([np.interp(t, s, points[:, d]) for d in range(3)], axis=1)
    d = np.gradient(c, axis=0)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    turn = np.arctan2(np.linalg.norm(cross_rows(d[:-1], d[1:]), axis=1),
                      np.einsum("ij,ij->i", d[1:], d[:-1]))
    cum = np.concatenate([[0.0], np.cumsum(turn)]) * weight * total / np.pi
    return np.interp(s, t, cum)


def dead_end_levels(plan):
    """(lo, hi, notes): the field levels between which the slices stay clear of dead ends.

    A patch on the side of a long muscle leaves surface beyond it: farther from the other
    patch than any point of the patch (psoas with the iliacus-area origin of Modenese &
    Kohout 2020: a third of the muscle above it). The field there is flat and below every
    cross-section's level, and the isolines of those levels are rings about the patch that
    sweep up through the dead end; fibres through them climb into it and hook back.

    The origin's dead end is the set of vertices on the field's lower half farther from the
    insertion patch than the origin patch's farthest vertex plus `DEAD_END` times the largest
    such distance. Distances run along the surface (shortest paths over the mesh's edges,
    Dijkstra, from the insertion patch's vertices), so that a muscle bent into a U, whose belly
    is farther from the insertion in a straight line than its origin, has none; they are
    computed only where straight-line distances from the patch's centroid find candidates.
    ``lo`` is the largest field value in the dead end (0 without one): the isolines above it
    no longer enter it, they cross the muscle at or below the patch. The same for the
    insertion (``hi`` the smallest value in its dead end, 1 without one). A dead end gets no
    fibres (none can run beyond its origin); a note gives its share of the surface's area."""
    v, u, f = plan.rest_vertices, plan.field, plan.faces
    bounds, notes = [0.0, 1.0], []
    for k, (own, other, name) in enumerate(((plan.origin, plan.insertion, "origin"),
                                             (plan.insertion, plan.origin, "insertion"))):
        half = u < 0.5 if k == 0 else u > 0.5
        d = np.linalg.norm(v - v[other].mean(axis=0), axis=1)
        if not (half & (d > d[own].max() + DEAD_END * d.max())).any():
            continue
        d = _surface_distance_from(v, plan.edges, other)
        dead = half & (d > d[own].max() + DEAD_END * d[np.isfinite(d)].max())
        if not dead.any():
            continue
        bounds[k] = float(u[dead].max() if k == 0 else u[dead].min())
        area = 0.5 * np.linalg.norm(plan.face_normals(), axis=1)
        share = area[dead[f].all(axis=1)].sum() / area.sum()
        notes.append(f"{share:.0%} of the surface {DEAD_END_NOTE} {name} patch (farther from "
                     f"the other attachment): no slices or fibres there; check the {name} "
                     "landmarks if the muscle's fibres reach it")
    return bounds[0], bounds[1], notes


def _surface_distance_from(vertices, edges, source):
    """(V,) shortest distance over the mesh's edges (`edge_graph`) from the vertices
    ``source`` (V,) bool."""
    return dijkstra(edge_graph(vertices, edges)[0], directed=False,
                    indices=np.flatnonzero(source), min_only=True)


def _levels(plan, resolution: int) -> np.ndarray:
    """(R + 1,) field levels whose isolines' centroids are evenly spaced along the muscle.

    The centroid C(t) and vector area of the whole isoline are measured at `_CANDIDATES`
    levels (evenly spaced, and at the area quantiles of the field, which resolve the levels
    where the muscle is; `fibres.slicing.isolines.isoline_moments`). Progress along the muscle is
    the centroid's advance along the isolines' mean normal, ``ds = max(0, dC . n)``: an
    isoline sweeping back through a dead end beyond a patch (the field is flat there) makes
    no progress and gets no slice. The centroid path's turning is added as a length
    (`bending_measure` with weight `BENDING`: a bend gets more slices, so the fibres' turns
    are spread over more joints -- psoas turn p95 42 -> 38 degrees -- and the slices that
    ring a narrow insertion come closer -- gluteus maximus 5.8 -> 4.4 % empty). The R - 1
    inner levels divide the sum evenly. Levels stay above and below the patches' dead ends
    (`dead_end_levels`): the path starts at the first isoline clear of them."""
    v, u, f = plan.rest_vertices, plan.field, plan.faces
    fn = plan.face_normals()
    area = 0.5 * np.sqrt(fn[:, 0] * fn[:, 0] + fn[:, 1] * fn[:, 1] + fn[:, 2] * fn[:, 2])
    uc = (u[f[:, 0]] + u[f[:, 1]] + u[f[:, 2]]) / 3.0
    order = _stable_argsort(uc)
    cum = np.cumsum(area[order])
    q = np.interp(np.linspace(0, 1, _CANDIDATES), cum / cum[-1], uc[order])
    cand = np.unique(np.concatenate([q, np.linspace(0.0, 1.0, _CANDIDATES)]))
    lo, hi, _ = plan.cached(("dead ends",), lambda: dead_end_levels(plan))
    first, last = max(lo + _RIM, _RIM), min(hi - _RIM, 1 - _RIM)
    cand = cand[(cand > first + _RIM) & (cand < last - _RIM)]
    cand = np.concatenate([[first], cand, [last]])
    length, centre, _ = isoline_moments(u, v, f, cand, area=False)
    ok = length > 0
    cand, centre = cand[ok], centre[ok]
    step = np.diff(centre, axis=0)
    ahead = np.einsum("ij,ij->i", step, centre[-1] - centre[:-1]) > 0
    ds = np.where(ahead, np.linalg.norm(step, axis=1), 0.0)
    s = np.concatenate([[0.0], np.cumsum(ds)])
    s = s + 1e-12 * max(s[-1], 1e-300) * np.arange(s.size) / s.size    # strictly increasing
    s = s + bending_measure(s, centre, BENDING)
    levels = np.interp(np.linspace(0.0, s[-1], resolution + 1), s, cand)
    levels[0], levels[-1] = _RIM, 1.0 - _RIM
    levels[1:-1] = np.clip(levels[1:-1], first + _RIM, last - _RIM)
    return levels


def _stable_argsort(x):
    """``np.argsort(x, kind="stable")`` of a float array without NaN: the vectorised default
    sort gives each value's run of equal values, whose stable order (`planes._stable_order`)
    is the answer."""
    order = np.argsort(x)
    xs = x[order]
    run = np.zeros(x.size, dtype=np.int64)
    np.cumsum(xs[1:] != xs[:-1], out=run[1:])
    rank = np.empty(x.size, dtype=np.int64)
    rank[order] = run
    return _stable_order(rank)[0]


def _loop_frames(p, first, size):
    """(L, 3) centroids, (L, 3) unit normals (vector areas) and (N,) segment lengths of the
    closed loops ``p[first[j]:first[j] + size[j]]`` (p (N, 3)): the centroid weighs each
    segment's midpoint by its length (the vertex mean for a loop of length 0)."""
    nxt = np.arange(1, len(p) + 1)
    nxt[first + size - 1] = first
    q = p[nxt]
    d = q - p
    seg = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
    centres = np.add.reduceat(0.5 * (p + q) * seg[:, None], first, axis=0)
    for j, (a, m) in enumerate(zip(first.tolist(), size.tolist())):
        total = seg[a:a + m].sum()
        centres[j] = centres[j] / total if total > 0 else p[a:a + m].mean(axis=0)
    c = np.repeat(centres, size, axis=0)
    normals = 0.5 * np.add.reduceat(cross_rows(p - c, q - c), first, axis=0)
    for j, area in enumerate(normals):
        norm = np.linalg.norm(area)
        normals[j] = area / norm if norm > 0 else (0.0, 0.0, 1.0)
    return centres, normals, seg


def _major_axis(points, c, n, loop, vertices):
    """The loop's major axis in its plane; its sign from the muscle's shape about the loop
    (`fibres.fit.box.shape_sign` of the vertices, so that a renumbered mesh gets the same
    axis), else from the vertex numbering (a symmetric muscle)."""
    d = points - c
    d = d - np.outer(d @ n, n)
    vals, vecs = np.linalg.eigh(d.T @ d)
    e1 = vecs[:, -1]
    dt = (vertices - c).T
    axial = n @ dt
    sign = shape_sign(dt - np.outer(n, axial), axial, n, e1)
    if sign == 0 and np.dot((loop.a + 1.0), d @ e1) < 0:
        sign = -1
    return e1 if sign >= 0 else -e1


def _transport(e1, n):
    p = e1 - np.dot(e1, n) * n
    norm = np.linalg.norm(p)
    if norm < 1e-9:
        return None
    return p / norm


#: finer arc-length samples per loop sample searched for a loop's seam (`_registered_seam`)
_FINE = 8


def _closest_position(points, q) -> float:
    """Fractional loop position (node + fraction) of the closed polyline's point nearest q."""
    a = points
    b = np.roll(points, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", q - a, ab) / np.maximum(
        np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
    d = np.linalg.norm(a + t[:, None] * ab - q, axis=1)
    k = int(np.argmin(d))
    return k + float(t[k])


def _arc_positions(seg, start, k):
    """(k,) fractional loop positions (node + fraction) that divide the closed loop with
    segment lengths ``seg`` into k equal arcs from the position ``start``."""
    m = len(seg)
    i0 = int(np.floor(start)) % m
    f0 = start - np.floor(start)
    # segment lengths in loop order from the start, the first one split there
    seg = np.concatenate([seg[i0:], seg[:i0]])
    head = seg[0] * (1.0 - f0)
    cum = np.empty(m + 2)
    cum[0], cum[1] = 0.0, head
    np.cumsum(seg[1:], out=cum[2:m + 1])
    cum[2:m + 1] += head
    cum[m + 1] = cum[m] + seg[0] * f0                            # back at the start
    pos = np.arange(-1.0, m + 1.0) + (i0 + 1.0)
    pos[0], pos[-1] = start, start + m
    cum += 1e-15 * cum[-1] * np.arange(cum.size)                 # strictly increasing
    target = np.arange(k) / k * cum[-1]
    return np.interp(target, cum, pos) % m


def _loop_samples(p, seam, k, seg=None):
    """(k,) positions and (k, 3) points of the closed polyline ``p`` at k equal arcs from
    ``seam``; ``seg``: its segment lengths (`_loop_frames`), when at hand."""
    if seg is None:
        seg = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
    pos = _arc_positions(seg, seam, k)
    i0 = np.floor(pos).astype(np.int64) % len(p)
    f = (pos - np.floor(pos))[:, None]
    return pos, (1.0 - f) * p[i0] + f * p[(i0 + 1) % len(p)]


def _register(ref, pts, guess, seg):
    """(positions (k,), points (k, 3)) of the `SAMPLES` arc-length samples of loop ``pts``
    (segment lengths ``seg``) from the seam whose samples lie nearest ``ref`` (k, 3), the
    previous loop's, in the least-squares sense with both sample sets centred (the loops move
    along the muscle; only the cyclic shift is sought): the shifts searched are `_FINE` per
    sample spacing, all round the loop, starting from ``guess``.

    Shift ``t = q F + r`` (F = `_FINE`) takes every F-th fine sample from r, rolled by q:
    its centred sum of squares depends on r only, and the cross term with the reference is
    a circular cross-correlation over q, computed for all q at once by FFT. The samples from
    the chosen seam are every F-th fine sample from it (equal arcs of the same loop)."""
    k = SAMPLES
    pos, fine = _loop_samples(pts, guess, k * _FINE, seg)
    ref = ref - ref.mean(axis=0)
    sub = fine.reshape(k, _FINE, 3).transpose(1, 0, 2)                # (F, K, 3): [r, k]
    sub = sub - sub.mean(axis=1, keepdims=True)
    power = np.einsum("rkd,rkd->r", sub, sub)
    # corr[r, q] = sum_k sub[r, (k + q) mod K] . ref[k]
    corr = np.fft.irfft(np.fft.rfft(sub, axis=1) * np.conj(np.fft.rfft(ref, axis=0))[None],
                        n=k, axis=1).sum(axis=2)
    cost = power[:, None] - 2.0 * corr                                # (F, K)
    r, q = np.unravel_index(int(np.argmin(cost)), cost.shape)
    pick = (q * _FINE + r + _FINE * np.arange(k)) % len(pos)
    return pos[pick], fine[pick]


def _registered_seam(p, seg, first, size, mid, mid_seam):
    """(L, `SAMPLES`) positions (node + fraction) of the loops' samples at equal arc lengths
    from their seams. The loops are ``p[first[j]:first[j] + size[j]]`` (p (N, 3)), their
    segment lengths ``seg`` (N,) (`_loop_frames`). Loop ``mid``'s seam is ``mid_seam`` (in
    ``[0, size[mid])``); each next loop outwards gets the seam whose samples lie nearest the
    previous loop's (`_register`), searched from the loop's point nearest the previous seam's
    point."""
    pts = [p[i:i + m] for i, m in zip(first, size)]
    segs = [seg[i:i + m] for i, m in zip(first, size)]
    samples = [None] * len(pts)
    samples[mid] = _loop_samples(pts[mid], float(mid_seam), SAMPLES, segs[mid])
    for rng in (range(mid + 1, len(pts)), range(mid - 1, -1, -1)):
        prev = mid
        for j in rng:
            guess = _closest_position(pts[j], samples[prev][1][0])
            samples[j] = _register(samples[prev][1], pts[j], guess, segs[j])
            prev = j
    return np.stack([smp[0] for smp in samples])


@dataclass(frozen=True)
class _Slices:
    """The loops of one resolution: per level (L = R + 1), `SAMPLES` loop samples as a sparse
    (L * SAMPLES, V) matrix of vertex weights, the frames at rest, and notes."""

    samples: sp.csr_matrix
    centres: np.ndarray
    normals: np.ndarray
    axes: np.ndarray
    shares: np.ndarray
    notes: tuple


def _slices(plan, resolution: int) -> _Slices:
    levels = _levels(plan, max(int(resolution), 2))[1:-1]
    if resolution < 2:  # one segment: the ends still come from a middle membrane
        levels = levels[:1]
    v = plan.rest_vertices
    loops, notes = [], list(plan.cached(("dead ends",), lambda: dead_end_levels(plan))[2])
    every = isoline_loops_at(plan.field, plan.faces, levels, plan.edges, plan.face_edges, v)
    for j, found in enumerate(every):
        if not found:
            raise InputError("the harmonic field has no isoline at a slice level",
                             where="mesh", fix="Check the attachment landmarks.")
        if len(found) > 1:
            notes.append(f"slice {j}: {len(found)} isoline loops, the longest kept")
        loops.append(found[0])
    size = np.array([len(lp) for lp in loops])
    first = np.cumsum(size) - size
    ea, eb, es = (np.concatenate([getattr(lp, x) for lp in loops]) for x in "abs")
    pts = (1.0 - es[:, None]) * v[ea] + es[:, None] * v[eb]     # all loops' `Loop.points`
    centres, normals, seg = _loop_frames(pts, first, size)
    mid = len(loops) // 2
    pts_mid = pts[first[mid]:first[mid] + size[mid]]
    axes = np.zeros_like(centres)
    axes[mid] = _major_axis(pts_mid, centres[mid], normals[mid], loops[mid], v)
    for rng in (range(mid + 1, len(loops)), range(mid - 1, -1, -1)):
        prev = mid
        for j in rng:
            e = _transport(axes[prev], normals[j])
            axes[j] = e if e is not None else axes[prev]
            prev = j
    # positions along each loop by arc length from a seam that starts at the middle loop's
    # point towards the square's corner (0, 0) and is carried to each next loop by its nearest
    # point (the field's flow lines cross its isolines at right angles)
    e2 = cross_rows(normals, axes)
    e2m = e2[mid]
    d = pts_mid - centres[mid]
    x, y = d @ axes[mid], d @ e2m
    score = -x / max(np.ptp(x), 1e-12) - y / max(np.ptp(y), 1e-12)
    pos = _registered_seam(pts, seg, first, size, mid, np.argmax(score))       # (L, SAMPLES)
    # each loop's extents along e1 and e2
    d = pts - np.repeat(centres, size, axis=0)
    x = np.einsum("ij,ij->i", d, np.repeat(axes, size, axis=0))
    y = np.einsum("ij,ij->i", d, np.repeat(e2, size, axis=0))
    a = np.maximum.reduceat(x, first) - np.minimum.reduceat(x, first)
    b = np.maximum.reduceat(y, first) - np.minimum.reduceat(y, first)
    shares = a / np.maximum(a + b, 1e-300)
    # sample k of loop j blends loop points i0 and i1 = i0 + 1, each an edge point: four
    # (row, vertex, weight) entries per sample, in the order (i0: a, b; i1: a, b) per loop
    i0 = np.floor(pos).astype(np.int64) % size[:, None]
    f = pos - np.floor(pos)
    g0, g1 = i0 + first[:, None], (i0 + 1) % size[:, None] + first[:, None]
    rows = np.repeat(np.arange(len(loops) * SAMPLES).reshape(-1, 1, SAMPLES), 4, axis=1)
    cols = np.stack([ea[g0], eb[g0], ea[g1], eb[g1]], axis=1)
    vals = np.stack([(1.0 - f) * (1.0 - es[g0]), (1.0 - f) * es[g0], f * (1.0 - es[g1]),
                     f * es[g1]], axis=1)
    mat = sp.csr_matrix((vals.reshape(-1), (rows.reshape(-1), cols.reshape(-1))),
                        shape=(len(loops) * SAMPLES, len(v)))
    return _Slices(mat, centres, normals, axes, shares, tuple(notes))
