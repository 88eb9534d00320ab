"""Write small OpenSim 4.0 model files (``Version="40000"``) from Python, for examples and tests.

A chainable builder over :mod:`xml.etree.ElementTree`; the XML follows what OpenSim 4.x itself
prints (``Model::print``): ``BodySet`` / ``JointSet`` with ``PhysicalOffsetFrame`` pairs,
``WrapObjectSet`` on bodies, ``ForceSet`` with ``GeometryPath`` (``PathPointSet`` and
``PathWrapSet``). Files it writes load in OpenSim 4.6 (tested).

Example
-------
>>> from motion.osim.builder import ModelBuilder
>>> xml = (ModelBuilder("pin")
...        .add_body("upper", meshes=["upper.stl"])
...        .add_weld_joint("fix", "ground", "upper")
...        .add_body("lower")
...        .add_pin_joint("knee", "upper", "lower", "knee_angle",
...                       location_in_parent=(0, -0.3, 0), range=(0.0, 2.0))
...        .add_wrap_cylinder("upper", "knee_cyl", radius=0.02, length=0.1,
...                           translation=(0, -0.3, 0), quadrant="-x")
...        .add_muscle("ext", [("upper", (-0.01, -0.1, 0)), ("lower", (-0.01, -0.1, 0))],
...                    wraps=["knee_cyl"])
...        .to_xml())
>>> xml.startswith('<?xml')
True

Conventions (OpenSim's): a PinJoint rotates about the z axis of its parent offset frame;
``orientation`` triples are body-fixed X-Y-Z Euler angles in radians; a WrapCylinder's axis is
its local z; a CustomJoint has exactly three rotation and three translation ``TransformAxis``.
"""
from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from .atomic_file import atomic_write

__all__ = ["ModelBuilder", "TransformAxisSpec"]

_VERSION = "40000"
_QUADRANTS = ("all", "x", "y", "z", "+x", "+y", "+z", "-x", "-y", "-z")
_MUSCLE_KINDS = ("Thelen2003Muscle", "PathActuator")


