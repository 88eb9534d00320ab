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
    template : fibres.templates.Template
    plan : DecompositionPlan
        The discrete choices; pass it back (``decompose(..., plan=bundle.plan)``) to
        decompose a deformed copy of the same mesh consistently.
    flags : mapping of str -> (N,) bool
        ``trimmed`` / ``reconstructed`` (attachment filtering, Kohout §3.4) and others.
    notes : tuple of str
        Decisions worth knowing (several loops in a slice, refined contours, repairs ...).
    box : fibres.fitting.Box
        The fitted template box of this surface.
    """

    points: np.ndarray
    rs: np.ndarray
    template: object
    plan: DecompositionPlan
    flags: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))
    notes: tuple = ()
    box: object = None

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
                                   self.plan, dict(self.flags), self.notes, self.box))

    @property
    def n_fibres(self) -> int:
        """N."""
        return int(self.points.shape[0])

    @property
    def resolution(self) -> int:
        """R, segments per fibre."""
        return int(self.points.shape[1] - 1)

    def lengths(self) -> np.ndarray:
        """(N,) polyline length of every fibre, metres."""
        return np.linalg.norm(np.diff(self.points, axis=1), axis=2).sum(axis=1)


def _unpickle_bundle(points, rs, spec, plan, flags, notes, box):
    template = template_from_spec(spec) if isinstance(spec, tuple) else spec
    return FibreBundle(points, rs, template, plan, flags, notes, box)
