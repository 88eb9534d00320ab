"""Keep deformed muscle surfaces out of wrap objects (and, with `motion.surface.bone_obstacles`,
bones): smooth signed-distance push-out.

Every obstacle has a signed distance ``d`` (negative inside) and an outward direction ``n`` in
its own frame, which moves with a body (``tf_ground_obstacle`` (F, 4, 4)). A vertex whose
distance is below ``allowed + margin`` is moved along ``n`` to the distance

    allowed + g(d - allowed),   g(x) = x                       for x >= m
                                g(x) = m exp((x - m) / m)      for x <  m

(``m`` = margin). ``g`` is C1, equals the identity outside the margin (vertices farther than
``m`` do not move at all) and maps any penetration depth into the open shell (0, m], so a
pushed vertex never ends inside and the result is a continuous, once-differentiable function
of the poses -- as needed for finite-difference moment arms. Penetrating parts flatten against
the obstacle like a muscle pressed on a pulley; `motion.surface.binding` then re-solves the
cross-section scale so the volume is kept.

Before the push-out, wrap objects squeeze the muscle's cross-section through its thickness
(`WrapObstacle.squeezer`, called by `motion.surface.binding`): the layers facing the object are
flattened in order into the room between the action line and the surface, so fibres bend
smoothly onto a pulley instead of at the corner a pure projection leaves where they cross it.

- Wrap objects (OpenSim's WrapCylinder, WrapSphere, WrapEllipsoid): analytic distances. The
  cylinder is treated as infinite along its axis inside its length and the push fades out
  smoothly (quintic) over one radius beyond the ends; the ellipsoid uses the scaled-radius
  approximation ``d = (|p / r| - 1) min(r)``, exact on the surface. WrapTorus is not pushed.
- Bones: `motion.surface.bone_obstacles` (the same soft floor on a signed-distance grid).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from .binding import smoothstep

__all__ = ["WrapObstacle", "soft_floor", "wrap_obstacle", "to_obstacle_frame"]

#: Knee of the through-thickness squeeze (`WrapObstacle.squeeze`): offsets reaching less than
#: this fraction of the room between the line and a wrap object are not changed.
SQUEEZE_KNEE = 0.3


def soft_floor(x, margin: float) -> np.ndarray:
    """``g(x)``: identity for ``x >= margin``, ``margin * exp((x - margin) / margin)`` below (C1)."""
    x = np.asarray(x, dtype=float)
    m = float(margin)
    return np.where(x >= m, x, m * np.exp(np.minimum(x - m, 0.0) / m))


def to_obstacle_frame(tf: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vertices (F, V, 3) in ground to the obstacle frame, tf (F, 4, 4) or (4, 4)."""
    tf = np.asarray(tf, dtype=float)
    if tf.ndim == 2:
        tf = tf[None]
    return np.matmul(v - tf[:, None, :3, 3], tf[:, :3, :3])   # row vectors: (v - t) R = R^T (v - t)


def _to_ground_dir(tf: np.ndarray, d: np.ndarray) -> np.ndarray:
    tf = np.asarray(tf, dtype=float)
    if tf.ndim == 2:
        tf = tf[None]
    return np.matmul(d, tf[:, :3, :3].transpose(0, 2, 1))


