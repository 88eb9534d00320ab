"""Fibre filtering near wide attachment areas: trimming and reconstruction (Kohout 2012 §3.4).

Morphed fibres tend to converge on one point at a wide attachment instead of spreading over it.
Kohout et al. cut every fibre with two planes perpendicular to the principal axis passing
through the extreme landmarks (the origin landmark farthest along the axis, the insertion
landmark least far along it), throw away the parts beyond the planes and replace each by ONE
new segment from the cut point to the surface point of the attachment area closest to the ray
that continues the last kept segment.

Attachment area on the surface (our reading of "the part of the surface cut out at the contour
of the projected landmarks"): every landmark is projected to its nearest surface vertex; the
area is the set of surface vertices within ``r`` of a projected landmark, where r is the median
distance between neighbouring landmarks (at least the mean edge length of the surface), plus
the projections themselves. For one landmark the area is its projection and that vertex's
neighbourhood of radius r = mean edge length.

Fibres that were cut are resampled uniformly by arc length so every fibre keeps P points;
untouched fibres are returned unchanged.
"""
from __future__ import annotations

import numpy as np

__all__ = ["trim_and_reconstruct", "attachment_region"]


def _vertices_faces(surface):
    if hasattr(surface, "vertices") and hasattr(surface, "faces"):
        return np.asarray(surface.vertices, float), np.asarray(surface.faces, np.int64)
    v, f = surface
    return np.asarray(v, float), np.asarray(f, np.int64)


def attachment_region(vertices, faces, landmarks) -> np.ndarray:
    """Surface points of an attachment area (module docstring).

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (T, 3) int
    landmarks : (K, 3) float

    Returns
    -------
    (C, 3) float
        Surface vertices belonging to the area.
    """
    from scipy.spatial import cKDTree

    tree = cKDTree(vertices)
    _, nearest = tree.query(landmarks)
    proj = vertices[np.unique(nearest)]
    edges = vertices[faces[:, [1, 2, 0]]] - vertices[faces]
    mean_edge = float(np.linalg.norm(edges, axis=-1).mean()) if len(faces) else 0.0
    radius = mean_edge
    if len(landmarks) > 1:
        d, _ = cKDTree(landmarks).query(landmarks, k=2)
        radius = max(radius, float(np.median(d[:, 1])))
    near = tree.query_ball_point(proj, r=radius)
    idx = np.unique(np.concatenate([np.asarray(n, dtype=np.int64) for n in near] + [nearest]))
    return vertices[idx]


