"""Action-line driven deformation of a muscle surface: bind once at rest, deform every frame.

Method (after Kohout, Kellnhofer & Martelli, "Fast deformation for modelling of musculoskeletal
system", GRAPP 2012, and Kohout et al., "Real-time modelling of fibrous muscle", Computer
Graphics Forum 2014, who drive the muscle surface by its action lines; the frames along the
line are the rotation-minimising frames of Wang et al., ACM TOG 2008):

1. Bind (rest pose, once). Every action line is resampled at ``n`` points equally spaced in
   arc length and given rotation-minimising frames (normal, binormal, tangent). Each vertex is
   projected onto the nearest point of each line (segment ``j``, fraction ``t``) and its offset
   is stored as local coordinates ``(x, y, z)`` in the linearly interpolated frame there.
   Several action lines (gluteus maximus 1-3) share a vertex through inverse-distance weights
   ``w_l ~ (d_l**2 + delta**2)**-2`` of the rest distances. Vertices near the origin
   (insertion) landmarks get a rigid weight ``w_o`` (``w_i``): 1 within ``rigid_radius``,
   falling with a C2 quintic smoothstep to 0 at ``blend_radius``; the belly weight is
   ``w_b = 1 - w_o - w_i``.
2. Deform (every frame, vectorised). The current lines are resampled the same way -- piecewise
   between anchor points (the path points that are always present) when they are given, so a
   stretch of line fixed on one body keeps its samples fixed on that body; their frames
   start from the origin body's rotation of the rest start frame (transported onto the current
   tangent) and the twist that the insertion body imposes at the far end is spread linearly in
   arc length. A vertex goes to

       v = w_o T_o v_rest + w_i T_i v_rest
           + w_b sum_l w_l [c_l(s) + k (x N_l(s) + y B_l(s)) + z T_l(s)]

   i.e. its material point slides with the arc-length parameter (the belly stretches along the
   line) while the cross-section scales by ``k``. Since the surface is affine in ``k`` its
   volume is a cubic in ``k``; ``k`` is solved per frame so that the volume equals the rest
   volume (`motion.surface.volume`). Wrap objects then squeeze the cross-section offsets
   ``k (x N + y B)`` through the thickness where they point into the object
   (`motion.surface.collision.WrapObstacle.squeezer`), obstacles (wrap objects, bones)
   push what still penetrates out (`motion.surface.collision`), and ``k`` is re-solved by a
   fixed number of secant steps (on the vertices the faces use; trailing face-less riders,
   e.g. fibre points, are squeezed and pushed once at the final ``k``: every step acts on each
   vertex alone, so that gives the same numbers).
   All steps are smooth functions of the body poses and the line points, so finite
   differences of anything measured on the surface are meaningful.

The linear part is precomputed as sparse (V, n L) matrices: a frame costs a few sparse products,
one cubic volume sum and a Newton solve.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .curves import (any_perpendicular, arc_fractions, catmull_rom_weights, closest_on_polyline, resample_polylines,
                     smoothed_tangents, rotation_minimizing_frames, transport_vector, twist_angle, twist_frames)
from .volume import combine_into_q, combine_vf, mesh_volume, solve_radial_scale, volume_cubic_vf

__all__ = ["SurfaceBinding", "SurfaceFrames", "bind_surface", "smoothstep"]


def smoothstep(x) -> np.ndarray:
    """C2 quintic step: 0 for x <= 0, 1 for x >= 1, ``6x^5 - 15x^4 + 10x^3`` between."""
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def _ro(a, dtype=float) -> np.ndarray:
    arr = np.array(a, dtype=dtype, copy=True)
    arr.setflags(write=False)
    return arr


def _check_tf(tf, name: str, n_frames: int | None = None) -> np.ndarray:
    tf = np.asarray(tf, dtype=float)
    tf = tf[None] if tf.shape == (4, 4) else tf
    if tf.ndim != 3 or tf.shape[1:] != (4, 4):
        raise ValueError(f"{name} must be (4, 4) or (F, 4, 4), got shape {tf.shape}")
    if n_frames is not None and tf.shape[0] not in (1, n_frames):
        raise ValueError(f"{name} has {tf.shape[0]} frames, expected {n_frames}")
    return tf


@dataclass(frozen=True, eq=False)
class SurfaceFrames:
    """A deformed surface over a motion.

    Attributes
    ----------
    vertices : (F, V, 3) float
        Deformed vertices in ground.
    radial_scale : (F,) float
        The cross-section scale ``k`` of the belly in each frame.
    volume : (F,) float
        Enclosed volume of the final surface in each frame.
    rest_volume : float
    rider_frames : (F, R, 3, 3) float or None
        With ``deform(..., rider_frames=R)``: the line frames (columns normal, binormal,
        tangent) at the last ``R`` vertices (the riders); (R, F, 3, 3) with ``riders_apart``.
    riders : (A, F, 3) float or None
        With ``deform(..., riders_apart=A)``: the last ``A`` vertices, rider-major; ``vertices``
        then holds the others.
    """

    vertices: np.ndarray
    radial_scale: np.ndarray
    volume: np.ndarray
    rest_volume: float
    rider_frames: np.ndarray | None = None
    riders: np.ndarray | None = None

    def __post_init__(self):
        for name in ("vertices", "radial_scale", "volume", "rider_frames", "riders"):
            if getattr(self, name) is None:
                continue
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.flags.writeable:   # own data: frozen without copying; a view: a frozen copy
                arr = arr if arr.flags.owndata else _ro(arr)
                arr.setflags(write=False)
            object.__setattr__(self, name, arr)    # read-only already: frozen by `deform`

    @property
    def volume_error(self) -> np.ndarray:
        """(F,) float: relative volume change ``volume / rest_volume - 1``."""
        return self.volume / self.rest_volume - 1.0


@dataclass(frozen=True, eq=False)
class SurfaceBinding:
    """A rest surface bound to its action lines and attachment bodies; see the module docstring.

    Build it with `bind_surface`; call `deform` for a whole motion.
    """

    rest_vertices: np.ndarray        # (V, 3) in ground at the rest pose
    faces: np.ndarray                # (T, 3)
    n_samples: int
    rest_frames: tuple               # per line: (n, 3, 3) rest frames
    tf_rest_origin: np.ndarray       # (4, 4)
    tf_rest_insertion: np.ndarray    # (4, 4)
    weight_origin: np.ndarray        # (V,)
    weight_insertion: np.ndarray     # (V,)
    weight_belly: np.ndarray         # (V,)
    fixed_matrix: sp.csr_matrix      # (V, 2 n L + 8): [centres; tangents; origin R|t; insertion R|t]
    radial_matrix: sp.csr_matrix     # (V, 2 n L): rows act on [normals; binormals]
    rest_volume: float
    rest_lengths: np.ndarray         # (L,)
    arc_fraction: np.ndarray         # (n,)
    anchor_fractions: tuple = ()     # per line: (K,) rest arc fractions of the anchors, or None
    frame_matrix: sp.csr_matrix | None = None   # (V, n L): belly weights of the line frames
    tangent_sigma: float = 0.0       # Gaussian smoothing of the line tangents, in samples
    caps: object | None = None       # end cross-sections turning with the bodies (`motion.surface.caps`)

    @property
    def n_lines(self) -> int:
        """L, the number of action lines driving the surface."""
        return len(self.rest_frames)

    # ------------------------------------------------------------------------- frames
    def line_frames(self, curves, tf_origin, tf_insertion, anchors=None):
        """Resampled current lines and their twisted rotation-minimising frames.

        Returns
        -------
        centres : (F, L, n, 3) float
        frames : (F, L, n, 3, 3) float
        """
        f_count = np.asarray(curves[0]).shape[0] if np.asarray(curves[0]).ndim == 3 else 1
        tf_o = _check_tf(tf_origin, "tf_origin", f_count)
        tf_i = _check_tf(tf_insertion, "tf_insertion", f_count)
        rot_o = tf_o[:, :3, :3] @ self.tf_rest_origin[:3, :3].T      # (F, 3, 3) rest -> now
        rot_i = tf_i[:, :3, :3] @ self.tf_rest_insertion[:3, :3].T
        centres, frames = [], []
        for l, (curve, rest) in enumerate(zip(curves, self.rest_frames)):  # loop over lines (few)
            c = np.asarray(curve, dtype=float)
            fractions = self.anchor_fractions[l]
            idx = None if anchors is None or fractions is None else anchors[l]
            c = resample_polylines(c if c.ndim == 3 else c[None], self.n_samples, anchors=idx,
                                   anchor_fractions=None if idx is None else fractions)
            c = np.broadcast_to(c, (max(f_count, c.shape[0]),) + c.shape[1:])
            tan = smoothed_tangents(c, self.tangent_sigma)
            carried_t0 = np.einsum("fij,j->fi", rot_o, rest[0, :, 2])
            carried_n0 = np.einsum("fij,j->fi", rot_o, rest[0, :, 0])
            r0 = transport_vector(carried_n0, carried_t0, tan[:, 0])
            fr = rotation_minimizing_frames(c, r0, tangents=tan)
            carried_te = np.einsum("fij,j->fi", rot_i, rest[-1, :, 2])
            carried_ne = np.einsum("fij,j->fi", rot_i, rest[-1, :, 0])
            want = transport_vector(carried_ne, carried_te, tan[:, -1])
            angle = twist_angle(fr[:, -1, :, 0], want, tan[:, -1])
            # zero at rest: the rest frames are this same construction with identity rotations
            fr = twist_frames(fr, angle, self.arc_fraction)
            if self.caps is not None:
                fr = self.caps.turn(fr, rot_o, rot_i, l)
            centres.append(c)
            frames.append(fr)
        return np.stack(centres, axis=1), np.stack(frames, axis=1)

    # ------------------------------------------------------------------------- deform
    def affine_parts(self, curves, tf_origin, tf_insertion, anchors=None, *, riders: int = 0,
                     rider_major: bool = False):
        """The two parts of ``v(k) = P + k Q`` for every frame, vertex-major.

        Returns
        -------
        p, q : (V, F, 3) float
        rider_frames : (F, R, 3, 3) float, only with ``riders = R > 0``
            The line frames interpolated at the last R vertices (`SurfaceFrames.rider_frames`);
            (R, F, 3, 3) with ``rider_major``.
        """
        centres, frames = self.line_frames(curves, tf_origin, tf_insertion, anchors)
        if riders:
            f_n = frames.shape[0]
            feat = np.ascontiguousarray(frames.reshape(f_n, -1, 9).transpose(1, 0, 2)).reshape(-1, f_n * 9)
            at = np.asarray(self.frame_matrix[-int(riders):] @ feat).reshape(int(riders), f_n, 3, 3)
            return self._affine(centres, frames, tf_origin, tf_insertion) + (
                at if rider_major else np.ascontiguousarray(at.transpose(1, 0, 2, 3)),)
        return self._affine(centres, frames, tf_origin, tf_insertion)

    def _affine(self, centres, frames, tf_origin, tf_insertion):
        """`affine_parts` from the resampled lines and their frames."""
        f_count = centres.shape[0]
        n_v = self.rest_vertices.shape[0]
        tf_o = np.broadcast_to(_check_tf(tf_origin, "tf_origin", f_count), (f_count, 4, 4))
        tf_i = np.broadcast_to(_check_tf(tf_insertion, "tf_insertion", f_count), (f_count, 4, 4))
        # feature rows (each an (F, 3) series): all lines' centres and tangents, then the columns
        # of the origin and insertion body transforms (rigid parts); one sparse product each
        fixed_feat = np.concatenate([centres.reshape(f_count, -1, 3), frames[..., 2].reshape(f_count, -1, 3),
                                     tf_o[:, :3, :].transpose(0, 2, 1), tf_i[:, :3, :].transpose(0, 2, 1)],
                                    axis=1)
        radial_feat = np.concatenate([frames[..., 0].reshape(f_count, -1, 3),
                                      frames[..., 1].reshape(f_count, -1, 3)], axis=1)
        fixed_feat = np.ascontiguousarray(fixed_feat.transpose(1, 0, 2)).reshape(fixed_feat.shape[1], -1)
        radial_feat = np.ascontiguousarray(radial_feat.transpose(1, 0, 2)).reshape(radial_feat.shape[1], -1)
        p = np.asarray(self.fixed_matrix @ fixed_feat).reshape(n_v, f_count, 3)
        q = np.asarray(self.radial_matrix @ radial_feat).reshape(n_v, f_count, 3)
        return p, q

    def deform(self, curves, tf_origin, tf_insertion, *, anchors=None, obstacles=(), preserve_volume: bool = True,
               push_iterations: int = 5, rider_frames: int = 0, riders_apart: int = 0) -> SurfaceFrames:
        """Deform the rest surface for every frame of a motion.

        Parameters
        ----------
        curves : sequence of L (F, P_l, 3) float
            The current action lines in ground, in the order given to `bind_surface`; any
            number of points (trailing NaN rows are padding), resampled here by arc length.
        tf_origin, tf_insertion : (F, 4, 4) float
            Current poses in ground of the origin and insertion bodies.
        anchors : sequence of L (F, K_l) int or None, keyword-only
            Per line, the indices in each frame's polyline of the anchor points given to
            `bind_surface` (``rest_anchors``); the arc length is then matched piecewise
            between anchors (`motion.surface.curves.resample_polylines`).
        obstacles : sequence, keyword-only
            Objects with ``push_out(vertices (F, V, 3)) -> (F, V, 3)``
            (`motion.surface.collision`), applied in order after the volume solve.
        preserve_volume : bool, keyword-only
            Solve the radial scale so the volume stays the rest volume (else ``k = 1``).
        push_iterations : int, keyword-only
            Secant updates of ``k`` after the obstacles pushed vertices out.
        rider_frames : int, keyword-only
            Also return the line frames at the last this many vertices (`SurfaceFrames`).
        riders_apart : int, keyword-only
            The last this many (face-less) vertices apart, rider-major (``SurfaceFrames.riders``).

        Returns
        -------
        SurfaceFrames
        """
        if len(curves) != self.n_lines:
            raise ValueError(f"expected {self.n_lines} curves, got {len(curves)}")
        at = None
        apart = int(riders_apart)
        if apart and int(self.faces.max()) >= len(self.rest_vertices) - apart:
            raise ValueError(f"riders_apart={apart}: the faces use some of the last {apart} vertices")
        if rider_frames:
            p, q, at = self.affine_parts(curves, tf_origin, tf_insertion, anchors, riders=rider_frames,
                                         rider_major=bool(apart))
        else:
            p, q = self.affine_parts(curves, tf_origin, tf_insertion, anchors)   # (V, F, 3)
        target = self.rest_volume
        if preserve_volume:
            coeffs = volume_cubic_vf(p, q, self.faces)
            k = solve_radial_scale(coeffs, target)
        else:
            k = np.ones(p.shape[1])
        if not obstacles:
            n_s = p.shape[0] - apart
            vertices = combine_vf(p[:n_s], q[:n_s], k)
            riders = combine_into_q(p[n_s:], q[n_s:], k) if apart else None   # q: this call's own
            if preserve_volume:
                volume = np.sum(coeffs * np.stack([np.ones_like(k), k, k * k, k * k * k], axis=1), axis=1)
            else:
                volume = mesh_volume(vertices, self.faces)
            return SurfaceFrames(vertices, k, volume, target, at, riders)
        p = np.ascontiguousarray(p.transpose(1, 0, 2))
        q = np.ascontiguousarray(q.transpose(1, 0, 2))

        rounds = 1 if len(obstacles) < 2 else 2

        def pusher(pp, qq, obs):
            squeezers = [o.squeezer(pp) for o in obs if getattr(o, "squeezes", hasattr(o, "squeezer"))]

            def pushed(kk):
                w = kk[:, None, None] * qq
                # wrap objects first squeeze the cross-section through its thickness (smooth in s
                # and in the poses, layers keep their order); the push-outs then remove what is left
                for squeeze in squeezers:
                    w = squeeze(w)
                v = pp + w
                # several obstacles: alternate projections, so a vertex squeezed between two
                # bones is not pushed out of one into the other
                for _ in range(rounds):
                    for obstacle in obs:
                        v = obstacle.push_out(v)
                return v, mesh_volume(v, self.faces)

            return pushed

        # every step acts on each vertex alone and the volume needs only the faces' vertices: the
        # secant steps move the leading vertices the faces use, the trailing face-less ones
        # (riders, e.g. fibre points) are placed once at the final k -- the same numbers
        n_used = int(self.faces.max()) + 1
        leading = [o.leading(n_used) if hasattr(o, "leading") else None for o in obstacles]
        split = n_used < p.shape[1] and preserve_volume and push_iterations > 0 and all(
            o is not None for o in leading)
        pushed = pusher(p[:, :n_used], q[:, :n_used], leading) if split else pusher(p, q, obstacles)
        vertices, volume = pushed(k)
        if preserve_volume and push_iterations > 0:
            # secant on vol(k) - target, starting with the cross-section estimate vol ~ k**2
            k_prev, g_prev = k, volume - target
            k = k * np.sqrt(target / np.maximum(volume, 1e-30))
            for _ in range(int(push_iterations)):
                vertices, volume = pushed(k)
                g = volume - target
                dk = k - k_prev
                dg = g - g_prev
                ok = np.abs(dg) > 1e-18 * max(target, 1e-30)
                k_next = np.where(ok, k - g * dk / np.where(ok, dg, 1.0), k)
                k_prev, g_prev = k, g
                k = np.clip(k_next, 0.25, 4.0)
            vertices, volume = (pusher(p, q, obstacles) if split else pushed)(k)
        n_s = vertices.shape[1] - apart     # riders apart: a rider-major copy of the last ones
        return SurfaceFrames(vertices[:, :n_s] if apart else vertices, k, volume, target, at,
                             vertices[:, n_s:].transpose(1, 0, 2) if apart else None)


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