@dataclass(frozen=True, eq=False)
class WrapObstacle:
    """An analytic wrap object as an obstacle.

    Attributes
    ----------
    kind : str
        "cylinder", "sphere" or "ellipsoid".
    tf_ground_obstacle : (F, 4, 4) or (4, 4) float
        The wrap frame in ground (body pose @ ``tf_body_wrap``).
    radii : (3,) float
        Cylinder: (radius, radius, length); sphere: (r, r, r); ellipsoid: its dimensions.
    margin : float
        Push-out shell thickness ``m`` in metres.
    inset : float or (V,) float
        Depth (m) by which each vertex may enter the object: the obstacle a vertex meets is the
        object's surface moved inwards by its inset (0: the wrap surface itself). `motion.wrap_surfaces`
        sets the muscle's local half-thickness (`motion.surface.thickness`), so that the wrap
        object guides the centre line while the tissue around it may lie inside the wrap radius.
    knee : float or None
        Knee of the through-thickness squeeze (`squeezer`); None: no squeeze, push-out only.
    """

    kind: str
    tf_ground_obstacle: np.ndarray
    radii: np.ndarray
    margin: float = 5e-4
    inset: object = 0.0
    knee: float | None = SQUEEZE_KNEE

    def __post_init__(self):
        if self.kind not in ("cylinder", "sphere", "ellipsoid"):
            raise ValueError(f"kind must be cylinder, sphere or ellipsoid, got {self.kind!r}")
        object.__setattr__(self, "tf_ground_obstacle", np.asarray(self.tf_ground_obstacle, dtype=float))
        object.__setattr__(self, "radii", np.asarray(self.radii, dtype=float).reshape(3))
        inset = np.asarray(self.inset, dtype=float)
        if inset.ndim > 1 or np.any(inset < 0) or not np.all(np.isfinite(inset)):
            raise ValueError("inset must be a non-negative number or a (V,) array")
        object.__setattr__(self, "inset", inset)

    @property
    def squeezes(self) -> bool:
        """True when the object squeezes the cross-section before the push-out (``knee`` set)."""
        return self.knee is not None

    def _inset_for(self, n_vertices: int) -> np.ndarray:
        """(V,) insets for a surface of ``n_vertices`` vertices."""
        if self.inset.ndim == 0:
            return np.full(n_vertices, float(self.inset))
        if self.inset.shape[0] != n_vertices:
            raise ValueError(f"inset has {self.inset.shape[0]} values for {n_vertices} vertices")
        return self.inset

    def signed_distance(self, vertices) -> np.ndarray:
        """(F, V) signed distance of ground vertices (F, V, 3) to the object; negative inside
        (the inset is not subtracted)."""
        return self._distance_direction(to_obstacle_frame(self.tf_ground_obstacle, np.asarray(vertices, float)))[0]

    def _distance_direction(self, p):
        if self.kind == "cylinder":
            rad = np.hypot(p[..., 0], p[..., 1])
            d = rad - self.radii[0]
            n = np.stack([p[..., 0], p[..., 1], np.zeros_like(rad)], axis=-1) / np.maximum(rad, 1e-12)[..., None]
            half = 0.5 * self.radii[2] if np.isfinite(self.radii[2]) else np.inf
            over = np.maximum(np.abs(p[..., 2]) - half, 0.0) if np.isfinite(half) else np.zeros_like(rad)
            window = 1.0 - smoothstep(over / self.radii[0])
            return d, n, window
        if self.kind == "sphere":
            rad = np.linalg.norm(p, axis=-1)
            return rad - self.radii[0], p / np.maximum(rad, 1e-12)[..., None], np.ones_like(rad)
        scaled = p / self.radii
        rad = np.linalg.norm(scaled, axis=-1)
        d = (rad - 1.0) * float(np.min(self.radii))
        grad = scaled / self.radii
        n = grad / np.maximum(np.linalg.norm(grad, axis=-1), 1e-12)[..., None]
        return d, n, np.ones_like(rad)

    def leading(self, n: int) -> "WrapObstacle":
        """The obstacle for the first ``n`` vertices of its surface (per-vertex insets cut)."""
        return self if self.inset.ndim == 0 else replace(self, inset=self.inset[:n])

    def squeezer(self, centres):
        """The through-thickness squeeze of offsets from ``centres`` (F, V, 3): a function of offsets.

        A deformed vertex is ``c + w`` (``c`` its point on the action line, ``w`` its scaled
        cross-section offset). With ``h = d(c) - margin`` the room between the centre and the
        push-out shell and ``n`` the object's outward direction at the centre, the inward
        depth ``t = -w . n`` of the offset is mapped to ``h soft(t / h)`` when ``h > 0``,
        ``soft(z) = z`` for ``z <= a`` and ``1 - (1 - a) exp(-(z - a) / (1 - a))`` beyond (C1,
        increasing, below 1; knee ``a = SQUEEZE_KNEE = 0.3``), and to ``min(t, h)`` when
        ``h <= 0`` (a centre within the shell or inside, as the chords of a resampled arc are:
        the layers facing the object land on the shell's outer face, a smooth surface, rather
        than on the rippled chords, whose ripple the fibre polylines would alias); continuous
        in ``h``. The tangential part of ``w`` is kept. So the layers of a muscle pressed on a pulley are flattened
        progressively, in order, into the room left between its line and the surface, instead
        of every penetrating point being projected onto the surface: a fibre that would cross
        the surface at an angle then bends over a length comparable to the muscle's thickness,
        not at a corner (a polyline sliding through such a corner has a length that wobbles
        with the pose: on the pulley test of `tests/analysis/test_run_cylinders.py` fibre
        moment arms were off by up to 19 % of R with the projection alone). Faded out like
        `push_out` beyond a cylinder's ends; what still penetrates is left to `push_out`.

        The clearance, direction and window depend on the centres only, so they are computed
        once here and the returned function (called for every radial scale ``k`` of the volume
        solve) costs a few array operations.

        Parameters
        ----------
        centres : (F, V, 3) float
            Ground points ``c``.

        Returns
        -------
        callable
            ``squeeze(offsets (F, V, 3)) -> (F, V, 3)`` squeezed offsets ``w``.
        """
        c = np.asarray(centres, dtype=float)
        d, n, window = self._distance_direction(to_obstacle_frame(self.tf_ground_obstacle, c))
        inward = _to_ground_dir(self.tf_ground_obstacle, -n) * window[..., None]   # windowed -n
        h = d - self.margin
        h = h + self._inset_for(c.shape[-2])
        inv_h = 1.0 / np.maximum(h, 1e-300)
        a = float(SQUEEZE_KNEE if self.knee is None else self.knee)

        def squeeze(offsets) -> np.ndarray:
            w = np.asarray(offsets, dtype=float)
            t = np.einsum("fvk,fvk->fv", w, inward)          # windowed inward depth
            z = np.clip(t * inv_h, a, 1e6)
            squeezed = np.where(h > 0.0, np.where(t <= a * h, t, h * (1.0 - (1.0 - a) * np.exp((a - z) / (1.0 - a)))),
                                np.minimum(t, h))
            return w - (t - squeezed)[..., None] * inward

        return squeeze

    def push_out(self, vertices) -> np.ndarray:
        """Vertices (F, V, 3) in ground, pushed out of the object (see the module docstring).

        One compiled pass over the vertices (`_push_loop`); the same distance, direction and
        window as `_distance_direction`."""
        v = np.asarray(vertices, dtype=float)
        tf = self.tf_ground_obstacle
        tf = np.ascontiguousarray(tf[None] if tf.ndim == 2 else tf)
        frames = v[None] if v.ndim == 2 else v
        if frames.shape[0] != tf.shape[0] and tf.shape[0] > 1:
            if frames.shape[0] != 1:
                raise ValueError(f"{frames.shape[0]} frames of vertices for {tf.shape[0]} obstacle poses")
            frames = np.broadcast_to(frames, (tf.shape[0],) + frames.shape[1:])
        frames = np.ascontiguousarray(frames)
        out = np.empty_like(frames)
        _push_loop(frames, tf, _KIND_CODES[self.kind], self.radii,
                   np.ascontiguousarray(self._inset_for(frames.shape[1]), dtype=float), float(self.margin), out)
        return out[0] if v.ndim == 2 and tf.shape[0] == 1 else out


