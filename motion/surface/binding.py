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

The linear part is precomputed as sparse (V, n L) matrices (`motion.surface.bind.bind_surface`):
a frame costs a few sparse products, one cubic volume sum and a Newton solve.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .curves import (resample_polylines, smoothed_tangents, rotation_minimizing_frames, transport_vector, twist_angle,
                     twist_frames)
from .volume import combine_vf, mesh_volume, solve_radial_scale, volume_cubic_vf

__all__ = ["RowBlocks", "SurfaceBinding", "SurfaceFrames", "smoothstep"]


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


class RowBlocks:
    """A sparse matrix (R, C) kept for products with wide dense matrices (C, K): its rows grouped
    by their pattern of nonzero columns, each group one small dense block (rows x its columns).

    Method: ``A @ X`` is, group by group, the block times the rows of ``X`` at the group's columns
    (one dense BLAS product) written to the group's rows. The sums are CSR's, in another order
    (round-off only). Why: a bound surface's rows have a few nonzeros each on a handful of
    patterns (one per line segment: 39 for 40 samples) and ``K = 3 F`` is in the thousands;
    scipy's CSR kernel does one axpy per nonzero, several times slower per multiply-add than the
    blocked BLAS product (docs/decisions.md, "Blocked rider products"). Narrow products (``K <
    WIDE``) and matrices with more than ``max(16, R / 8)`` patterns keep the CSR product; the
    groups are made at the first wide product.
    """

    WIDE = 48

    def __init__(self, matrix):
        a = sp.csr_matrix(matrix, dtype=float, copy=True)
        a.sum_duplicates()
        a.sort_indices()
        self.csr, self.shape, self._groups = a, a.shape, None

    def _grouped(self):
        """The groups ``[(rows, cols, block)]`` (rows a slice where contiguous), or ``[]``: CSR."""
        if self._groups is None:
            a, n_r = self.csr, self.shape[0]
            nnz = np.diff(a.indptr)
            width = int(nnz.max(initial=0))
            where = (np.repeat(np.arange(n_r), nnz), np.arange(a.nnz) - np.repeat(a.indptr[:-1], nnz))
            cols = np.full((n_r, width), -1, dtype=np.int64)   # each row's columns, padded with -1
            cols[where] = a.indices
            vals = np.zeros((n_r, width))
            vals[where] = a.data
            keys, inverse = np.unique(cols, axis=0, return_inverse=True)
            groups = []
            if n_r and len(keys) <= max(16, n_r // 8):
                order = np.argsort(inverse.ravel(), kind="stable")
                starts = np.searchsorted(inverse.ravel()[order], np.arange(len(keys) + 1))
                for g, key in enumerate(keys):
                    rows = order[starts[g]:starts[g + 1]]
                    used = key[key >= 0]
                    block = np.ascontiguousarray(vals[rows][:, :len(used)])
                    if rows[-1] - rows[0] == len(rows) - 1:
                        rows = slice(int(rows[0]), int(rows[-1]) + 1)     # contiguous: no scatter
                    groups.append((rows, used, block))
            self._groups = groups
        return self._groups

    def __matmul__(self, x) -> np.ndarray:
        """``A @ x`` for a dense ``x`` (C, K): (R, K) float."""
        x = np.asarray(x, dtype=float)
        groups = self._grouped() if x.ndim == 2 and x.shape[1] >= self.WIDE else []
        if not groups:
            return np.asarray(self.csr @ x)
        out = np.empty((self.shape[0],) + x.shape[1:])
        for rows, cols, block in groups:
            if len(cols):
                out[rows] = block @ x[cols]
            else:
                out[rows] = 0.0
        return out


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
        fixed_feat, radial_feat = self._features(centres, frames, tf_origin, tf_insertion)
        n_v, f_count = self.rest_vertices.shape[0], centres.shape[0]
        fixed, radial, _ = self._split(0)
        p = (fixed @ fixed_feat).reshape(n_v, f_count, 3)
        q = (radial @ radial_feat).reshape(n_v, f_count, 3)
        return (p, q, self._rider_frames(frames, riders, rider_major)) if riders else (p, q)

    def _rider_frames(self, frames, riders: int, rider_major: bool) -> np.ndarray:
        """The line frames (R, F, 3, 3) at the last ``riders`` vertices ((F, R, 3, 3) unless
        ``rider_major``), from the lines' frames (F, L, n, 3, 3)."""
        f_n = frames.shape[0]
        feat = np.ascontiguousarray(frames.reshape(f_n, -1, 9).transpose(1, 0, 2)).reshape(-1, f_n * 9)
        cache = self.__dict__.setdefault("_frame_rows", {})
        if riders not in cache:
            cache[riders] = RowBlocks(self.frame_matrix[-int(riders):])
        at = (cache[riders] @ feat).reshape(int(riders), f_n, 3, 3)
        return at if rider_major else np.ascontiguousarray(at.transpose(1, 0, 2, 3))

    def _features(self, centres, frames, tf_origin, tf_insertion):
        """The right-hand sides of the sparse products, feature-major: ``fixed`` (2 n L + 8, 3 F)
        (all lines' centres and tangents, then the columns of the origin and insertion body
        transforms, the rigid parts) and ``radial`` (2 n L, 3 F) (normals, binormals)."""
        f_count = centres.shape[0]
        tf_o = np.broadcast_to(_check_tf(tf_origin, "tf_origin", f_count), (f_count, 4, 4))
        tf_i = np.broadcast_to(_check_tf(tf_insertion, "tf_insertion", f_count), (f_count, 4, 4))
        fixed_feat = np.concatenate([centres.reshape(f_count, -1, 3), frames[..., 2].reshape(f_count, -1, 3),
                                     tf_o[:, :3, :].transpose(0, 2, 1), tf_i[:, :3, :].transpose(0, 2, 1)],
                                    axis=1)
        radial_feat = np.concatenate([frames[..., 0].reshape(f_count, -1, 3),
                                      frames[..., 1].reshape(f_count, -1, 3)], axis=1)
        fixed_feat = np.ascontiguousarray(fixed_feat.transpose(1, 0, 2)).reshape(fixed_feat.shape[1], -1)
        radial_feat = np.ascontiguousarray(radial_feat.transpose(1, 0, 2)).reshape(radial_feat.shape[1], -1)
        return fixed_feat, radial_feat

    def _split(self, apart: int) -> tuple:
        """The fixed and radial rows of the leading vertices and, for the last ``apart`` ones,
        ``[fixed | radial]`` in one matrix, as `RowBlocks` (made once per ``apart``, kept on the
        binding)."""
        cache = self.__dict__.setdefault("_splits", {})
        if apart not in cache:
            n_s = self.rest_vertices.shape[0] - apart
            cache[apart] = (RowBlocks(self.fixed_matrix[:n_s]), RowBlocks(self.radial_matrix[:n_s]),
                            RowBlocks(sp.hstack([self.fixed_matrix[n_s:], self.radial_matrix[n_s:]], format="csr")))
        return cache[apart]

    def _free(self, curves, tf_origin, tf_insertion, anchors, preserve_volume, rider_frames, apart, keep):
        """`deform` without obstacles. The leading vertices' parts P, Q give the cubic and ``k``;
        the last ``apart`` (riders) are ``P + k Q`` in one product of their rows of ``[fixed |
        radial]`` with the features, the radial ones scaled by ``k`` per frame (the same sums)."""
        centres, frames = self.line_frames(curves, tf_origin, tf_insertion, anchors)
        fixed_feat, radial_feat = self._features(centres, frames, tf_origin, tf_insertion)
        n_f, n_s = centres.shape[0], self.rest_vertices.shape[0] - apart
        fixed, radial, both = self._split(apart)
        p = (fixed @ fixed_feat).reshape(n_s, n_f, 3)
        q = (radial @ radial_feat).reshape(n_s, n_f, 3)
        target = self.rest_volume
        if preserve_volume:
            coeffs = volume_cubic_vf(p, q, self.faces)
            k = solve_radial_scale(coeffs, target)
            volume = np.sum(coeffs * np.stack([np.ones_like(k), k, k * k, k * k * k], axis=1), axis=1)
        else:
            k = np.ones(n_f)
            volume = mesh_volume(combine_vf(p, q, k), self.faces)
        keep = n_f if keep is None else min(int(keep), n_f)
        vertices = combine_vf(p[:, :keep], q[:, :keep], k[:keep])
        riders = None
        if apart:
            radial_feat.reshape(-1, n_f, 3)[...] *= k[None, :, None]
            riders = (both @ np.vstack([fixed_feat, radial_feat])).reshape(apart, n_f, 3)
            riders.setflags(write=False)
        at = self._rider_frames(frames, rider_frames, bool(apart)) if rider_frames else None
        return SurfaceFrames(vertices, k, volume, target, at, riders)

    def deform(self, curves, tf_origin, tf_insertion, *, anchors=None, obstacles=(), preserve_volume: bool = True,
               push_iterations: int = 5, rider_frames: int = 0, riders_apart: int = 0,
               keep_vertices: int | None = None) -> SurfaceFrames:
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
        keep_vertices : int, optional, keyword-only
            ``SurfaceFrames.vertices`` at the first this many frames only (the other outputs
            cover every frame).

        Returns
        -------
        SurfaceFrames
        """
        if len(curves) != self.n_lines:
            raise ValueError(f"expected {self.n_lines} curves, got {len(curves)}")
        apart = int(riders_apart)
        if apart and int(self.faces.max()) >= len(self.rest_vertices) - apart:
            raise ValueError(f"riders_apart={apart}: the faces use some of the last {apart} vertices")
        if not obstacles:
            return self._free(curves, tf_origin, tf_insertion, anchors, preserve_volume, rider_frames, apart,
                              keep_vertices)
        at = None
        if rider_frames:
            p, q, at = self.affine_parts(curves, tf_origin, tf_insertion, anchors, riders=rider_frames,
                                         rider_major=bool(apart))
        else:
            p, q = self.affine_parts(curves, tf_origin, tf_insertion, anchors)   # (V, F, 3)
        target = self.rest_volume
        k = solve_radial_scale(volume_cubic_vf(p, q, self.faces), target) if preserve_volume else np.ones(p.shape[1])
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
        return SurfaceFrames(vertices[:keep_vertices, :n_s], k, volume, target, at,
                             vertices[:, n_s:].transpose(1, 0, 2) if apart else None)
