"""Volume of closed triangle surfaces over frames, and the radial scale that keeps it constant.

The enclosed volume of a closed, consistently oriented triangle surface follows from the
divergence theorem as a sum of signed tetrahedra against the origin,

    6 V = sum_T  v0 . (v1 x v2)

(e.g. Zhang & Chen, "Efficient feature extraction for 2D/3D objects in mesh representation",
ICIP 2001). The deformation of `motion.surface.binding` writes every vertex of every frame as
``v(k) = P + k Q`` where ``k`` is one radial scale per frame (the cross-section of the muscle
belly scales with ``k``). The volume is then a cubic polynomial in ``k`` whose four
coefficients are trilinear sums over the triangles; one Newton solve per frame (vectorised over
frames) gives the ``k`` that restores the rest volume exactly. The root is a smooth function
of ``P`` and ``Q``, so the corrected surface stays a smooth function of the body poses.

The cubic's sums run in one compiled loop (`_cubic_loop`: numba, module level, cached on
disk, so compiled once per environment), triangle by triangle over all frames at once, reading
the vertex-major layout of the binding in order; ``mesh_volume``'s sum in another
(`_volume_loop`, frame by frame: the binding calls it for every step of its volume solve). Why
compiled: docs/decisions.md ("A whole model over a whole trial", "Wrapped muscles' push-out and
volume, compiled").
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["mesh_volume", "volume_cubic", "volume_cubic_vf", "combine_vf", "solve_radial_scale"]

def _as_frames(vertices) -> tuple[np.ndarray, bool]:
    v = np.ascontiguousarray(vertices, dtype=float)
    if v.ndim == 2:
        return v[None], True
    if v.ndim != 3 or v.shape[-1] != 3:
        raise ValueError(f"vertices must be (V, 3) or (F, V, 3), got shape {v.shape}")
    return v, False


def _check_faces(faces, n_vertices: int) -> np.ndarray:
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must be (T, 3), got shape {f.shape}")
    if f.size and (f.min() < 0 or f.max() >= n_vertices):
        raise ValueError("faces index vertices that do not exist")
    return f


def mesh_volume(vertices, faces) -> np.ndarray | float:
    """Signed enclosed volume of a closed triangle surface, per frame.

    Parameters
    ----------
    vertices : (V, 3) or (F, V, 3) float
    faces : (T, 3) int
        Consistently oriented; outward normals give a positive volume.

    Returns
    -------
    float or (F,) float
        Volume in the cube of the vertices' unit.
    """
    v, single = _as_frames(vertices)
    f = _check_faces(faces, v.shape[1])
    out = np.zeros(v.shape[0])
    _volume_loop(v, f, out)
    out /= 6.0
    return float(out[0]) if single else out


def volume_cubic(p, q, faces) -> np.ndarray:
    """Coefficients of the volume of ``P + k Q`` as a cubic in ``k``, per frame.

    Parameters
    ----------
    p, q : (F, V, 3) float
        Fixed part and radially scaled part of every vertex.
    faces : (T, 3) int

    Returns
    -------
    (F, 4) float
        ``c`` with ``volume(k) = c0 + c1 k + c2 k**2 + c3 k**3``.
    """
    p, _ = _as_frames(p)
    q, _ = _as_frames(q)
    if p.shape != q.shape:
        raise ValueError(f"p and q must have the same shape, got {p.shape} and {q.shape}")
    return volume_cubic_vf(p.transpose(1, 0, 2), q.transpose(1, 0, 2), faces)


def volume_cubic_vf(p_vf, q_vf, faces) -> np.ndarray:
    """`volume_cubic` for vertex-major arrays ``(V, F, 3)`` (the binding's internal layout).

    Only the vertices the faces use are read: trailing face-less vertices (riders such as fibre
    points) cost nothing.

    Returns
    -------
    (F, 4) float
    """
    p_vf = np.asarray(p_vf, dtype=float)
    q_vf = np.asarray(q_vf, dtype=float)
    if p_vf.shape != q_vf.shape or p_vf.ndim != 3 or p_vf.shape[-1] != 3:
        raise ValueError(f"p and q must be the same (V, F, 3), got {p_vf.shape} and {q_vf.shape}")
    f = _check_faces(faces, p_vf.shape[0])
    out = np.zeros((p_vf.shape[1], 4))
    _cubic_loop(p_vf, q_vf, f, out)
    return out / 6.0


@njit(cache=True, nogil=True)
def _volume_loop(v, faces, out):  # pragma: no cover
    """``out[f] += v0 . (v1 x v2)`` over the triangles (6 x the volume of frame f)."""
    for f in range(v.shape[0]):
        acc = 0.0
        for t in range(faces.shape[0]):
            i0, i1, i2 = faces[t, 0], faces[t, 1], faces[t, 2]
            x1, y1, z1 = v[f, i1, 0], v[f, i1, 1], v[f, i1, 2]
            x2, y2, z2 = v[f, i2, 0], v[f, i2, 1], v[f, i2, 2]
            acc += (v[f, i0, 0] * (y1 * z2 - z1 * y2) + v[f, i0, 1] * (z1 * x2 - x1 * z2)
                    + v[f, i0, 2] * (x1 * y2 - y1 * x2))
        out[f] += acc


@njit(cache=True, nogil=True)
def _cubic_loop(p, q, faces, out):  # pragma: no cover
    """``out[f] += (p0.(p1 x p2), q0.a + p0.b, q0.b + p0.c, q0.(q1 x q2))`` summed over the
    triangles, with ``a = p1 x p2``, ``b = p1 x q2 + q1 x p2``, ``c = q1 x q2`` (6 x the cubic's
    coefficients); triangle by triangle, all frames of one triangle's corners in order."""
    for t in range(faces.shape[0]):
        i0, i1, i2 = faces[t, 0], faces[t, 1], faces[t, 2]
        for f in range(p.shape[1]):
            p0x, p0y, p0z = p[i0, f, 0], p[i0, f, 1], p[i0, f, 2]
            p1x, p1y, p1z = p[i1, f, 0], p[i1, f, 1], p[i1, f, 2]
            p2x, p2y, p2z = p[i2, f, 0], p[i2, f, 1], p[i2, f, 2]
            q0x, q0y, q0z = q[i0, f, 0], q[i0, f, 1], q[i0, f, 2]
            q1x, q1y, q1z = q[i1, f, 0], q[i1, f, 1], q[i1, f, 2]
            q2x, q2y, q2z = q[i2, f, 0], q[i2, f, 1], q[i2, f, 2]
            ax, ay, az = p1y * p2z - p1z * p2y, p1z * p2x - p1x * p2z, p1x * p2y - p1y * p2x
            bx = p1y * q2z - p1z * q2y + q1y * p2z - q1z * p2y
            by = p1z * q2x - p1x * q2z + q1z * p2x - q1x * p2z
            bz = p1x * q2y - p1y * q2x + q1x * p2y - q1y * p2x
            cx, cy, cz = q1y * q2z - q1z * q2y, q1z * q2x - q1x * q2z, q1x * q2y - q1y * q2x
            out[f, 0] += p0x * ax + p0y * ay + p0z * az
            out[f, 1] += q0x * ax + q0y * ay + q0z * az + p0x * bx + p0y * by + p0z * bz
            out[f, 2] += q0x * bx + q0y * by + q0z * bz + p0x * cx + p0y * cy + p0z * cz
            out[f, 3] += q0x * cx + q0y * cy + q0z * cz


def combine_vf(p_vf, q_vf, k) -> np.ndarray:
    """Frame-major vertices ``(F, V, 3) = P + k Q`` from vertex-major ``P, Q`` (V, F, 3)."""
    p = np.asarray(p_vf, dtype=float)
    w = np.asarray(q_vf, dtype=float) * np.asarray(k, dtype=float)[None, :, None]
    w += p
    return np.ascontiguousarray(w.transpose(1, 0, 2))


def solve_radial_scale(coefficients, target, *, start=None, bounds=(0.25, 4.0), iterations=30) -> np.ndarray:
    """The radial scale ``k`` per frame at which the cubic volume equals ``target``.

    Newton's method from ``start`` (default 1), safeguarded by bisection inside ``bounds``;
    vectorised over frames with a fixed iteration count, so ``k`` is a smooth function of the
    coefficients wherever the root is simple.

    Parameters
    ----------
    coefficients : (F, 4) float
        From `volume_cubic`.
    target : float or (F,) float
        The volume to reach (the rest volume).
    start : (F,) float, optional
    bounds : (2,) float, keyword-only
        Search interval for ``k``; a frame with no root inside it gets the bound nearest to one.

    Returns
    -------
    (F,) float
    """
    c = np.asarray(coefficients, dtype=float)
    if c.ndim != 2 or c.shape[1] != 4:
        raise ValueError(f"coefficients must be (F, 4), got shape {c.shape}")
    target = np.broadcast_to(np.asarray(target, dtype=float), c.shape[:1])
    lo = np.full(c.shape[0], float(bounds[0]))
    hi = np.full(c.shape[0], float(bounds[1]))
    k = np.ones(c.shape[0]) if start is None else np.clip(np.asarray(start, dtype=float), lo, hi)

    def g(x):
        return c[:, 0] + x * (c[:, 1] + x * (c[:, 2] + x * c[:, 3])) - target

    sign_lo = np.sign(g(lo))
    for _ in range(int(iterations)):
        val = g(k)
        same = np.sign(val) == sign_lo
        lo = np.where(same, k, lo)
        hi = np.where(same, hi, k)
        slope = c[:, 1] + k * (2.0 * c[:, 2] + 3.0 * k * c[:, 3])
        with np.errstate(divide="ignore", invalid="ignore"):
            step = k - val / slope
        inside = np.isfinite(step) & (step > lo) & (step < hi)
        k = np.where(inside, step, 0.5 * (lo + hi))
    # polish: plain Newton steps at the bracketed root reach round-off
    for _ in range(2):
        slope = c[:, 1] + k * (2.0 * c[:, 2] + 3.0 * k * c[:, 3])
        with np.errstate(divide="ignore", invalid="ignore"):
            step = k - g(k) / slope
        k = np.where(np.isfinite(step), step, k)
    return k
