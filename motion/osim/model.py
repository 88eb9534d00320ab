"""The musculoskeletal model as frozen data: what `motion.load_model` returns.

Data model (all classes are frozen dataclasses; arrays are float64 and read-only; names are
OpenSim's own names; every frame transform is a (4, 4) homogeneous matrix named
``tf_<to>_<from>`` so that ``p_to = tf_to_from @ p_from``):

- `Model`: ``name``, ``file``, ``version`` (the document's Version: 20001, 30000, 40000 ...),
  ``bodies`` (tuple of `Body`, ground first, named ``"ground"``), ``joints`` (tuple of `Joint`,
  parents before children, one per non-ground body), ``coordinates`` (tuple of `Coordinate`,
  model order = the order of OpenSim's CoordinateSet), ``couplers`` (tuple of
  `CouplerConstraint`), ``welds`` (tuple of `WeldConstraint`), ``paths`` (tuple of `Path`, the
  order of the ForceSet), ``wrap_objects`` (tuple of `WrapObject`).
  Look-ups: ``coordinate_names``, ``coordinate_index(name)``, ``body_names``,
  ``body_index(name)``, ``path_names``, ``path(name)``, ``wrap_object(name)``,
  ``coupled_coordinates`` / ``dependent_coordinates`` / ``independent_coordinates`` (bool (C,), see below).
- `Body`: ``name``, ``geometry`` (tuple of `Geometry`: ``mesh_file``, ``scale_factors`` (3,),
  ``tf_body_geometry`` (4, 4)).
- `Joint`: ``name``, ``kind`` (OpenSim class name, e.g. ``"CustomJoint"``, ``"PinJoint"``),
  ``parent`` / ``child`` body names, ``tf_parent_jointframe`` (the parent-side joint frame F
  in the parent body, OpenSim's ``location_in_parent``/``orientation_in_parent`` or the parent
  PhysicalOffsetFrame), ``tf_child_jointframe`` (the child-side frame M in the child body),
  ``coordinates`` (names of the coordinates the joint owns) and ``axes``: the joint as
  OpenSim's SpatialTransform, a tuple of `TransformAxis` — three rotations then three
  translations. Every supported joint type is converted to this form on reading (PinJoint =
  rotation about the frame's z axis, BallJoint = body-fixed x-y-z rotations, ...), so that
  kinematics has one code path (plus ``radii`` for an EllipsoidJoint, whose M origin is at
  ``radii * z_M`` in F, SimTK's Ellipsoid mobilizer): ``tf_F_M = [R1 R2 R3 | t]`` with each rotation about its
  axis expressed in the frame rotated by the previous ones (OpenSim's CustomJoint /
  SimTK::MobilizedBody::FunctionBased) and the translation ``t = sum_k f_k(q) axis_k``
  expressed in F. The body pose is ``tf_ground_child = tf_ground_parent @
  tf_parent_jointframe @ tf_F_M @ inv(tf_child_jointframe)``.
- `TransformAxis`: ``name`` (rotation1..3, translation1..3), ``kind`` ("rotation" |
  "translation"), ``axis`` (3,) unit, ``coordinates`` (names; empty for a Constant),
  ``function`` (a `motion.osim.functions` object of one variable).
- `Coordinate`: ``name``, ``motion_type`` ("rotational" | "translational" | "coupled"),
  ``default_value``, ``range`` (2,), ``clamped``, ``locked``, ``joint`` (its joint's name),
  ``free_to_satisfy_constraints`` (OpenSim's ``is_free_to_satisfy_constraints``: assembly may
  move it freely to meet constraints; OpenSim then calls it dependent).
- `CouplerConstraint`: ``name``, ``independent`` (names), ``dependent`` (name), ``function``,
  ``scale_factor``: q_dependent = scale_factor * function(q_independent).
- `WeldConstraint`: ``name``, ``body_1``, ``body_2``, ``tf_body1_frame``, ``tf_body2_frame``
  (read and kept; the pose from a motion's assembled coordinates already satisfies it).
- `Path`: one force that owns a GeometryPath: ``name``, ``force_type`` (class name),
  ``points`` (tuple of `PathPoint`), ``wraps`` (tuple of `PathWrap`, in PathWrapSet order).
- `PathPoint`: ``name``, ``kind`` ("fixed" | "conditional" | "moving"), ``body``, ``location``
  (3,) in the body; conditional: ``coordinate`` and ``range`` (2,) (active when
  range[0] - 1e-5 <= q <= range[1] + 1e-5); moving: ``moving_functions`` (3 functions or None
  for x, y, z) and ``moving_coordinates`` (3 names or None); a None axis keeps ``location``.
- `PathWrap`: ``wrap_object`` (name), ``method`` ("hybrid" | "midpoint" | "axial"),
  ``range`` (start, end) 1-based path-point indices or (-1, -1) for the whole path.
- `WrapObject`: ``name``, ``kind`` ("cylinder" | "sphere" | "ellipsoid" | "torus"), ``body``,
  ``xyz_body_rotation`` (3,), ``translation`` (3,), ``active``, ``quadrant`` (e.g. "all",
  "x", "-y"), ``radius``, ``length``, ``dimensions`` (3,), ``inner_radius``,
  ``outer_radius`` (unused parameters are NaN); ``tf_body_wrap`` (4, 4) places the wrap
  frame in its body (rotation = body-fixed x-y-z Euler angles, as OpenSim).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "Model", "Body", "Geometry", "Joint", "TransformAxis", "Coordinate", "CouplerConstraint",
    "WeldConstraint", "Path", "PathPoint", "PathWrap", "WrapObject", "MOTION_TYPES",
    "WRAP_KINDS", "frame_transform", "euler_xyz_matrix",
]

MOTION_TYPES = ("rotational", "translational", "coupled")
WRAP_KINDS = ("cylinder", "sphere", "ellipsoid", "torus")
POINT_KINDS = ("fixed", "conditional", "moving")
WRAP_METHODS = ("hybrid", "midpoint", "axial")


def readonly_array(value, shape=None, dtype=float, *, name="an array") -> np.ndarray:
    """A read-only copy of ``value`` as a ``dtype`` array, checked against ``shape`` (a tuple in
    which -1 matches any length; None: any shape; ``name`` says what it is in the ValueError).
    The records of `motion` and `analysis` hold their arrays this way, so that a model, surface
    spec or result cannot change under a cached computation."""
    arr = np.array(value, dtype=dtype, copy=True)
    if shape is not None and (arr.ndim != len(shape)
                              or any(s not in (-1, n) for s, n in zip(shape, arr.shape))):
        want = "(" + ", ".join("n" if s == -1 else str(s) for s in shape) + ")"
        raise ValueError(f"expected {name} of shape {want}, got shape {arr.shape}")
    arr.setflags(write=False)
    return arr


def _freeze(obj, arrays=None, tuples=()) -> None:
    """On the frozen dataclass ``obj``: each field named in ``arrays`` (name -> shape) becomes a
    read-only float copy checked against its shape (None stays None), each one in ``tuples`` a
    tuple."""
    for name, shape in (arrays or {}).items():
        value = getattr(obj, name)
        if value is not None:
            object.__setattr__(obj, name, readonly_array(value, shape))
    for name in tuples:
        object.__setattr__(obj, name, tuple(getattr(obj, name)))


def euler_xyz_matrix(angles) -> np.ndarray:
    """Rotation matrix of body-fixed x-y-z Euler angles (SimTK BodyRotationSequence XYZ).

    Parameters
    ----------
    angles : (..., 3) float
        Angles in radians.

    Returns
    -------
    (..., 3, 3) float
        ``R = Rx(a0) @ Ry(a1) @ Rz(a2)``: OpenSim's convention for ``orientation``,
        ``orientation_in_parent`` and ``xyz_body_rotation``.
    """
    a = np.asarray(angles, dtype=float)
    c, s = np.cos(a), np.sin(a)
    c0, c1, c2 = c[..., 0], c[..., 1], c[..., 2]
    s0, s1, s2 = s[..., 0], s[..., 1], s[..., 2]
    r = np.empty(a.shape[:-1] + (3, 3))
    r[..., 0, 0] = c1 * c2
    r[..., 0, 1] = -c1 * s2
    r[..., 0, 2] = s1
    r[..., 1, 0] = s0 * s1 * c2 + c0 * s2
    r[..., 1, 1] = -s0 * s1 * s2 + c0 * c2
    r[..., 1, 2] = -s0 * c1
    r[..., 2, 0] = -c0 * s1 * c2 + s0 * s2
    r[..., 2, 1] = c0 * s1 * s2 + s0 * c2
    r[..., 2, 2] = c0 * c1
    return r


def frame_transform(translation, orientation) -> np.ndarray:
    """(4, 4) transform of an OpenSim offset frame: translation and body-fixed XYZ angles."""
    tf = np.eye(4)
    tf[:3, :3] = euler_xyz_matrix(np.asarray(orientation, dtype=float))
    tf[:3, 3] = np.asarray(translation, dtype=float)
    return tf


@dataclass(frozen=True, eq=False)
class Geometry:
    """A mesh attached to a body: file name as written in the model and its scale."""

    mesh_file: str
    scale_factors: np.ndarray = field(default_factory=lambda: np.ones(3))
    tf_body_geometry: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self):
        _freeze(self, {"scale_factors": (3,), "tf_body_geometry": (4, 4)})


@dataclass(frozen=True, eq=False)
class Body:
    """A rigid body (ground included, named ``"ground"``)."""

    name: str
    geometry: tuple = ()


@dataclass(frozen=True, eq=False)
class TransformAxis:
    """One axis of a SpatialTransform: rotation about / translation along ``axis``."""

    name: str
    kind: str
    axis: np.ndarray
    coordinates: tuple
    function: Any

    def __post_init__(self):
        if self.kind not in ("rotation", "translation"):
            raise ValueError(f"kind must be 'rotation' or 'translation', got {self.kind!r}")
        _freeze(self, {"axis": (3,)}, ("coordinates",))


@dataclass(frozen=True, eq=False)
class Joint:
    """A joint as a SpatialTransform between two offset frames (see module docstring)."""

    name: str
    kind: str
    parent: str
    child: str
    tf_parent_jointframe: np.ndarray
    tf_child_jointframe: np.ndarray
    coordinates: tuple
    axes: tuple
    radii: np.ndarray | None = None

    def __post_init__(self):
        _freeze(self, {"radii": (3,), "tf_parent_jointframe": (4, 4), "tf_child_jointframe": (4, 4)},
                ("coordinates", "axes"))


@dataclass(frozen=True, eq=False)
class Coordinate:
    """A generalized coordinate (SI: rad or m)."""

    name: str
    motion_type: str
    default_value: float
    range: np.ndarray
    clamped: bool
    locked: bool
    joint: str
    free_to_satisfy_constraints: bool = False

    def __post_init__(self):
        if self.motion_type not in MOTION_TYPES:
            raise ValueError(f"motion_type must be one of {MOTION_TYPES}, got {self.motion_type!r}")
        _freeze(self, {"range": (2,)})
        object.__setattr__(self, "default_value", float(self.default_value))


@dataclass(frozen=True, eq=False)
class CouplerConstraint:
    """CoordinateCouplerConstraint: q_dependent = scale_factor * function(q_independent...)."""

    name: str
    independent: tuple
    dependent: str
    function: Any
    scale_factor: float = 1.0

    def __post_init__(self):
        _freeze(self, tuples=("independent",))


@dataclass(frozen=True, eq=False)
class WeldConstraint:
    """WeldConstraint between a frame on ``body_1`` and one on ``body_2``."""

    name: str
    body_1: str
    body_2: str
    tf_body1_frame: np.ndarray
    tf_body2_frame: np.ndarray

    def __post_init__(self):
        _freeze(self, {"tf_body1_frame": (4, 4), "tf_body2_frame": (4, 4)})


@dataclass(frozen=True, eq=False)
class PathPoint:
    """PathPoint, ConditionalPathPoint or MovingPathPoint (``kind``)."""

    name: str
    kind: str
    body: str
    location: np.ndarray
    coordinate: str | None = None
    range: np.ndarray | None = None
    moving_functions: tuple | None = None
    moving_coordinates: tuple | None = None

    def __post_init__(self):
        if self.kind not in POINT_KINDS:
            raise ValueError(f"kind must be one of {POINT_KINDS}, got {self.kind!r}")
        _freeze(self, {"location": (3,), "range": (2,)})
        if self.moving_functions is not None:
            _freeze(self, tuples=("moving_functions", "moving_coordinates"))


@dataclass(frozen=True, eq=False)
class PathWrap:
    """One entry of a PathWrapSet."""

    wrap_object: str
    method: str = "hybrid"
    range: tuple = (-1, -1)

    def __post_init__(self):
        object.__setattr__(self, "range", tuple(int(r) for r in self.range))


@dataclass(frozen=True, eq=False)
class Path:
    """A force owning a GeometryPath (Muscle, PathActuator, Ligament, PathSpring ...)."""

    name: str
    force_type: str
    points: tuple
    wraps: tuple = ()

    def __post_init__(self):
        _freeze(self, tuples=("points", "wraps"))

    @property
    def bodies(self) -> tuple:
        """Names of the bodies of the path's points, in path order (repeats removed)."""
        return tuple(dict.fromkeys(p.body for p in self.points))


