"""Binding a rest muscle surface to its action lines and attachment bodies (step 1 of
`motion.surface.binding`: Kohout, Kellnhofer & Martelli, GRAPP 2012; Kohout et al., Computer
Graphics Forum 2014; rotation-minimising frames after Wang et al., ACM TOG 2008).

Every vertex gets, once at rest, its place relative to each action line (segment, fraction and
local coordinates in the line's frame there), its inverse-distance weights between several lines
and its rigid weights near the attachment landmarks; all of it is folded into the sparse
matrices of `motion.surface.binding.SurfaceBinding`, whose `deform` then moves the surface for
every frame of a motion.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .binding import SurfaceBinding, _check_tf, _ro, smoothstep
from .curves import (any_perpendicular, arc_fractions, catmull_rom_weights, closest_on_polyline, resample_polylines,
                     smoothed_tangents, rotation_minimizing_frames)
from .volume import mesh_volume

__all__ = ["bind_surface"]


def bind_surface(rest_vertices, faces, rest_curves, tf_rest_origin, tf_rest_insertion,
                 origin_points, insertion_points, *, n_samples: int = 40,
                 rigid_radius: float | None = None, blend_radius: float | None = None,
                 line_blend: float | None = None, rest_anchors=None, free_vertices=None,
                 tangent_smoothing: float = 0.0) -> SurfaceBinding:
    """Bind a rest surface to its action lines and attachment bodies.

    Parameters
    ----------
    rest_vertices : (V, 3) float
        Closed, outward-oriented surface in ground at the rest pose (metres).
    faces : (T, 3) int
    rest_curves : sequence of L (P_l, 3) float
        Action lines in ground at the rest pose (any point count; resampled by arc length).
    tf_rest_origin, tf_rest_insertion : (4, 4) float
        Rest poses in ground of the origin and insertion bodies.
    origin_points, insertion_points : (K, 3) float
        Attachment landmarks in ground at the rest pose.
    n_samples : int, keyword-only
        Samples per action line.
    rigid_radius, blend_radius : float, keyword-only
        Vertices within ``rigid_radius`` of an attachment landmark move rigidly with its body;
        the rigid weight falls smoothly to 0 at ``blend_radius``. Defaults: 2 % and 5 % of
        the mean rest action-line length.
    line_blend : float, keyword-only
        ``delta`` of the inverse-distance weights between several lines (default 2 % of the
        mean rest line length).
    rest_anchors : sequence of L (K_l,) int or None, keyword-only
        Indices of anchor points (e.g. the path points that are always present) in each rest
        line, first and last included; `SurfaceBinding.deform` then matches arc length piece by
        piece between anchors, so a piece fixed on one body does not slide over that body as
        the free pieces stretch. None: one piece (global arc length).
    tangent_smoothing : float, keyword-only
        Arc length (m, at rest) over which the line tangents that orient the cross-sections
        are averaged (`motion.surface.curves.smoothed_tangents`, standard deviation); 0: none.
    free_vertices : (V,) bool or index array or None, keyword-only
        Vertices that get no rigid attachment zone (``w_o = w_i = 0``, all belly): points
        carried with the surface that are not part of it, e.g. fibre points, whose ends the
        caller moves with their bodies itself (`analysis.run`). None: none.

    Returns
    -------
    SurfaceBinding
    """
    verts = np.asarray(rest_vertices, dtype=float)
    tri = np.asarray(faces, dtype=np.int64)
    if verts.ndim != 2 or verts.shape[1] != 3:
        raise ValueError(f"rest_vertices must be (V, 3), got shape {verts.shape}")
    if tri.ndim != 2 or tri.shape[1] != 3 or tri.min() < 0 or tri.max() >= len(verts):
        raise ValueError("faces must be (T, 3) indices into rest_vertices")
    if len(rest_curves) == 0:
        raise ValueError("at least one rest action line is needed")
    n = int(n_samples)
    tf_o = _check_tf(tf_rest_origin, "tf_rest_origin")[0]
    tf_i = _check_tf(tf_rest_insertion, "tf_rest_insertion")[0]
    arc = np.linspace(0.0, 1.0, n)

    fractions = []
    for k, c in enumerate(rest_curves):
        idx = None if rest_anchors is None else rest_anchors[k]
        fractions.append(None if idx is None or len(idx) < 3 else _ro(arc_fractions(c, idx)))
    curves = [resample_polylines(np.asarray(c, dtype=float), n) for c in rest_curves]
    lengths = np.array([np.sum(np.linalg.norm(np.diff(c, axis=0), axis=-1)) for c in curves])
    if np.any(lengths <= 0):
        raise ValueError("a rest action line has zero length")
    mean_len = float(np.mean(lengths))
    rigid = 0.02 * mean_len if rigid_radius is None else float(rigid_radius)
    blend = 0.05 * mean_len if blend_radius is None else float(blend_radius)
    if blend <= rigid:
        raise ValueError("blend_radius must exceed rigid_radius")
    delta = 0.02 * mean_len if line_blend is None else float(line_blend)
    sigma = float(tangent_smoothing) / (mean_len / (n - 1)) if tangent_smoothing else 0.0

    # rigid weights from the distance to the attachment landmarks
    from scipy.spatial import cKDTree

    def rigid_weight(points):
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if len(pts) == 0:
            return np.zeros(len(verts))
        d, _ = cKDTree(pts).query(verts)
        return 1.0 - smoothstep((d - rigid) / (blend - rigid))

    w_o = rigid_weight(origin_points)
    w_i = rigid_weight(insertion_points)
    if free_vertices is not None:
        w_o[free_vertices] = 0.0
        w_i[free_vertices] = 0.0
    over = w_o + w_i
    scale = np.where(over > 1.0, 1.0 / np.maximum(over, 1e-30), 1.0)
    w_o, w_i = w_o * scale, w_i * scale
    w_b = 1.0 - w_o - w_i

    # rest frames: start normal perpendicular to the first tangent, no twist at rest
    rest_frames = []
    n_l = len(curves)
    rows, cols = [], []
    vals_c, vals_t, vals_n, vals_b = [], [], [], []
    dists, per_line = [], []
    for l, c in enumerate(curves):  # loop over action lines (few)
        tan = smoothed_tangents(c[None], sigma)
        fr = rotation_minimizing_frames(c[None], any_perpendicular(tan[:, 0]), tangents=tan)[0]
        rest_frames.append(_ro(fr))
        j, t, d = closest_on_polyline(verts, c)
        c_idx, c_w = catmull_rom_weights(j, t, len(c))
        centre = np.einsum("vk,vkj->vj", c_w, c[c_idx])
        basis = (1.0 - t)[:, None, None] * fr[j] + t[:, None, None] * fr[j + 1]  # (V, 3, 3)
        local = np.linalg.solve(basis, (verts - centre)[..., None])[..., 0]       # (V, 3)
        dists.append(d)
        per_line.append((j, t, local, c_idx, c_w))
    d = np.stack(dists, axis=1)  # (V, L)
    w_line = 1.0 / (d * d + delta * delta) ** 2
    w_line /= np.sum(w_line, axis=1, keepdims=True)
    n_v = len(verts)
    rows_c, cols_c, vals_f = [], [], []
    for l, (j, t, local, c_idx, c_w) in enumerate(per_line):
        w = w_b * w_line[:, l]
        for offset, share in ((0, 1.0 - t), (1, t)):
            rows.append(np.arange(n_v))
            cols.append(l * n + j + offset)
            vals_f.append(w * share)
            vals_n.append(w * share * local[:, 0])
            vals_b.append(w * share * local[:, 1])
            vals_t.append(w * share * local[:, 2])
        for k in range(c_idx.shape[1]):   # the centre: spline weights on up to 4 samples
            rows_c.append(np.arange(n_v))
            cols_c.append(l * n + c_idx[:, k])
            vals_c.append(w * c_w[:, k])
    rows = np.concatenate(rows)
    cols = np.concatenate(cols)
    rows_c = np.concatenate(rows_c)
    cols_c = np.concatenate(cols_c)
    # rigid parts: w * (R local + t) = sum_j (w local_j) R[:, j] + w t, on 8 extra feature rows
    rig_rows, rig_cols, rig_vals = [], [], []
    for slot, (w, tf) in enumerate(((w_o, tf_o), (w_i, tf_i))):
        inv = np.linalg.inv(tf)
        local = verts @ inv[:3, :3].T + inv[:3, 3]
        sel = np.nonzero(w > 0)[0]
        for j, val in enumerate((local[sel, 0], local[sel, 1], local[sel, 2], np.ones(len(sel)))):
            rig_rows.append(sel)
            rig_cols.append(np.full(len(sel), 2 * n * n_l + 4 * slot + j))
            rig_vals.append(w[sel] * val)
    fixed = sp.csr_matrix((np.concatenate(vals_c + vals_t + rig_vals),
                           (np.concatenate([rows_c, rows] + rig_rows),
                            np.concatenate([cols_c, cols + n * n_l] + rig_cols))), shape=(n_v, 2 * n * n_l + 8))
    frame_matrix = sp.csr_matrix((np.concatenate(vals_f), (rows, cols)), shape=(n_v, n * n_l))
    radial = sp.csr_matrix((np.concatenate(vals_n + vals_b),
                            (np.concatenate([rows, rows]), np.concatenate([cols, cols + n * n_l]))),
                           shape=(n_v, 2 * n * n_l))
    volume = mesh_volume(verts, tri)
    if not volume > 0:
        raise ValueError(f"the rest surface must be closed with outward normals (volume {volume:.3g})")
    return SurfaceBinding(
        rest_vertices=_ro(verts), faces=_ro(tri, np.int64), n_samples=n,
        rest_frames=tuple(rest_frames), tf_rest_origin=_ro(tf_o), tf_rest_insertion=_ro(tf_i),
        weight_origin=_ro(w_o), weight_insertion=_ro(w_i), weight_belly=_ro(w_b),
        fixed_matrix=fixed, radial_matrix=radial, rest_volume=float(volume),
        rest_lengths=_ro(lengths), arc_fraction=_ro(arc), anchor_fractions=tuple(fractions),
        frame_matrix=frame_matrix, tangent_sigma=sigma)
