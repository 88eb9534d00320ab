"""Four muscle-like surfaces of different shapes, made here (no data files), with landmarks.

Each is the zero level set of a signed distance function, contoured by marching cubes on a
1.5 mm grid (VTK through pyvista) and cleaned by `fibres.as_surface`:

- ``strap``: a long thin band (sartorius-like), 300 x 28 x 7 mm, bent into a gentle S;
  landmarks on its two end faces;
- ``bipennate``: a spindle (rectus femoris-like), 220 mm long, 50 x 35 mm at the belly,
  tapering to tendons; landmarks on the two tendon tips;
- ``fan``: a triangular slab (pectoralis / gluteus medius-like), an origin arc of 140 mm
  converging over 120 mm to a 20 mm insertion, 12 mm thick at the origin; landmarks along
  the arc's edge and round the insertion;
- ``curved``: a tube of 14-18 mm radius bent through 120 degrees on a 70 mm radius
  (iliopsoas-like); landmarks on the end faces.

``shape(name)`` returns ``(vertices (V, 3) m, faces (T, 3), origin (K, 3) m, insertion (K, 3) m,
template)``.
"""
from __future__ import annotations

import numpy as np

SHAPES = ("strap", "bipennate", "fan", "curved")
STEP = 1.5e-3


def _contour(sdf, lo, hi):
    import pyvista as pv

    n = np.ceil((np.asarray(hi) - np.asarray(lo)) / STEP).astype(int) + 1
    grid = pv.ImageData(dimensions=tuple(n), spacing=(STEP,) * 3, origin=tuple(lo))
    grid.point_data["d"] = sdf(np.asarray(grid.points))
    surf = grid.contour([0.0], scalars="d").triangulate().clean()
    faces = np.asarray(surf.faces).reshape(-1, 4)[:, 1:]
    from fibres import as_surface

    s = as_surface((np.asarray(surf.points, dtype=np.float64), faces))
    return s.vertices, s.faces


