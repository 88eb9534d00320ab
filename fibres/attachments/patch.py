"""Attachment patches: the origin and insertion areas as regions of the muscle surface.

Landmarks of an attachment are usually digitised on the bone, not on the muscle mesh (the
LHDL landmarks lie a median 3-7 mm and up to ~30 mm off the muscle surface). Modenese & Kohout
(Ann. Biomed. Eng. 48:1793-1804, 2020) project them onto the muscle and take the area their
outline encloses. Our rule, step by step:

1. every landmark is projected to its nearest surface vertex (a *seed*); landmarks farther
   than `FAR_LANDMARK` from the surface are reported in one note (they still count);
2. the patch is the union of
   a. the surface grown from the seeds along the surface (Dijkstra over the mesh edges, so it
      never jumps through a thin muscle to its other face) up to the radius ``r`` (the
      median distance from a seed to its nearest other seed, at least half a mean edge), so
      that neighbouring landmarks' disks overlap, keeping the vertices that face the
      landmarks (as in b); and
   b. the region the landmarks outline (landmarks are often digitised around the border of
      the area): vertices whose projection on the landmarks' best-fit plane falls inside
      their convex hull, that lie within 2 x the landmarks' median distance from the surface
      + 2 mean edges of the landmarks' surface (a quadratic height field fitted to them, on
      either side: muscles overlap bones a little), and whose outward normal faces that
      surface within 60 degrees (`FACING_COS`: the deep face of a flat muscle, not its
      superficial face nor the flanks of a tapering end);
3. holes are filled: every region of the rest of the surface smaller than half the patch
   (but never the largest region, the muscle's free surface) joins the patch;
4. pieces of the patch with less than `MIN_PIECE` of its area (a stray landmark) are dropped,
   with a note;
5. where origin and insertion patches meet or overlap, each vertex goes to the nearer
   (geodesic) seed set, and one ring of free vertices is kept between them, so the field has
   room to rise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import ConvexHull, QhullError, cKDTree

from ..errors import InputError

__all__ = ["AttachmentPatches", "attachment_patches", "cross_rows", "edge_graph", "face_normals",
           "FAR_LANDMARK", "MIN_PIECE"]

#: landmarks farther than this (metres) from the muscle surface are named in a note
FAR_LANDMARK = 0.02
#: a vertex faces the landmarks' surface when its normal is within acos(FACING_COS) of it
FACING_COS = 0.5
#: patch pieces with less than this share of the patch area are dropped
MIN_PIECE = 0.05
_STRIP = False


@dataclass(frozen=True)
class AttachmentPatches:
    """Origin and insertion patches of a surface.

    Attributes
    ----------
    origin, insertion : (V,) bool
        Vertices of each patch.
    origin_faces, insertion_faces : (T,) bool
        Faces with all three corners in the patch.
    distances : tuple of two (K,) float arrays
        Distance (metres) of each origin / insertion landmark from the surface.
    notes : tuple of str
    """

    origin: np.ndarray
    insertion: np.ndarray
    origin_faces: np.ndarray
    insertion_faces: np.ndarray
    distances: tuple
    notes: tuple = ()


def edge_graph(vertices, edges):
    """The mesh's edge graph weighted by the edges' lengths: a sparse (V, V) matrix with the
    length of each edge ``(a, b)``, ``a < b``, at ``(a, b)`` (the graph routines here are
    undirected: the upper triangle is the graph), the row of each stored entry, and the
    lengths. Straight in sparse-row form when the edges come sorted (`mesh_edges` order; the
    rows are then the edges' first vertices), else by sorting."""
    d = np.take(vertices, edges[:, 0], axis=0) - np.take(vertices, edges[:, 1], axis=0)
    length = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
    lo, hi = np.minimum(edges[:, 0], edges[:, 1]), np.maximum(edges[:, 0], edges[:, 1])
    n = len(vertices)
    key = lo * np.int64(n) + hi
    if key.size and not (np.diff(key) > 0).all():
        graph = sp.csr_matrix((length, (lo, hi)), shape=(n, n))
        return graph, np.repeat(np.arange(n), np.diff(graph.indptr)), length
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(lo, minlength=n), out=indptr[1:])
    return sp.csr_matrix((length, hi, indptr), shape=(n, n)), lo, length


def cross_rows(p, q):
    """Row-wise cross products of (..., 3) arrays (np.cross's formula, written out per
    coordinate)."""
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    out[..., 0] = p[..., 1] * q[..., 2] - p[..., 2] * q[..., 1]
    out[..., 1] = p[..., 2] * q[..., 0] - p[..., 0] * q[..., 2]
    out[..., 2] = p[..., 0] * q[..., 1] - p[..., 1] * q[..., 0]
    return out