_KIND_CODES = {"cylinder": 0, "sphere": 1, "ellipsoid": 2}


@njit(cache=True, nogil=True)
def _push_loop(v, tf, kind, radii, inset, margin, out):  # pragma: no cover
    """`WrapObstacle.push_out` of every vertex ``v`` (F, V, 3) into ``out``: to the obstacle frame
    ``tf`` (F or 1, 4, 4), signed distance and window (cylinder 0, sphere 1, ellipsoid 2, as
    `WrapObstacle._distance_direction`), the soft floor's move along the outward direction (the
    ellipsoid's in its scaled space), back to ground."""
    r_min = min(radii[0], min(radii[1], radii[2]))
    half = 0.5 * radii[2]
    for f in range(v.shape[0]):
        g = f if tf.shape[0] > 1 else 0
        for i in range(v.shape[1]):
            wx, wy, wz = v[f, i, 0] - tf[g, 0, 3], v[f, i, 1] - tf[g, 1, 3], v[f, i, 2] - tf[g, 2, 3]
            px = tf[g, 0, 0] * wx + tf[g, 1, 0] * wy + tf[g, 2, 0] * wz
            py = tf[g, 0, 1] * wx + tf[g, 1, 1] * wy + tf[g, 2, 1] * wz
            pz = tf[g, 0, 2] * wx + tf[g, 1, 2] * wy + tf[g, 2, 2] * wz
            window = 1.0
            if kind == 0:
                rad = math.hypot(px, py)
                d = rad - radii[0]
                if math.isfinite(half):
                    x = min(max(abs(pz) - half, 0.0) / radii[0], 1.0)
                    window = 1.0 - x * x * x * (x * (6.0 * x - 15.0) + 10.0)
            elif kind == 1:
                rad = math.sqrt(px * px + py * py + pz * pz)
                d = rad - radii[0]
            else:
                sx, sy, sz = px / radii[0], py / radii[1], pz / radii[2]
                rad = math.sqrt(sx * sx + sy * sy + sz * sz)
                d = (rad - 1.0) * r_min
            x = d + inset[i]
            move = 0.0
            if x < margin:
                move = (margin * math.exp((x - margin) / margin) - x) * window
            if move == 0.0:
                out[f, i, 0], out[f, i, 1], out[f, i, 2] = v[f, i, 0], v[f, i, 1], v[f, i, 2]
                continue
            inv = 1.0 / max(rad, 1e-12)
            if kind == 0:
                dx, dy, dz = move * px * inv, move * py * inv, 0.0
            elif kind == 1:
                dx, dy, dz = move * px * inv, move * py * inv, move * pz * inv
            else:           # in the scaled space, so that the surface point lands on the ellipsoid
                scale = ((d + move) / r_min + 1.0) * inv
                dx, dy, dz = sx * scale * radii[0] - px, sy * scale * radii[1] - py, sz * scale * radii[2] - pz
            for k in range(3):
                out[f, i, k] = v[f, i, k] + tf[g, k, 0] * dx + tf[g, k, 1] * dy + tf[g, k, 2] * dz


def wrap_obstacle(wrap, tf_ground_body, *, margin: float = 5e-4, inset=0.0,
                  knee: float | None = SQUEEZE_KNEE) -> WrapObstacle | None:
    """A `WrapObstacle` for a `motion.osim.model.WrapObject` on a body with pose (F, 4, 4).

    ``inset`` (scalar or (V,)) and ``knee``: see `WrapObstacle`. Returns None for a torus (not
    pushed; documented limitation).
    """
    tf = np.asarray(tf_ground_body, dtype=float) @ np.asarray(wrap.tf_body_wrap, dtype=float)
    if wrap.kind == "cylinder":
        radii = (wrap.radius, wrap.radius, wrap.length if np.isfinite(wrap.length) else np.inf)
    elif wrap.kind == "sphere":
        radii = (wrap.radius,) * 3
    elif wrap.kind == "ellipsoid":
        radii = tuple(wrap.dimensions)
    else:
        return None
    return WrapObstacle(wrap.kind, tf, np.asarray(radii, dtype=float), margin, inset, knee)
