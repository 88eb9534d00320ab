"""Fibre quality: numbers that say whether a muscle's fibres represent it, without looking.

For one decomposition (fibres, the closed surface they were made in and the attachment
patches, `fibres.attachments.patch`):

- ``empty_5mm``: share of the muscle volume farther than 5 mm from every fibre, and
  ``empty_spacing``: farther than one fibre spacing ``sqrt(volume / (N * mean length))``
  (the side of the square each fibre would own in a cross-section). The volume is sampled
  at the centres of a regular grid of about `VOLUME_SAMPLES` cells inside the surface
  (`fibres.mesh.inside.inside_grid`); fibres are
  resampled every `FIBRE_STEP` so point-to-polyline distances are exact to within half of
  it (each sample's nearest fibre point from a k-d tree, searched only up to the larger of
  the two distances asked about).
- ``turn_max``, ``turn_p95``: the largest angle between consecutive segments of a fibre
  (degrees), its maximum and 95th percentile over the fibres.
- ``origin_covered``, ``insertion_covered``: share of each attachment patch's area within
  5 mm of a fibre end.
- ``outside``: inner fibre points outside the surface (by ray parity,
  `fibres.mesh.surface_distance.SurfaceGrid.inside`).

`LIMITS` are the sensible bounds a warning checks (`FibreQuality.problems`; the volume's limit
applies to both shares, so few fibres in a big muscle are not flagged for their spacing).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..mesh.inside import inside_grid
from ..mesh.surface_distance import SurfaceGrid
from ..attachments.patch_map import _sub_centroids

__all__ = ["FibreQuality", "FibreQualityWarning", "fibre_quality", "LIMITS", "VOLUME_SAMPLES",
           "FIBRE_STEP"]

#: volume grid points inside the surface (about)
VOLUME_SAMPLES = 40_000
#: fibre resampling step, metres
FIBRE_STEP = 5e-4
#: distance that counts as "near a fibre", metres
NEAR = 5e-3
#: the limits of `FibreQuality.problems` (shares, degrees, counts)
LIMITS = {"empty_5mm": 0.10, "turn_max": 60.0, "turn_p95": 30.0, "origin_covered": 0.75,
          "insertion_covered": 0.75, "outside": 0}


class FibreQualityWarning(UserWarning):
    """A muscle's fibres fall below the usual limits (`LIMITS`)."""


@dataclass(frozen=True)
class FibreQuality:
    """Quality numbers of one muscle's fibres (module docstring); shares in [0, 1]."""

    empty_5mm: float
    empty_spacing: float
    spacing_mm: float
    turn_max: float
    turn_p95: float
    origin_covered: float
    insertion_covered: float
    outside: int

    def as_dict(self) -> dict:
        return {k: (round(float(v), 4) if isinstance(v, float) else v)
                for k, v in asdict(self).items()}

    def problems(self) -> list:
        """Human-readable list of the limits (`LIMITS`) this muscle's fibres break."""
        out = []
        # empty both in absolute terms and for this many fibres (a run with few fibres leaves
        # volume more than 5 mm from them, but not more than their own spacing)
        if self.empty_5mm > LIMITS["empty_5mm"] and self.empty_spacing > LIMITS["empty_5mm"]:
            out.append(f"{self.empty_5mm:.0%} of the volume is more than 5 mm from a fibre "
                       f"({self.empty_spacing:.0%} more than their spacing, "
                       f"{self.spacing_mm:.1f} mm)")
        if self.turn_max > LIMITS["turn_max"]:
            out.append(f"a fibre turns by {self.turn_max:.0f} degrees")
        if self.turn_p95 > LIMITS["turn_p95"]:
            out.append(f"95th percentile of the fibres' sharpest turns {self.turn_p95:.0f} "
                       "degrees")
        for end in ("origin", "insertion"):
            share = getattr(self, f"{end}_covered")
            if share < LIMITS[f"{end}_covered"]:
                out.append(f"only {share:.0%} of the {end} area is within 5 mm of a fibre end")
        if self.outside > LIMITS["outside"]:
            out.append(f"{self.outside} fibre points lie outside the surface")
        return out


def _turns(points):
    seg = np.diff(points, axis=1)
    length = np.linalg.norm(seg, axis=2)
    dot = np.einsum("npk,npk->np", seg[:, 1:], seg[:, :-1])
    den = length[:, 1:] * length[:, :-1]
    cos = np.where(den > 1e-18, dot / np.maximum(den, 1e-300), 1.0)
    ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return ang.max(axis=1) if ang.shape[1] else np.zeros(len(points))


def _resampled(points, step):
    out = []
    for fib in points:
        seg = np.linalg.norm(np.diff(fib, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        t = np.linspace(0.0, s[-1], max(int(np.ceil(s[-1] / step)) + 1, 2))
        out.append(np.stack([np.interp(t, s, fib[:, d]) for d in range(3)], axis=1))
    return np.concatenate(out)


def _patch_samples(vertices, faces, face_mask):
    tri = vertices[faces[face_mask]]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    w = _sub_centroids(2)               # the centroids of the 4 midpoint sub-triangles
    pts = np.einsum("sk,tkd->tsd", w, tri).reshape(-1, 3)
    return pts, np.repeat(area / len(w), len(w))


def fibre_quality(points, vertices, faces, origin_faces, insertion_faces) -> FibreQuality:
    """Quality numbers of fibres ``points`` (N, P, 3) in a closed surface (metres).

    ``origin_faces``, ``insertion_faces``: (T,) bool patch faces
    (`fibres.attachments.patch.attachment_patches`)."""
    pts = np.asarray(points, dtype=np.float64)
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    tri = v[f]
    volume = float(np.einsum("ij,ij->i", tri[:, 0],
                             np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)
    h = (abs(volume) / VOLUME_SAMPLES) ** (1.0 / 3.0)
    inside = inside_grid(v, f, h)
    dense = _resampled(pts, FIBRE_STEP)
    # built without median splits (sliding midpoint): faster to build, the same nearest points
    tree = cKDTree(dense, balanced_tree=False, compact_nodes=False)
    n, length = len(pts), float(np.linalg.norm(np.diff(pts, axis=1), axis=2).sum(axis=1).mean())
    spacing = float(np.sqrt(abs(volume) / max(n * length, 1e-300)))
    # only "farther than NEAR / spacing" is asked: a search bounded just above both is exact for
    # every distance up to the bound and inf beyond (the same shares, a third less searching)
    bound = max(NEAR, spacing) * (1.0 + 1e-9)
    dist = tree.query(inside, distance_upper_bound=bound)[0] if len(inside) else np.zeros(0)
    empty5 = float((dist > NEAR).mean()) if dist.size else 0.0
    empty_sp = float((dist > spacing).mean()) if dist.size else 0.0
    turns = _turns(pts)
    covered = []
    for mask, col in ((origin_faces, 0), (insertion_faces, -1)):
        mask = np.asarray(mask, dtype=bool)
        if not mask.any():
            covered.append(float("nan"))
            continue
        sp, sw = _patch_samples(v, f, mask)
        d = cKDTree(pts[:, col]).query(sp)[0]
        covered.append(float(sw[d <= NEAR].sum() / sw.sum()))
    outside = int((~SurfaceGrid(v, f, reach=0.0).inside(pts[:, 1:-1].reshape(-1, 3))).sum())
    return FibreQuality(empty5, empty_sp, spacing * 1e3, float(turns.max(initial=0.0)),
                        float(np.percentile(turns, 95)) if turns.size else 0.0,
                        covered[0], covered[1], outside)