def face_normals(vertices, faces):
    """(T, 3) face normals scaled by twice the face area: ``(b - a) x (c - a)`` for the corners
    a, b, c."""
    a = np.take(vertices, faces[:, 0], axis=0)
    return cross_rows(np.take(vertices, faces[:, 1], axis=0) - a,
                      np.take(vertices, faces[:, 2], axis=0) - a)


def _grow(graph, seeds, radius):
    """(V,) geodesic distance from the nearest seed, inf beyond ``radius``."""
    return dijkstra(graph, directed=False, indices=np.unique(seeds), limit=radius,
                    min_only=True)


def _components(mask, graph, rows):
    """Connected components of the graph (`edge_graph`, its entries' ``rows``) without the edges
    that join a vertex of ``mask`` to one outside it: the pieces of ``mask`` and those of the
    rest at once, (count, (V,) labels, (E,) whether each stored edge is kept). Labels are
    numbered by each component's first vertex (scipy's order)."""
    keep = mask[rows] == mask[graph.indices]
    at = np.zeros(len(keep) + 1, dtype=np.int64)
    np.cumsum(keep, out=at[1:])
    cut = sp.csr_matrix((np.ones(int(at[-1])), graph.indices[keep], at[graph.indptr]),
                        shape=graph.shape)
    return connected_components(cut, directed=False) + (keep,)


def _pieces(patch, graph, rows, vertex_area, name, notes):
    """The patch with its holes filled and its small pieces dropped (module docstring, steps
    3 and 4): holes are the components of the rest of the surface smaller than half the
    patch (not the muscle's free surface, the largest, nor a face that a ring of landmarks
    round a thin muscle's rim happens to enclose); pieces under `MIN_PIECE` of the filled
    patch's area are dropped, with a note. The filled patch's pieces join the components that
    the cut edges between the patch and a hole connect (a search over the components, not the
    surface: the same components, numbered alike)."""
    n, label, kept = _components(patch, graph, rows)
    rest = np.zeros(n, dtype=bool)
    rest[label[~patch]] = True
    area = np.bincount(label, vertex_area, n)
    if rest.sum() > 1:
        small = rest & (area < 0.5 * vertex_area[patch].sum())
        small[np.flatnonzero(rest)[area[rest].argmax()]] = False
        if small.any():
            patch = patch | small[label]
            a, b = label[rows[~kept]], label[graph.indices[~kept]]
            join = small[a] | small[b]
            n, merged = connected_components(
                sp.csr_matrix((np.ones(int(join.sum())), (a[join], b[join])), shape=(n, n)),
                directed=False)
            label = merged[label]
            area = np.bincount(label, vertex_area, n)
    piece = np.zeros(n, dtype=bool)
    piece[label[patch]] = True
    if piece.sum() <= 1:
        return patch
    keep = ~piece | (area >= MIN_PIECE * area[piece].sum())
    if keep.all():
        notes.append(f"{name} patch: {int(piece.sum())} separate pieces (the field has a "
                     "saddle between them)")
        return patch
    notes.append(f"{name} patch: {int((~keep).sum())} small piece(s) of {int(piece.sum())} "
                 f"dropped (under {MIN_PIECE:.0%} of the area: stray landmarks)")
    return patch & keep[label]