def _polyline_distance(p, path):
    """Distance from points to a polyline and the arc parameter (0..1) of the nearest point."""
    a, b = path[:-1], path[1:]
    ab = b - a
    seg_len = np.linalg.norm(ab, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    t = np.clip(np.einsum("nsk,sk->ns", p[:, None] - a[None], ab) / (seg_len ** 2)[None], 0, 1)
    q = a[None] + t[..., None] * ab[None]
    d = np.linalg.norm(p[:, None] - q, axis=2)
    k = np.argmin(d, axis=1)
    rows = np.arange(len(p))
    s = (cum[k] + t[rows, k] * seg_len[k]) / cum[-1]
    return d[rows, k], s, q[rows, k], k


def _swept(path, half_w, half_t, lo, hi, normal=np.array([0.0, 0.0, 1.0])):
    """Solid swept along ``path`` with an elliptic section of half-axes (half_w(s), half_t(s)),
    the ``half_t`` axis along ``normal``; flat ends at the path's ends."""
    def sdf(p):
        d, s, q, k = _polyline_distance(p, path)
        tang = path[np.minimum(k + 1, len(path) - 1)] - path[k]
        tang /= np.linalg.norm(tang, axis=1, keepdims=True)
        rel = p - q
        nrm = normal - (tang @ normal)[:, None] * tang
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        side = np.cross(tang, nrm)
        x, y = rel @ np.eye(3), None
        u = np.einsum("ij,ij->i", rel, side)
        v = np.einsum("ij,ij->i", rel, nrm)
        w, t = half_w(s), half_t(s)
        ell = np.sqrt((u / w) ** 2 + (v / t) ** 2) - 1.0
        ell = ell * np.minimum(w, t)
        # flat ends: beyond the path's first/last point along its tangent
        e0 = (path[0] - p) @ (path[1] - path[0]) / np.linalg.norm(path[1] - path[0])
        e1 = (p - path[-1]) @ (path[-1] - path[-2]) / np.linalg.norm(path[-1] - path[-2])
        return np.maximum(ell, np.maximum(e0, e1))
    return _contour(sdf, lo, hi)


def _end_ring(path, end, radius_w, radius_t, normal=np.array([0.0, 0.0, 1.0]), n=12, scale=0.7):
    c = path[0] if end == 0 else path[-1]
    tang = path[1] - path[0] if end == 0 else path[-1] - path[-2]
    tang /= np.linalg.norm(tang)
    nrm = normal - (tang @ normal) * tang
    nrm /= np.linalg.norm(nrm)
    side = np.cross(tang, nrm)
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = c + scale * (radius_w * np.cos(th)[:, None] * side + radius_t * np.sin(th)[:, None] * nrm)
    return np.vstack([c, ring])


def shape(name):
    if name == "strap":
        s = np.linspace(0, 1, 61)
        path = np.c_[0.3 * s, 0.02 * np.sin(2 * np.pi * s), np.zeros_like(s)]
        v, f = _swept(path, lambda s: 0.014 + 0 * s, lambda s: 0.0035 + 0 * s,
                      (-0.01, -0.04, -0.01), (0.31, 0.04, 0.01), normal=np.array([0.0, 0.0, 1.0]))
        return v, f, _end_ring(path, 0, 0.014, 0.0035), _end_ring(path, 1, 0.014, 0.0035), "parallel"
    if name == "bipennate":
        s = np.linspace(0, 1, 45)
        path = np.c_[np.zeros_like(s), np.zeros_like(s), 0.22 * s]
        prof = lambda s: 0.004 + np.sin(np.pi * s) ** 1.5  # noqa: E731
        v, f = _swept(path, lambda s: 0.025 * prof(s) / 1.004, lambda s: 0.0175 * prof(s) / 1.004,
                      (-0.03, -0.03, -0.01), (0.03, 0.03, 0.23), normal=np.array([0.0, 1.0, 0.0]))
        tip = 0.004 * 0.025
        return (v, f, _end_ring(path, 0, tip + 0.003, tip + 0.002, np.array([0.0, 1.0, 0.0])),
                _end_ring(path, 1, tip + 0.003, tip + 0.002, np.array([0.0, 1.0, 0.0])),
                "bipennate")
    if name == "fan":
        apex = np.array([0.0, 0.0, 0.0])

        def sdf(p):
            x, y, z = p.T
            r = np.hypot(x, y)
            ang = np.arctan2(y, x)
            half = np.radians(33)
            # the sector between the insertion (r = 10 mm) and the arc (r = 130 mm)
            d_ang = (np.abs(ang - np.pi / 2) - half) * np.maximum(r, 1e-3)
            d_r = np.maximum(0.012 - r, r - 0.13)
            thick = 0.003 + 0.003 * np.clip((r - 0.01) / 0.12, 0, 1)
            d_z = np.abs(z) - thick
            return np.maximum(np.maximum(d_ang, d_r), d_z)
        v, f = _contour(sdf, (-0.09, -0.005, -0.01), (0.09, 0.14, 0.01))
        th = np.radians(np.linspace(90 - 31, 90 + 31, 15))
        origin = np.c_[0.128 * np.cos(th), 0.128 * np.sin(th), np.zeros_like(th)]
        th2 = np.radians(np.linspace(90 - 30, 90 + 30, 7))
        insertion = np.c_[0.013 * np.cos(th2), 0.013 * np.sin(th2), np.zeros_like(th2)] + apex
        return v, f, origin, insertion, "fanned"
    if name == "curved":
        phi = np.linspace(0, np.radians(120), 61)
        path = np.c_[0.07 * np.cos(phi), 0.07 * np.sin(phi), np.zeros_like(phi)]
        rad = lambda s: 0.014 + 0.004 * np.sin(np.pi * s)  # noqa: E731
        v, f = _swept(path, rad, rad, (-0.06, -0.01, -0.03), (0.1, 0.1, 0.03))
        return v, f, _end_ring(path, 0, 0.014, 0.014), _end_ring(path, 1, 0.014, 0.014), "curved"
    raise KeyError(name)
