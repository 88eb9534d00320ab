"""`FibreBundle`: the result of decomposing one muscle surface into fibres."""
from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from .plan import DecompositionPlan, template_from_spec, template_spec

__all__ = ["FibreBundle"]


@dataclass(frozen=True)
class FibreBundle:
    """Fibre polylines of one muscle (Kohout et al. 2012), with how they were made.

    Attributes
    ----------
    points : (N, P, 3) float
        Fibre polylines in metres, P = resolution + 1, from the origin towards the
        insertion. Fibre ``k`` comes from template parameters ``rs[k]``.
    rs : (N, 2) float
        Sobol template parameters of the fibres.
    template : fibres.template.templates.Template
    plan : DecompositionPlan
        The discrete choices; pass it back (``decompose(..., plan=bundle.plan)``) to
        decompose a deformed copy of the same mesh consistently.
    flags : mapping of str -> (N,) bool
        ``trimmed`` / ``reconstructed`` (attachment filtering, Kohout §3.4) and others.
    notes : tuple of str
        Decisions worth knowing (several loops in a slice, refined contours, repairs ...).
    box : fibres.fit.fitting.Box or None
        The fitted template box of this surface (planar slicing; None for harmonic).
    surface : (vertices (V, 3), faces (T, 3)) or None
        The surface the fibres were made in (what `quality` measures against).
    """

    points: np.ndarray
    rs: np.ndarray
    template: object
    plan: DecompositionPlan
    flags: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))
    notes: tuple = ()
    box: object = None
    surface: tuple = None

    def __post_init__(self):
        pts = np.array(self.points, dtype=np.float64, copy=True)
        rs = np.array(self.rs, dtype=np.float64, copy=True)
        if pts.ndim != 3 or pts.shape[2] != 3 or pts.shape[1] < 2:
            raise ValueError(f"points must be (N, P, 3) with P >= 2, got {pts.shape}")
        if rs.shape != (pts.shape[0], 2):
            raise ValueError(f"rs must be (N, 2) = ({pts.shape[0]}, 2), got {rs.shape}")
        flags = {}
        for name, value in dict(self.flags).items():
            arr = np.array(value, dtype=bool, copy=True)
            if arr.shape != (pts.shape[0],):
                raise ValueError(f"flag {name!r} must be ({pts.shape[0]},), got {arr.shape}")
            arr.flags.writeable = False
            flags[name] = arr
        pts.flags.writeable = False
        rs.flags.writeable = False
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "rs", rs)
        object.__setattr__(self, "flags", MappingProxyType(flags))
        object.__setattr__(self, "notes", tuple(str(n) for n in self.notes))

    def __reduce__(self):
        # mappingproxy fields (flags, the Template's params) are not picklable
        return (_unpickle_bundle, (self.points, self.rs, template_spec(self.template),
                                   self.plan, dict(self.flags), self.notes, self.box,
                                   self.surface))

    @property
    def n_fibres(self) -> int:
        """N."""
        return int(self.points.shape[0])

    @property
    def resolution(self) -> int:
        """R, segments per fibre."""
        return int(self.points.shape[1] - 1)

    @property
    def quality(self):
        """`fibres.finishing.quality.FibreQuality` of these fibres in their surface (computed once, on
        first use: ~0.1 s for a real muscle). The attachment patches are the plan's
        (harmonic slicing) or made from the plan's rest landmarks
        (`fibres.attachments.patch`); None without a surface."""
        cached = self.__dict__.get("_quality")
        if cached is None and self.surface is not None:
            from .finishing.quality import fibre_quality
            v, f = self.surface
            of, if_ = _patch_faces(self.plan, f)
            cached = fibre_quality(self.points, v, f, of, if_)
            object.__setattr__(self, "_quality", cached)
        return cached

    def lengths(self) -> np.ndarray:
        """(N,) polyline length of every fibre, metres."""
        return np.linalg.norm(np.diff(self.points, axis=1), axis=2).sum(axis=1)


def _patch_faces(plan, faces):
    """(origin_faces, insertion_faces) of a plan: its own patches, or patches made from its
    rest landmarks on its rest surface (cached on the plan object)."""
    if hasattr(plan, "origin_faces"):
        return tuple(fm if fm.any() else vm[faces].any(axis=1) for fm, vm in
                     ((plan.origin_faces, plan.origin), (plan.insertion_faces, plan.insertion)))
    cache = plan.__dict__.get("_patch_faces")
    if cache is None:
        from .attachments.patch import attachment_patches
        from .slicing.harmonic_field import mesh_edges
        v = plan.rest_vertices
        edges, _ = mesh_edges(faces, len(v))
        p = attachment_patches(v, faces, plan.rest_origin, plan.rest_insertion, edges)
        cache = tuple(fm if fm.any() else vm[faces].any(axis=1) for fm, vm in
                      ((p.origin_faces, p.origin), (p.insertion_faces, p.insertion)))
        plan.__dict__["_patch_faces"] = cache
    return cache


def _unpickle_bundle(points, rs, spec, plan, flags, notes, box, surface=None):
    template = template_from_spec(spec) if isinstance(spec, tuple) else spec
    return FibreBundle(points, rs, template, plan, flags, notes, box, surface)