def _closest_to_rays(candidates, start, direction, *, chunk: int = 1 << 21):
    """For each ray (start (N,3), direction (N,3)) the candidate (C,3) closest to it.

    Distances of a point q to the ray s + t d (t >= 0): |q - s - max((q - s).d, 0) d|.
    Fibres are processed in blocks of about ``chunk`` fibre-candidate pairs (bounded memory).
    """
    dn = direction / np.linalg.norm(direction, axis=1, keepdims=True)
    out = np.empty_like(start)
    step = max(1, chunk // max(len(candidates), 1))
    for a in range(0, len(start), step):  # blocks of fibres, not single fibres
        rel = candidates[None, :, :] - start[a:a + step, None, :]       # (n, C, 3)
        along = np.einsum("nck,nk->nc", rel, dn[a:a + step])
        perp = rel - np.maximum(along, 0.0)[..., None] * dn[a:a + step, None, :]
        out[a:a + step] = candidates[np.argmin(np.einsum("nck,nck->nc", perp, perp), axis=1)]
    return out


def _resample(poly, n_out):
    """Resample poly-lines (M, Q, 3) uniformly by arc length to (M, n_out, 3)."""
    seg = np.linalg.norm(np.diff(poly, axis=1), axis=-1)              # (M, Q-1)
    cum = np.concatenate([np.zeros((len(poly), 1)), np.cumsum(seg, axis=1)], axis=1)
    target = cum[:, -1:] * np.linspace(0.0, 1.0, n_out)[None, :]      # (M, n_out)
    idx = (cum[:, None, 1:] <= target[:, :, None]).sum(axis=2)        # segment index
    idx = np.clip(idx, 0, poly.shape[1] - 2)
    rows = np.arange(len(poly))[:, None]
    c0, c1 = cum[rows, idx], cum[rows, idx + 1]
    frac = np.where(c1 > c0, (target - c0) / np.where(c1 > c0, c1 - c0, 1.0), 0.0)
    p0, p1 = poly[rows, idx], poly[rows, idx + 1]
    out = p0 + frac[..., None] * (p1 - p0)
    out[:, 0], out[:, -1] = poly[:, 0], poly[:, -1]
    return out


def trim_and_reconstruct(points, surface, origin, insertion, axis):
    """Cut fibres at the extreme-landmark planes and rebuild their ends on the attachment areas.

    Kohout et al. (GRAPP 2012) §3.4, vectorised over fibres.

    Parameters
    ----------
    points : (N, P, 3) float
        Fibres running from the origin (index 0) to the insertion (index P-1).
    surface : Surface or (vertices (V,3), faces (T,3))
        The muscle surface.
    origin, insertion : (K, 3) float
        Attachment landmarks.
    axis : (3,) float
        Principal axis pointing from origin to insertion.

    Returns
    -------
    points : (N, P, 3) float64
        Filtered fibres (untouched fibres are returned as they were).
    trimmed : (N,) bool
        A part beyond a cutting plane was removed.
    reconstructed : (N,) bool
        A new end segment was added on an attachment area.
    """
    pts = np.array(points, dtype=np.float64, copy=True)
    n, p = pts.shape[:2]
    trimmed = np.zeros(n, bool)
    recon = np.zeros(n, bool)
    if n == 0 or p < 2:
        return pts, trimmed, recon
    u = np.asarray(axis, dtype=np.float64)
    u = u / np.linalg.norm(u)
    origin = np.asarray(origin, float).reshape(-1, 3)
    insertion = np.asarray(insertion, float).reshape(-1, 3)
    h_o = float((origin @ u).max())       # origin plane: the origin landmark farthest along u
    h_i = float((insertion @ u).min())    # insertion plane: the least far insertion landmark
    if h_o >= h_i:  # the attachment bands overlap along the axis: nothing sensible to cut
        return pts, trimmed, recon
    h = pts @ u                                                       # (N, P)
    idx = np.arange(p)[None, :]
    below = h < h_o    # strictly beyond the origin plane
    above = h > h_i    # strictly beyond the insertion plane
    j_o = np.where(below.any(axis=1), np.where(below, idx, -1).max(axis=1), -1)
    j_i = np.where(above.any(axis=1), np.where(above, idx, p).min(axis=1), p)
    # cut where the fibre truly passes between the planes: at least one point strictly inside
    inside = (h >= h_o) & (h <= h_i)
    ok = inside.any(axis=1) & (j_o < j_i - 1)
    cut_o = ok & (j_o >= 0)
    cut_i = ok & (j_i <= p - 1)
    if not (cut_o.any() or cut_i.any()):
        return pts, trimmed, recon
    rows = np.arange(n)
    verts, faces = _vertices_faces(surface)

    # cut points on the planes (segments j_o -> j_o+1 and j_i-1 -> j_i)
    a_o, b_o = np.clip(j_o, 0, p - 2), np.clip(j_o, 0, p - 2) + 1
    a_i, b_i = np.clip(j_i, 1, p - 1) - 1, np.clip(j_i, 1, p - 1)

    def cut(a, b, level):
        ha, hb = h[rows, a], h[rows, b]
        s = np.where(hb != ha, (level - ha) / np.where(hb != ha, hb - ha, 1.0), 0.0)
        return pts[rows, a] + np.clip(s, 0, 1)[:, None] * (pts[rows, b] - pts[rows, a])

    c_o, c_i = cut(a_o, b_o, h_o), cut(a_i, b_i, h_i)
    end_o, end_i = pts[:, 0].copy(), pts[:, -1].copy()
    if cut_o.any():
        region = attachment_region(verts, faces, origin)
        d = pts[cut_o, a_o[cut_o]] - pts[cut_o, b_o[cut_o]]          # pointing to the origin
        end_o[cut_o] = _closest_to_rays(region, c_o[cut_o], d)
    if cut_i.any():
        region = attachment_region(verts, faces, insertion)
        d = pts[cut_i, b_i[cut_i]] - pts[cut_i, a_i[cut_i]]          # pointing to the insertion
        end_i[cut_i] = _closest_to_rays(region, c_i[cut_i], d)

    # assemble [end_o, c_o, kept points..., c_i, end_i]; dropped points collapse onto the cut
    # points (zero-length segments), then resample by arc length
    body = pts.copy()
    body = np.where((cut_o[:, None] & (idx <= j_o[:, None]))[..., None], c_o[:, None], body)
    body = np.where((cut_i[:, None] & (idx >= j_i[:, None]))[..., None], c_i[:, None], body)
    start = np.where(cut_o[:, None], end_o, pts[:, 0])
    stop = np.where(cut_i[:, None], end_i, pts[:, -1])
    first = np.where(cut_o[:, None], c_o, pts[:, 0])
    last = np.where(cut_i[:, None], c_i, pts[:, -1])
    poly = np.concatenate([start[:, None], first[:, None], body, last[:, None], stop[:, None]],
                          axis=1)
    sel = cut_o | cut_i
    pts[sel] = _resample(poly[sel], p)
    trimmed[sel] = True
    recon[sel] = True
    return pts, trimmed, recon