def attachment_patches(vertices, faces, origin, insertion, edges, *,
                       normals=None) -> AttachmentPatches:
    """The origin and insertion patches of a closed surface (module docstring).

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (T, 3) int
    origin, insertion : (K, 3) float
        Landmarks, same units as the vertices.
    edges : (E, 2) int
        `fibres.slicing.harmonic_field.mesh_edges` of the faces.
    normals : (T, 3) float, optional
        `face_normals` of the surface, when at hand.
    """
    v = np.asarray(vertices, dtype=np.float64)
    graph, rows, length = edge_graph(v, edges)
    mean_edge = float(length.mean())
    tree = cKDTree(v, leafsize=64, balanced_tree=False, compact_nodes=False)  # faster build
    notes = []
    fn = face_normals(v, faces) if normals is None else normals
    fx, fy, fz = fn[:, 0], fn[:, 1], fn[:, 2]
    flat = faces.reshape(-1)
    vx, vy, vz = (np.bincount(flat, np.repeat(c, 3), len(v)) for c in (fx, fy, fz))
    size = np.maximum(np.sqrt(vx * vx + vy * vy + vz * vz), 1e-300)
    vn = np.stack([vx / size, vy / size, vz / size], axis=1)
    vertex_area = np.bincount(flat, np.repeat(0.5 * np.sqrt(fx * fx + fy * fy + fz * fz) / 3.0,
                                              3), len(v))
    patches, dists, seed_sets = [], [], []
    for name, pts in (("origin", origin), ("insertion", insertion)):
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
        if len(pts) == 0:
            raise InputError(f"no {name} landmarks", where=name,
                             fix=f"Give at least one {name} landmark.")
        dist, seeds = tree.query(pts)
        far = dist > FAR_LANDMARK
        if far.any():
            notes.append(f"{int(far.sum())} of {len(pts)} {name} landmarks lie more than "
                         f"{FAR_LANDMARK * 1e3:.0f} mm from the muscle surface (farthest "
                         f"{dist.max() * 1e3:.1f} mm); they were projected onto it")
        proj = v[np.unique(seeds)]
        if len(proj) > 1:
            nn = cKDTree(proj).query(proj, k=2)[0][:, 1]
            radius = max(float(np.median(nn)), 0.5 * mean_edge)
        else:
            radius = 0.5 * mean_edge
        d = _grow(graph, seeds, radius)
        enclosed, facing = _enclosed(v, vn, pts, dist, mean_edge)
        patch = np.isfinite(d) if _STRIP else (np.isfinite(d) & facing) | enclosed
        patch = _pieces(patch, graph, rows, vertex_area, name, notes)
        patches.append(patch)
        dists.append(dist)
        seed_sets.append(seeds)
    o, i = patches
    both = o & i
    if both.any() or _touching(o, i, edges):
        # split by the nearer seed set, then free one ring between them
        nearer_o = _grow(graph, seed_sets[0], np.inf) <= _grow(graph, seed_sets[1], np.inf)
        o, i = o & nearer_o, i & ~nearer_o
        ring = _touching_vertices(o, i, edges)
        o, i = o & ~ring, i & ~ring
        notes.append("origin and insertion patches met: split by the nearer landmarks")
    if not o.any() or not i.any():
        raise InputError("the origin and insertion landmarks project onto the same part of the "
                         "surface", where="attachments",
                         fix="Check that the landmarks belong to this muscle's two ends.")
    f0, f1, f2 = faces[:, 0], faces[:, 1], faces[:, 2]
    of, if_ = o[f0] & o[f1] & o[f2], i[f0] & i[f1] & i[f2]
    return AttachmentPatches(o, i, of, if_, (dists[0], dists[1]), tuple(notes))


def _enclosed(v, vn, landmarks, dist, mean_edge):
    """(V,) vertices over the region the landmarks outline (module docstring, step 2b), and
    (V,) vertices facing the landmarks' surface (all, for fewer than 4 landmarks)."""
    none, every = np.zeros(len(v), dtype=bool), np.ones(len(v), dtype=bool)
    if len(landmarks) < 4:
        return none, every
    centre = landmarks.mean(axis=0)
    d = landmarks - centre
    vals, vecs = np.linalg.eigh(d.T @ d)
    if vals[1] < 1e-6 * vals[2]:                     # collinear landmarks: no area
        return none, every
    frame = vecs[:, ::-1]                            # in-plane e1, e2; normal e3
    lx, ly, lz = (d @ frame).T
    # the landmarks' surface as a height field over their plane (quadratic with >= 6)
    basis = (lambda x, y: np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1)) \
        if len(landmarks) >= 6 else (lambda x, y: np.stack([np.ones_like(x), x, y], axis=1))
    coef = np.linalg.lstsq(basis(lx, ly), lz, rcond=None)[0]
    vx, vy, vz = ((v - centre) @ frame).T
    height = vz - basis(vx, vy) @ coef
    # the muscle lies on one side: its vertices' median height says which (its sign is the
    # majority's, when more than half lie on one side)
    n_up, n_down = np.count_nonzero(height > 0.0), np.count_nonzero(height < 0.0)
    side = 1.0 if 2 * n_up > len(height) else -1.0 if 2 * n_down > len(height) else \
        float(np.sign(np.median(height)) or 1.0)
    limit = 2.0 * float(np.median(dist)) + 2.0 * mean_edge
    near = np.abs(height) < limit
    try:
        hull = ConvexHull(np.stack([lx, ly], axis=1))
    except QhullError:
        return none, every
    eq = hull.equations                                  # (H, 3): a x + b y + c <= 0 inside
    # facing the bone: the outward vertex normal points towards the landmarks' surface
    cos = vn @ frame[:, 2]
    facing = cos * side < -FACING_COS
    test = np.flatnonzero(near & facing)                 # the hull test only where it matters
    enclosed = np.zeros(len(v), dtype=bool)
    enclosed[test] = (np.stack([vx[test], vy[test]], axis=1) @ eq[:, :2].T + eq[:, 2]
                      <= 1e-12).all(axis=1)
    return enclosed, facing


def _touching(a, b, edges) -> bool:
    ea, eb = a[edges[:, 0]], b[edges[:, 1]]
    return bool((ea & eb).any() or (a[edges[:, 1]] & b[edges[:, 0]]).any())


def _touching_vertices(a, b, edges):
    """(V,) vertices of ``a`` or ``b`` on an edge joining the two."""
    x, y = edges[:, 0], edges[:, 1]
    cross = (a[x] & b[y]) | (b[x] & a[y])
    out = np.zeros(a.shape, dtype=bool)
    out[x[cross]] = True
    out[y[cross]] = True
    return out