def _num(x) -> str:
    """Shortest round-trip text of a float (deterministic, full precision)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"non-finite number {x!r} in the model")
    if x == 0.0:
        return "0"
    r = repr(x)
    return r[:-2] if r.endswith(".0") else r


def _vec(values, n=3, what="vector") -> str:
    vals = [float(v) for v in values]
    if len(vals) != n:
        raise ValueError(f"{what} must have {n} numbers, got {len(vals)}")
    return " ".join(_num(v) for v in vals)


def _rank(rows) -> int:
    import numpy as np

    return int(np.linalg.matrix_rank(np.asarray(rows, dtype=float), tol=1e-9))


def _sub(parent, tag, text=None, **attrib):
    el = ET.SubElement(parent, tag, attrib)
    if text is not None:
        el.text = text
    return el


def _set(parent, tag, name):
    """An OpenSim Set: <tag name=...><objects/><groups/></tag>; returns the objects element."""
    s = _sub(parent, tag, name=name)
    objects = _sub(s, "objects")
    _sub(s, "groups")
    return objects


@dataclass(frozen=True)
class TransformAxisSpec:
    """One TransformAxis of a CustomJoint's SpatialTransform.

    Parameters
    ----------
    axis : (3,) float
        Axis in the parent offset frame (rotations) / translation direction.
    coordinate : str or None
        The coordinate driving this axis; None for a constant axis.
    slope, intercept : float
        ``LinearFunction`` value = slope * q + intercept (used when ``coordinate`` is set).
    value : float
        ``Constant`` value (used when ``coordinate`` is None).
    """

    axis: tuple = (0.0, 0.0, 1.0)
    coordinate: str | None = None
    slope: float = 1.0
    intercept: float = 0.0
    value: float = 0.0


class ModelBuilder:
    """Build an OpenSim 4.0 model file step by step; every ``add_*`` returns ``self``.

    Parameters
    ----------
    name : str
        The model's name.
    gravity : (3,) float, keyword-only
        Gravity in ground (m/s^2).
    credits : str, keyword-only
        Free text stored in ``<credits>``.

    Notes
    -----
    Bodies must be added before anything refers to them; names must be unique per kind.
    ``write`` is atomic (temporary file + rename).
    """

    def __init__(self, name: str, *, gravity=(0.0, -9.80665, 0.0), credits: str | None = None):
        self.name = str(name)
        self._gravity = _vec(gravity, what="gravity")
        self._credits = credits
        self._bodies: dict[str, ET.Element] = {}
        self._joints: list[ET.Element] = []
        self._forces: list[ET.Element] = []
        self._wraps: dict[str, str] = {}  # wrap object name -> body
        self._coordinates: set[str] = set()
        self._children: set[str] = set()

    # -- bodies and geometry -------------------------------------------------------------
    def add_body(self, name: str, *, mass: float = 1.0, mass_center=(0.0, 0.0, 0.0),
                 inertia=(0.01, 0.01, 0.01, 0.0, 0.0, 0.0), meshes=(), mesh_scale=(1.0, 1.0, 1.0)):
        """Add a Body.

        Parameters
        ----------
        name : str
        mass : float
            kg.
        mass_center : (3,) float
            In the body frame (m).
        inertia : (6,) float
            ``Ixx Iyy Izz Ixy Ixz Iyz`` about the mass centre (kg m^2).
        meshes : sequence of str
            Geometry files attached to the body (``<Mesh>``; paths as OpenSim resolves them,
            relative to the model file or its ``Geometry`` folder).
        mesh_scale : (3,) float
            Scale factors applied to every mesh of this body.
        """
        name = str(name)
        if name == "ground" or name in self._bodies:
            raise ValueError(f"body {name!r} already exists")
        body = ET.Element("Body", name=name)
        if meshes:
            geoms = _sub(body, "attached_geometry")
            for i, mesh_file in enumerate(meshes, start=1):
                mesh = _sub(geoms, "Mesh", name=f"{name}_geom_{i}")
                _sub(mesh, "socket_frame", "..")
                _sub(mesh, "scale_factors", _vec(mesh_scale, what="mesh_scale"))
                _sub(mesh, "mesh_file", str(mesh_file).replace(os.sep, "/"))
        wset = _sub(body, "WrapObjectSet", name="wrapobjectset")
        _sub(wset, "objects")
        _sub(wset, "groups")
        _sub(body, "mass", _num(mass))
        _sub(body, "mass_center", _vec(mass_center, what="mass_center"))
        _sub(body, "inertia", _vec(inertia, 6, what="inertia"))
        self._bodies[name] = body
        return self

    def _frame_path(self, body: str) -> str:
        if body == "ground":
            return "/ground"
        if body not in self._bodies:
            raise ValueError(f"unknown body {body!r}; add it with add_body first")
        return f"/bodyset/{body}"

    # -- joints -----------------------------------------------------------------------------
    def _joint(self, kind, name, parent, child, loc_p, ori_p, loc_c, ori_c):
        if child == "ground":
            raise ValueError("ground cannot be a joint's child")
        if child in self._children:
            raise ValueError(f"body {child!r} already has a parent joint")
        self._frame_path(parent), self._frame_path(child)
        joint = ET.Element(kind, name=str(name))
        _sub(joint, "socket_parent_frame", f"{parent}_offset")
        _sub(joint, "socket_child_frame", f"{child}_offset")
        self._children.add(child)
        self._joints.append(joint)
        return joint, (parent, loc_p, ori_p), (child, loc_c, ori_c)

    @staticmethod
    def _frames(joint, *specs):
        frames = _sub(joint, "frames")
        for body, loc, ori in specs:
            f = _sub(frames, "PhysicalOffsetFrame", name=f"{body}_offset")
            _sub(f, "socket_parent", "/ground" if body == "ground" else f"/bodyset/{body}")
            _sub(f, "translation", _vec(loc, what="location"))
            _sub(f, "orientation", _vec(ori, what="orientation"))

    def _coordinate(self, parent_el, name, default, range, clamped, locked):
        if name in self._coordinates:
            raise ValueError(f"coordinate {name!r} already exists")
        lo, hi = (float(v) for v in range)
        if not lo <= hi:
            raise ValueError(f"coordinate {name!r}: range min {lo} > max {hi}")
        self._coordinates.add(name)
        c = _sub(parent_el, "Coordinate", name=str(name))
        _sub(c, "default_value", _num(default))
        _sub(c, "default_speed_value", "0")
        _sub(c, "range", f"{_num(lo)} {_num(hi)}")
        _sub(c, "clamped", "true" if clamped else "false")
        _sub(c, "locked", "true" if locked else "false")

    def add_weld_joint(self, name: str, parent: str, child: str, *, location_in_parent=(0, 0, 0),
                       orientation_in_parent=(0, 0, 0), location_in_child=(0, 0, 0),
                       orientation_in_child=(0, 0, 0)):
        """Add a WeldJoint fixing ``child`` to ``parent`` (offsets in m, X-Y-Z Euler in rad)."""
        joint, p, c = self._joint("WeldJoint", name, parent, child, location_in_parent,
                                  orientation_in_parent, location_in_child, orientation_in_child)
        self._frames(joint, p, c)
        return self

    def add_pin_joint(self, name: str, parent: str, child: str, coordinate: str, *,
                      location_in_parent=(0, 0, 0), orientation_in_parent=(0, 0, 0),
                      location_in_child=(0, 0, 0), orientation_in_child=(0, 0, 0),
                      default: float = 0.0, range=(-math.pi, math.pi), clamped: bool = False,
                      locked: bool = False):
        """Add a PinJoint: ``child`` rotates by ``coordinate`` about the parent offset frame's z.

        ``tf_parent_child = T(loc_p) R(ori_p) Rz(q) R(ori_c)^-1 T(loc_c)^-1``.
        """
        joint, p, c = self._joint("PinJoint", name, parent, child, location_in_parent,
                                  orientation_in_parent, location_in_child, orientation_in_child)
        coords = _sub(joint, "coordinates")
        self._coordinate(coords, coordinate, default, range, clamped, locked)
        self._frames(joint, p, c)
        return self

    def add_custom_joint(self, name: str, parent: str, child: str, *, coordinates,
                         rotations=(), translations=(), location_in_parent=(0, 0, 0),
                         orientation_in_parent=(0, 0, 0), location_in_child=(0, 0, 0),
                         orientation_in_child=(0, 0, 0)):
        """Add a CustomJoint with a SpatialTransform.

        Parameters
        ----------
        coordinates : sequence of dict
            Each ``{"name": str, "default": 0.0, "range": (lo, hi), "clamped": False,
            "locked": False}`` (only ``name`` is required).
        rotations, translations : sequence of TransformAxisSpec, at most 3 each
            Missing axes are filled with constant-zero unit axes (x, y, z, skipping those that
            would make the set linearly dependent, which OpenSim rejects).
        """
        rotations, translations = list(rotations), list(translations)
        if len(rotations) > 3 or len(translations) > 3:
            raise ValueError("a CustomJoint has at most 3 rotation and 3 translation axes")
        joint, p, c = self._joint("CustomJoint", name, parent, child, location_in_parent,
                                  orientation_in_parent, location_in_child, orientation_in_child)
        coords = _sub(joint, "coordinates")
        names = []
        for spec in coordinates:
            spec = dict(spec)
            cname = spec.pop("name")
            names.append(cname)
            self._coordinate(coords, cname, spec.pop("default", 0.0),
                             spec.pop("range", (-math.pi, math.pi)), spec.pop("clamped", False),
                             spec.pop("locked", False))
            if spec:
                raise ValueError(f"coordinate {cname!r}: unknown keys {sorted(spec)}")
        self._frames(joint, p, c)
        units = [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
        st = _sub(joint, "SpatialTransform")
        for kind, given in (("rotation", rotations), ("translation", translations)):
            filled = list(given)
            for u in units:
                if len(filled) == 3:
                    break
                mat = [list(map(float, a.axis)) for a in filled] + [list(u)]
                if _rank(mat) == len(mat):
                    filled.append(TransformAxisSpec(axis=u))
            for i, ax in enumerate(filled, start=1):
                if ax.coordinate is not None and ax.coordinate not in names:
                    raise ValueError(f"{kind}{i}: coordinate {ax.coordinate!r} is not one of "
                                     f"joint {name!r}'s coordinates {names}")
                ta = _sub(st, "TransformAxis", name=f"{kind}{i}")
                _sub(ta, "coordinates", ax.coordinate or "")
                _sub(ta, "axis", _vec(ax.axis, what="axis"))
                if ax.coordinate is not None:
                    f = _sub(ta, "LinearFunction", name="function")
                    _sub(f, "coefficients", f"{_num(ax.slope)} {_num(ax.intercept)}")
                else:
                    f = _sub(ta, "Constant", name="function")
                    _sub(f, "value", _num(ax.value))
        return self

    # -- wrap objects -----------------------------------------------------------------------
    def _wrap(self, kind, body, name, translation, rotation, quadrant):
        self._frame_path(body)
        if body == "ground":
            raise ValueError("attach wrap objects to a body, not ground")
        if name in self._wraps:
            raise ValueError(f"wrap object {name!r} already exists")
        if quadrant not in _QUADRANTS:
            raise ValueError(f"quadrant must be one of {_QUADRANTS}, got {quadrant!r}")
        self._wraps[name] = body
        w = _sub(self._bodies[body].find("WrapObjectSet/objects"), kind, name=str(name))
        _sub(w, "active", "true")
        _sub(w, "xyz_body_rotation", _vec(rotation, what="rotation"))
        _sub(w, "translation", _vec(translation, what="translation"))
        _sub(w, "quadrant", quadrant)
        return w

    def add_wrap_cylinder(self, body: str, name: str, *, radius: float, length: float,
                          translation=(0, 0, 0), rotation=(0, 0, 0), quadrant: str = "all"):
        """Add a WrapCylinder (axis = its local z) to ``body``; rotation is X-Y-Z Euler (rad)."""
        if not (radius > 0 and length > 0):
            raise ValueError("WrapCylinder radius and length must be positive")
        w = self._wrap("WrapCylinder", body, name, translation, rotation, quadrant)
        _sub(w, "radius", _num(radius))
        _sub(w, "length", _num(length))
        return self

    def add_wrap_sphere(self, body: str, name: str, *, radius: float, translation=(0, 0, 0),
                        rotation=(0, 0, 0), quadrant: str = "all"):
        """Add a WrapSphere to ``body``."""
        if not radius > 0:
            raise ValueError("WrapSphere radius must be positive")
        w = self._wrap("WrapSphere", body, name, translation, rotation, quadrant)
        _sub(w, "radius", _num(radius))
        return self

    # -- muscles ----------------------------------------------------------------------------
    def add_muscle(self, name: str, points, *, wraps=(), kind: str = "Thelen2003Muscle",
                   max_isometric_force: float = 500.0, optimal_fiber_length: float = 0.1,
                   tendon_slack_length: float = 0.1, pennation_angle: float = 0.0):
        """Add a muscle (or PathActuator) with PathPoints and a PathWrapSet.

        Parameters
        ----------
        points : sequence of (body, (3,) float)
            Path points in order from origin to insertion, each in its body's frame (m).
        wraps : sequence of str
            Wrap object names, in the order OpenSim applies them (``method`` hybrid, full range).
        kind : {"Thelen2003Muscle", "PathActuator"}
        """
        if kind not in _MUSCLE_KINDS:
            raise ValueError(f"kind must be one of {_MUSCLE_KINDS}, got {kind!r}")
        points = list(points)
        if len(points) < 2:
            raise ValueError(f"muscle {name!r} needs at least 2 path points")
        if any(f.get("name") == name for f in self._forces):
            raise ValueError(f"force {name!r} already exists")
        m = ET.Element(kind, name=str(name))
        path = _sub(m, "GeometryPath", name="geometrypath")
        pps = _sub(path, "PathPointSet")
        objs = _sub(pps, "objects")
        _sub(pps, "groups")
        for i, (body, loc) in enumerate(points, start=1):
            pp = _sub(objs, "PathPoint", name=f"{name}-P{i}")
            _sub(pp, "socket_parent_frame", self._frame_path(body))
            _sub(pp, "location", _vec(loc, what="path point"))
        pws = _sub(path, "PathWrapSet")
        wobjs = _sub(pws, "objects")
        _sub(pws, "groups")
        for i, wname in enumerate(wraps, start=1):
            if wname not in self._wraps:
                raise ValueError(f"muscle {name!r}: unknown wrap object {wname!r}")
            pw = _sub(wobjs, "PathWrap", name=f"{name}-wrap{i}")
            _sub(pw, "wrap_object", wname)
            _sub(pw, "method", "hybrid")
            _sub(pw, "range", "-1 -1")
        if kind == "Thelen2003Muscle":
            _sub(m, "max_isometric_force", _num(max_isometric_force))
            _sub(m, "optimal_fiber_length", _num(optimal_fiber_length))
            _sub(m, "tendon_slack_length", _num(tendon_slack_length))
            _sub(m, "pennation_angle_at_optimal", _num(pennation_angle))
        else:
            _sub(m, "optimal_force", _num(max_isometric_force))
        self._forces.append(m)
        return self

    # -- output -----------------------------------------------------------------------------
    def to_element(self) -> ET.Element:
        """The ``<OpenSimDocument>`` element."""
        doc = ET.Element("OpenSimDocument", Version=_VERSION)
        model = _sub(doc, "Model", name=self.name)
        ground = _sub(model, "Ground", name="ground")
        _sub(ground, "FrameGeometry", name="frame_geometry")
        fg = ground.find("FrameGeometry")
        _sub(fg, "socket_frame", "..")
        _sub(model, "gravity", self._gravity)
        if self._credits:
            _sub(model, "credits", self._credits)
        _sub(model, "length_units", "meters")
        _sub(model, "force_units", "N")
        _set(model, "BodySet", "bodyset").extend(self._bodies.values())
        _set(model, "JointSet", "jointset").extend(self._joints)
        _set(model, "ForceSet", "forceset").extend(self._forces)
        return doc

    def to_xml(self) -> str:
        """The model file's text (UTF-8 XML declaration, tab-indented, '\\n' line ends)."""
        doc = self.to_element()
        ET.indent(doc, space="\t")
        return '<?xml version="1.0" encoding="UTF-8" ?>\n' + ET.tostring(doc, encoding="unicode") + "\n"

    def write(self, path) -> Path:
        """Write the ``.osim`` file atomically (`motion.osim.atomic_file`); returns its path."""
        path = Path(path)
        with atomic_write(path) as tmp:
            tmp.write_text(self.to_xml(), encoding="utf-8", newline="\n")
        return path