@dataclass(frozen=True, eq=False)
class WrapObject:
    """WrapCylinder / WrapSphere / WrapEllipsoid / WrapTorus fixed in ``body``."""

    name: str
    kind: str
    body: str
    xyz_body_rotation: np.ndarray
    translation: np.ndarray
    active: bool = True
    quadrant: str = "all"
    radius: float = float("nan")
    length: float = float("nan")
    dimensions: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    inner_radius: float = float("nan")
    outer_radius: float = float("nan")

    def __post_init__(self):
        if self.kind not in WRAP_KINDS:
            raise ValueError(f"kind must be one of {WRAP_KINDS}, got {self.kind!r}")
        _freeze(self, {"xyz_body_rotation": (3,), "translation": (3,), "dimensions": (3,)})

    @property
    def tf_body_wrap(self) -> np.ndarray:
        """(4, 4) wrap frame in its body: p_body = tf_body_wrap @ p_wrap."""
        return frame_transform(self.translation, self.xyz_body_rotation)


@dataclass(frozen=True, eq=False)
class Model:
    """An OpenSim model (see the module docstring for the whole data model)."""

    name: str
    file: str
    version: int
    bodies: tuple
    joints: tuple
    coordinates: tuple
    couplers: tuple = ()
    welds: tuple = ()
    paths: tuple = ()
    wrap_objects: tuple = ()

    def __post_init__(self):
        _freeze(self, tuples=("bodies", "joints", "coordinates", "couplers", "welds", "paths",
                              "wrap_objects"))
        object.__setattr__(self, "_coord_index", {c.name: i for i, c in enumerate(self.coordinates)})
        object.__setattr__(self, "_body_index", {b.name: i for i, b in enumerate(self.bodies)})
        object.__setattr__(self, "_path_index", {p.name: i for i, p in enumerate(self.paths)})
        object.__setattr__(self, "_wrap_index", {w.name: i for i, w in enumerate(self.wrap_objects)})
        object.__setattr__(self, "_memo", {})

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_memo"] = {}                 # derived data stays with the process that made it
        return state

    def cached(self, key, make):
        """The value kept under ``key`` (hashable) with this model, ``make()`` the first time:
        what the computations derive from a model alone (index plans of its paths, its wraps'
        fixed description) is made once per model (the model is frozen). Two threads asking at
        once may both make it; one value is kept."""
        hit = self._memo.get(key)
        if hit is None:
            hit = self._memo.setdefault(key, make())
        return hit

    def _indexed(self, index: dict, name: str, kind: str) -> int:
        """``index[name]``, or a KeyError naming the model and the missing ``kind``."""
        try:
            return index[name]
        except KeyError:
            raise KeyError(f"model {self.name!r} has no {kind} {name!r}") from None

    @property
    def constraints(self) -> tuple:
        """All constraints: couplers then welds."""
        return self.couplers + self.welds

    @property
    def coordinate_names(self) -> tuple:
        """(C,) coordinate names in model order."""
        return tuple(c.name for c in self.coordinates)

    def coordinate_index(self, name: str) -> int:
        """Index of coordinate ``name`` in model order (KeyError if absent)."""
        return self._indexed(self._coord_index, name, "coordinate")

    @property
    def body_names(self) -> tuple:
        """(B,) body names, ground first."""
        return tuple(b.name for b in self.bodies)

    def body_index(self, name: str) -> int:
        """Index of body ``name`` (KeyError if absent)."""
        return self._indexed(self._body_index, name, "body")

    @property
    def path_names(self) -> tuple:
        """(M,) names of the path forces in ForceSet order."""
        return tuple(p.name for p in self.paths)

    def path(self, name: str) -> Path:
        """The path force called ``name`` (KeyError if absent)."""
        return self.paths[self._indexed(self._path_index, name, "path force")]

    def wrap_object(self, name: str) -> WrapObject:
        """The wrap object called ``name`` (KeyError if absent)."""
        return self.wrap_objects[self._indexed(self._wrap_index, name, "wrap object")]

    @property
    def coupled_coordinates(self) -> np.ndarray:
        """(C,) bool: the coordinate is the dependent one of a coupler constraint."""
        dep = np.zeros(len(self.coordinates), dtype=bool)
        for c in self.couplers:
            dep[self.coordinate_index(c.dependent)] = True
        return dep

    @property
    def dependent_coordinates(self) -> np.ndarray:
        """(C,) bool: OpenSim's Coordinate::isDependent: a coupler's dependent, or a coordinate
        free to satisfy constraints (set by assembly, e.g. to close a WeldConstraint loop)."""
        free = np.array([c.free_to_satisfy_constraints for c in self.coordinates], dtype=bool)
        return self.coupled_coordinates | free

    @property
    def independent_coordinates(self) -> np.ndarray:
        """(C,) bool: not dependent (see `dependent_coordinates`) and not locked."""
        locked = np.array([c.locked for c in self.coordinates], dtype=bool)
        return ~(self.dependent_coordinates | locked)
