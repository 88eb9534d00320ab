"""Keep deformed muscle surfaces out of bones: a bone's signed distance on a grid and the smooth
push-out of `motion.surface.collision` (its module docstring: the soft floor ``g``).

A truncated signed distance grid in the bone's body frame (spacing ``h``, 2 mm in
`motion.wrap_surfaces`), built once per mesh: inside/outside from a flood fill of the
voxelised surface (``scipy.ndimage.binary_fill_holes``; on the surface shell, the normal of
the closest face), magnitude = exact distance to the closest of the six faces with the
nearest centroids (Ericson's closest point on a triangle), clamped to +-40 mm. It is read with
tricubic B-spline interpolation (``scipy.ndimage.map_coordinates``, order 3, C2), whose
gradient gives ``n``; up to four push steps per call (the field is not linear over deep
penetrations). ``allowed`` is ``min(0.3 mm, d_rest)`` per vertex: a vertex that already overlaps
the bone at rest (segmentation overlap in LHDL: 561 iliacus vertices start inside the hip
bone) may stay as deep as it was but not go deeper; vertices rigid with that bone keep their
distance anyway. Measured against VTK's exact distance on the LHDL femur within 10 mm of its
surface: max |error| 0.3 mm, p99 0.08 mm (2 mm grid).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from fibres.mesh.closest_point import closest_points_on_triangles

from .binding import smoothstep
from .collision import soft_floor, to_obstacle_frame

__all__ = ["BoneDistance", "BoneObstacle", "CLEARANCE", "SIDE_WEIGHT"]

#: Weight of the rest-side direction in the bone push direction (see `BoneObstacle`).
SIDE_WEIGHT = 4.0

#: Clearance (m) kept from bones by vertices that start at least that far out: covers the
#: distance grid's error (max 0.3 mm, p99 0.08 mm against VTK's exact distance, LHDL femur).
CLEARANCE = 3e-4


@dataclass(frozen=True, eq=False)
class BoneDistance:
    """A bone's signed distance field on a grid in its body frame, tricubic B-spline read-out.

    Build with `BoneDistance.from_mesh`. Distances in metres, negative inside.
    """

    origin: np.ndarray        # (3,) grid corner in the body frame
    spacing: float
    coefficients: np.ndarray  # (nx, ny, nz) prefiltered B-spline coefficients of the SDF
    far: float                # value used outside the grid (positive, far from the bone)
    values: np.ndarray | None = None  # (nx, ny, nz) float32 grid values, for a quick linear pre-pass
    _cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def from_mesh(cls, vertices, faces, *, spacing: float = 1.5e-3, pad: float = 0.02,
                  band: float = 0.04) -> "BoneDistance":
        """Signed distance grid of a closed bone surface (V, 3) in its body frame, metres.

        Inside/outside away from the surface comes from a flood fill of the voxelised surface
        (``scipy.ndimage.binary_fill_holes``), near it from the nearest face's normal; distances
        beyond ``band`` are clamped to +-``band`` (a truncated distance field: only the shell
        near the bone matters for the push-out).
        """
        from scipy.ndimage import binary_dilation, binary_fill_holes, spline_filter
        from scipy.spatial import cKDTree

        v = np.asarray(vertices, dtype=float)
        f = np.asarray(faces, dtype=np.int64)
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        normal = np.cross(b - a, c - a)
        area2 = np.linalg.norm(normal, axis=-1)
        keep = area2 > 1e-20
        a, b, c, normal = a[keep], b[keep], c[keep], normal[keep] / area2[keep, None]
        centroid = (a + b + c) / 3.0
        circum = np.max(np.stack([np.linalg.norm(x - centroid, axis=-1) for x in (a, b, c)]), axis=0)
        lo = v.min(axis=0) - pad
        hi = v.max(axis=0) + pad
        shape = tuple(int(n) for n in np.ceil((hi - lo) / spacing).astype(int) + 1)
        axes = [lo[i] + spacing * np.arange(shape[i]) for i in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        # voxelise the surface with samples finer than the grid, then flood-fill the outside
        n_sub = int(np.clip(np.ceil(2.0 * np.max(circum) / spacing), 1, 6))
        w = np.array([(i, j, n_sub - i - j) for i in range(n_sub + 1) for j in range(n_sub + 1 - i)],
                     dtype=float) / n_sub
        samples = (w[:, 0, None, None] * a[None] + w[:, 1, None, None] * b[None]
                   + w[:, 2, None, None] * c[None]).reshape(-1, 3)
        cell = np.clip(np.rint((samples - lo) / spacing).astype(int), 0, np.array(shape) - 1)
        shell = np.zeros(shape, dtype=bool)
        shell[cell[:, 0], cell[:, 1], cell[:, 2]] = True
        shell = binary_dilation(shell)
        inside = binary_fill_holes(shell) & ~shell
        # distance: beyond 10 mm the nearest centroid (error < a circumradius) with the flood-fill
        # sign; within 10 mm the exact distance to the closest of the six nearest-centroid faces
        tree = cKDTree(centroid)
        d1, _ = tree.query(grid, k=1, distance_upper_bound=band)
        inside_flat = inside.reshape(-1)
        sdf = np.where(inside_flat, -1.0, 1.0) * np.minimum(d1, band)
        near = np.nonzero(d1 < 0.01 + np.max(circum))[0]
        step = 200_000
        for s in range(0, len(near), step):  # chunks of grid points
            sel = near[s:s + step]
            p = grid[sel]
            _, idx = tree.query(p, k=6)
            closest = closest_points_on_triangles(p[:, None, :], a[idx], b[idx], c[idx])   # (P, 6, 3)
            rel = p[:, None, :] - closest
            dist = np.linalg.norm(rel, axis=-1)
            best = np.argmin(dist + 1e-9 * np.arange(6)[None, :], axis=1)
            rows = np.arange(len(p))
            mag = np.minimum(dist[rows, best], band)
            # sign: among the candidates as close as the best (shared edges and vertices), the
            # face the point is most squarely in front of or behind decides
            facing = np.einsum("pkj,pkj->pk", rel, normal[idx]) / np.maximum(dist, 1e-15)
            tie = dist <= dist[rows, best][:, None] + 1e-9
            pick = np.argmax(np.where(tie, np.abs(facing), -1.0), axis=1)
            sign_near = np.where(facing[rows, pick] >= 0, 1.0, -1.0)
            # far from the surface the flood fill decides; on the shell the faces do
            on_shell = shell.reshape(-1)[sel]
            sign = np.where(on_shell, sign_near, np.where(inside.reshape(-1)[sel], -1.0, 1.0))
            sdf[sel] = sign * mag
        sdf = sdf.reshape(shape)
        coeffs = spline_filter(sdf, order=3, mode="nearest")
        return cls(origin=lo, spacing=float(spacing), coefficients=coeffs, far=float(band),
                   values=sdf.astype(np.float32))

    def evaluate_linear(self, points) -> np.ndarray:
        """Trilinear read-out of the grid values (...,): cheap, within ~h^2 |d''| of `evaluate`."""
        from scipy.ndimage import map_coordinates

        p = np.asarray(points, dtype=float)
        grid = self.values if self.values is not None else self.coefficients
        idx = ((p - self.origin) / self.spacing).reshape(-1, 3).T
        out = map_coordinates(grid, idx, order=1, mode="constant", cval=self.far)
        return out.reshape(p.shape[:-1])

    def evaluate(self, points, *, gradient: bool = False):
        """Signed distance (...,) at body-frame points (..., 3); with ``gradient`` also (..., 3)."""
        from scipy.ndimage import map_coordinates

        p = np.asarray(points, dtype=float)
        idx = ((p - self.origin) / self.spacing).reshape(-1, 3).T
        shape = np.array(self.coefficients.shape)
        inside = np.all((idx >= 1) & (idx <= (shape - 2)[:, None]), axis=0)
        value = np.full(idx.shape[1], self.far)
        grad = np.zeros((idx.shape[1], 3))
        if np.any(inside):
            sub = idx[:, inside]
            value[inside] = map_coordinates(self.coefficients, sub, order=3, prefilter=False, mode="nearest")
            if gradient:
                h = 0.1
                for axis in range(3):  # three axes, forward differences of the (C2) spline
                    plus = sub.copy()
                    plus[axis] += h
                    grad[inside, axis] = (
                        map_coordinates(self.coefficients, plus, order=3, prefilter=False, mode="nearest")
                        - value[inside]) / (h * self.spacing)
        value = value.reshape(p.shape[:-1])
        if gradient:
            return value, grad.reshape(p.shape)
        return value


@dataclass(frozen=True, eq=False)
class BoneObstacle:
    """A bone moving with its body, as an obstacle for one muscle.

    Attributes
    ----------
    distance : BoneDistance
    tf_ground_body : (F, 4, 4) float
    allowed : (V,) float
        Per-vertex floor of the signed distance: ``min(CLEARANCE, d_rest)``.
    side : (V, 3) float
        Outward direction of the field at each vertex's rest position, in the body frame (zero
        beyond the truncation band). The push goes along ``normalize(SIDE_WEIGHT side + n)`` (weight 4): a vertex
        keeps to the side of the bone it started on instead of flipping to the nearest surface
        when it is driven past the bone's medial axis (where ``n`` turns over), which keeps the
        pushed surface a well-conditioned function of the poses.
    strength : (V,) float
        1 for vertices that start outside the bone, fading to 0 for those that start more
        than 1 mm inside (those are left alone).
    margin : float
    iterations : int
        Push steps (the field is not exactly linear over deep penetrations).
    """

    distance: BoneDistance
    tf_ground_body: np.ndarray
    allowed: np.ndarray
    side: np.ndarray
    strength: np.ndarray
    margin: float = 5e-4
    iterations: int = 6

    @classmethod
    def bind(cls, distance: BoneDistance, tf_ground_body, rest_vertices, tf_rest_body, *,
             margin: float = 5e-4) -> "BoneObstacle":
        """Obstacle for a surface whose rest vertices (V, 3, ground) start where they start."""
        tf_rest = np.asarray(tf_rest_body, dtype=float)
        local = to_obstacle_frame(tf_rest, np.asarray(rest_vertices, dtype=float)[None])[0]
        d, g = distance.evaluate(local, gradient=True)
        norm = np.linalg.norm(g, axis=-1, keepdims=True)
        side = np.where(norm > 0.5, g / np.maximum(norm, 1e-12), 0.0)
        # vertices that start inside the bone (segmentation overlap) are not pushed: their rest
        # position is already inconsistent with the bone, and pushing them from deep inside a
        # thin part of the bone is ill-conditioned; the strength fades in over 1 mm of depth
        strength = smoothstep(d / 1e-3 + 1.0)
        # the floor keeps CLEARANCE (the grid's distance error) where the rest position allows
        return cls(distance, np.asarray(tf_ground_body, dtype=float), np.minimum(d, CLEARANCE), side,
                   strength, margin)

    def leading(self, n: int) -> "BoneObstacle":
        """The obstacle for the first ``n`` vertices of its surface (per-vertex arrays cut)."""
        return replace(self, allowed=self.allowed[:n], side=self.side[:n], strength=self.strength[:n])

    def push_out(self, vertices) -> np.ndarray:
        """Vertices (F, V, 3) in ground pushed out to ``allowed`` (module docstring)."""
        v = np.array(vertices, dtype=float)
        tf = self.tf_ground_body if self.tf_ground_body.ndim == 3 else self.tf_ground_body[None]
        tf = np.broadcast_to(tf, (v.shape[0], 4, 4))
        # candidates: a cheap linear pre-pass with 3 mm of slack (the spline and the linear
        # read-out of the same grid differ by far less); only they are pushed and re-evaluated
        local = to_obstacle_frame(tf, v)
        near = (self.distance.evaluate_linear(local) - self.allowed[None, :] < self.margin + 3e-3) \
            & (self.strength[None, :] > 0)
        f_idx, v_idx = np.nonzero(near)
        if len(f_idx) == 0:
            return v
        pts = v[f_idx, v_idx]
        rot = tf[f_idx, :3, :3]
        for _ in range(int(self.iterations)):
            loc = np.einsum("pji,pj->pi", rot, pts - tf[f_idx, :3, 3])
            d, g = self.distance.evaluate(loc, gradient=True)
            x = d - self.allowed[v_idx]
            move = (soft_floor(x, self.margin) - x) * self.strength[v_idx]
            if not np.any(move):
                break
            n = g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-12)
            u = SIDE_WEIGHT * self.side[v_idx] + n
            u /= np.linalg.norm(u, axis=-1, keepdims=True)   # >= 3: |w side| is 0 or 4, |n| = 1
            # a step along u changes d by about (g . u) per metre: at most move / 0.7
            rate = np.maximum(np.sum(g * u, axis=-1), 0.7)
            pts = pts + np.einsum("pij,pj->pi", rot, (move / rate)[:, None] * u)
        v[f_idx, v_idx] = pts
        return v
