"""What `motion.wrap_surfaces` needs to know about one muscle surface: `MuscleSurfaceSpec`.

The fields mirror the fibre-model TOML (``docs/INTERFACE.md``), already read and converted to
metres by the caller:

- ``frame = "ground"``: mesh and landmarks in ground at the rest pose ``rest_pose``
  (coordinate values, SI; unspecified coordinates take the model's default values).
- ``frame = "<body name>"``: mesh and landmarks in that body's frame (the rest pose then only
  matters for the action lines and the other attachment body).
- ``frame = "bodies"``: NMSBuilder/LHDL export, one scanner frame in which every body frame is
  the identity; see `motion.surface.rest` for how the matching pose is found.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from ..osim.model import readonly_array

__all__ = ["MuscleSurfaceSpec", "SurfaceAttachment", "BoneMesh"]


@dataclass(frozen=True, eq=False)
class SurfaceAttachment:
    """Attachment landmarks of one muscle end.

    Attributes
    ----------
    body : str
        The body the landmarks ride on.
    points : (K, 3) float
        Metres; in the muscle's ``frame`` or, with ``in_body_frame``, in ``body``'s own frame
        (e.g. a path point's location).
    in_body_frame : bool
    """

    body: str
    points: np.ndarray
    in_body_frame: bool = False

    def __post_init__(self):
        pts = readonly_array(self.points, (-1, 3))
        if len(pts) == 0 or not np.all(np.isfinite(pts)):
            raise ValueError("attachment points must be a non-empty finite (K, 3) array")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "body", str(self.body))
        object.__setattr__(self, "in_body_frame", bool(self.in_body_frame))


@dataclass(frozen=True, eq=False)
class BoneMesh:
    """A bone surface for collision, riding on ``body``.

    Attributes
    ----------
    body : str
    vertices : (V, 3) float
        Metres; in the muscle's ``frame`` or, with ``in_body_frame``, in ``body``'s frame.
    faces : (T, 3) int
    in_body_frame : bool
    """

    body: str
    vertices: np.ndarray
    faces: np.ndarray
    in_body_frame: bool = False

    def __post_init__(self):
        object.__setattr__(self, "body", str(self.body))
        object.__setattr__(self, "vertices", readonly_array(self.vertices, (-1, 3)))
        object.__setattr__(self, "faces", readonly_array(self.faces, (-1, 3), np.int64))


@dataclass(frozen=True, eq=False)
class MuscleSurfaceSpec:
    """One muscle surface to move with the model.

    Attributes
    ----------
    name : str
        The muscle's name (used in messages).
    action_lines : tuple of str
        Names of the model's paths (OpenSim muscles) that drive the surface, at least one.
    vertices : (V, 3) float or None
        The rest surface in ``frame``, metres; None to generate a fusiform surface around the
        first action line at the rest pose (`motion.surface.generate`).
    faces : (T, 3) int or None
        Closed surface, outward normals (flipped automatically if inward).
    frame : str
        "ground", a body name, or "bodies".
    rest_pose : mapping str -> float
        Coordinate values (SI) of the rest pose; missing ones take the model default.
    origin, insertion : SurfaceAttachment or None
        Attachment landmarks; None: the first (last) path point of the first action line.
    bones : tuple of BoneMesh
        Optional bones to keep the surface out of.
    volume : float or None
        For a generated surface: its volume (m^3); None: from the muscle's max isometric
        force and optimal fibre length, else a 1:5 spindle.
    riders : int
        The last ``riders`` vertices are not part of the surface (no face may use them) but
        points carried with it, e.g. fibre points: they follow the belly deformation only,
        without the rigid attachment zones (`motion.bind_surface` ``free_vertices``).
    tendon_slack : tuple of float or None
        Tendon slack length (m) per action line. None: a generated surface takes the model's
        ``tendon_slack_length`` of each line (its belly then spans the fibre part of the path,
        `motion.osim.muscle_parameters`), a mesh none (0). With a positive value the surface is the
        belly between the two tendons: it slides along the line and its attachment landmarks
        ride the belly, not the bones.
    origin_tendon_share : float
        The share (0..1) of the tendon length that lies at the origin end, the rest at the
        insertion (`motion.osim.muscle_parameters.belly_span`); 0.5 by default (OpenSim does not
        say where a muscle's tendon sits). A gastrocnemius, whose long tendon is distal: ~0.1.
    """

    name: str
    action_lines: tuple
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    frame: str = "ground"
    rest_pose: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))
    origin: SurfaceAttachment | None = None
    insertion: SurfaceAttachment | None = None
    bones: tuple = ()
    volume: float | None = None
    riders: int = 0
    tendon_slack: tuple | None = None
    origin_tendon_share: float = 0.5

    def __post_init__(self):
        lines = (self.action_lines,) if isinstance(self.action_lines, str) else tuple(self.action_lines)
        if not lines:
            raise ValueError(f"muscle {self.name!r}: at least one action line is needed")
        object.__setattr__(self, "action_lines", tuple(str(x) for x in lines))
        if (self.vertices is None) != (self.faces is None):
            raise ValueError(f"muscle {self.name!r}: give both vertices and faces, or neither")
        if self.vertices is not None:
            object.__setattr__(self, "vertices", readonly_array(self.vertices, (-1, 3)))
            object.__setattr__(self, "faces", readonly_array(self.faces, (-1, 3), np.int64))
        riders = int(self.riders)
        if riders < 0 or (riders and (self.vertices is None or riders > len(self.vertices)
                                      or (self.faces.size and self.faces.max() >= len(self.vertices) - riders))):
            raise ValueError(f"muscle {self.name!r}: riders={self.riders} must count trailing vertices "
                             "that no face uses")
        object.__setattr__(self, "riders", riders)
        if self.tendon_slack is not None:
            slack = tuple(float(x) for x in np.broadcast_to(np.asarray(self.tendon_slack, dtype=float),
                                                           (len(lines),)))
            if not all(np.isfinite(x) and x >= 0 for x in slack):
                raise ValueError(f"muscle {self.name!r}: tendon_slack must be >= 0 per action line")
            object.__setattr__(self, "tendon_slack", slack)
        share = float(self.origin_tendon_share)
        if not 0.0 <= share <= 1.0:
            raise ValueError(f"muscle {self.name!r}: origin_tendon_share must lie in [0, 1], got {share}")
        object.__setattr__(self, "origin_tendon_share", share)
        object.__setattr__(self, "rest_pose",
                           MappingProxyType({str(k): float(v) for k, v in dict(self.rest_pose).items()}))
        object.__setattr__(self, "bones", tuple(self.bones))
        object.__setattr__(self, "frame", str(self.frame))

    @property
    def generated(self) -> bool:
        """True when the surface is generated around the action line."""
        return self.vertices is None
