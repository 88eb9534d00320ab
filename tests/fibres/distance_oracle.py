"""Brute-force oracle for `fibres.mesh.surface_distance` (tests only): every point against every
triangle, the soft-min blend of the module docstring written on dense (points x triangles)
arrays. The closest points use `np.select` over Ericson's cases (an independent writing of
`fibres.mesh.closest_point`)."""
import numpy as np

from fibres.mesh.surface_distance import KAPPA, OFFSET_FAR, OFFSET_NEAR


def closest_points(tri, p):
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


def brute(x, vertices, faces, reach, tau, chunk=32, offset=False):
    """The blend over every triangle within ``reach`` (numpy, chunks of points)."""
    tri = vertices[faces]                                                    # (T, 3, 3)
    nrm = _unit_normals(tri)[None]
    s, n = np.empty(len(x)), np.empty((len(x), 3))
    for a in range(0, len(x), chunk):  # chunks of points: (chunk, T) pairs at a time
        diff = x[a:a + chunk, None] - closest_points(tri[None], x[a:a + chunk, None])
        d = np.sqrt(np.einsum("ntk,ntk->nt", diff, diff))
        d = np.where(d <= reach, d, np.inf)
        s[a:a + chunk], n[a:a + chunk] = _blend_numpy(d, diff, nrm, tau, KAPPA, offset)
    return s, n
