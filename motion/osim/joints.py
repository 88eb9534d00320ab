"""OpenSim joints as SpatialTransforms: reading CustomJoint and converting the other types.

Every joint becomes the six `TransformAxis` of OpenSim's SpatialTransform (three rotations, each
about its axis in the frame rotated by the previous ones, then three translations in the parent
joint frame F). The other joint types are the SimTK mobilizers OpenSim builds for them
(SimTK::MobilizedBody docs; OpenSim's Joint classes):

- PinJoint: rotation about z.  SliderJoint: translation along x.
- UniversalJoint: rotation about x, then about the new y.
- BallJoint, GimbalJoint: body-fixed x-y-z rotations (OpenSim uses Euler angles, SimTK
  BodyRotationSequence 1-2-3).  EllipsoidJoint: the same rotations, and M's origin at
  ``radii * z_M`` in F (SimTK::MobilizedBody::Ellipsoid; checked against OpenSim 4.6).  FreeJoint: those three, then translations x, y, z in F.
- PlanarJoint: rotation about z, translations along x and y of F.
- WeldJoint: no coordinates.

Coordinate motion types follow OpenSim 4.6 (CustomJoint::constructCoordinates): a coordinate
used by a rotation (translation) axis through a LinearFunction of slope +-1 is rotational
(translational), otherwise coupled; a CustomJoint's coordinates are ordered by their first
appearance in the SpatialTransform.
"""
from __future__ import annotations

import numpy as np

from .functions import Constant, LinearFunction
from .model import TransformAxis
from .xml_document import Node, function_child, parse_function

__all__ = ["JOINT_TYPES", "joint_axes", "custom_joint_axes", "motion_types"]

_E = np.eye(3)
_IDENTITY = LinearFunction(1.0, 0.0)
_ZERO = Constant(0.0)

# joint type -> list of (kind, axis index 0/1/2, coordinate slot) for its coordinates in order
_JOINT_DOFS = {
    "WeldJoint": [],
    "PinJoint": [("rotation", 2)],
    "SliderJoint": [("translation", 0)],
    "UniversalJoint": [("rotation", 0), ("rotation", 1)],
    "BallJoint": [("rotation", 0), ("rotation", 1), ("rotation", 2)],
    "GimbalJoint": [("rotation", 0), ("rotation", 1), ("rotation", 2)],
    "EllipsoidJoint": [("rotation", 0), ("rotation", 1), ("rotation", 2)],
    "FreeJoint": [("rotation", 0), ("rotation", 1), ("rotation", 2),
                  ("translation", 0), ("translation", 1), ("translation", 2)],
    "PlanarJoint": [("rotation", 2), ("translation", 0), ("translation", 1)],
}
JOINT_TYPES = ("CustomJoint",) + tuple(_JOINT_DOFS)


def joint_axes(kind: str, coordinate_names: tuple, node: Node) -> tuple:
    """The SpatialTransform of a non-Custom joint type with the given coordinates."""
    dofs = _JOINT_DOFS[kind]
    if len(coordinate_names) != len(dofs):
        raise node.error(f"{kind} needs {len(dofs)} coordinates, found {len(coordinate_names)}",
                         f"give the {kind} exactly {len(dofs)} <Coordinate> elements")
    rot, trans = [], []
    for (dof_kind, k), cname in zip(dofs, coordinate_names):
        (rot if dof_kind == "rotation" else trans).append((k, cname))
    axes = []
    used = [k for k, _ in rot]
    # rotations in order; pad with unused independent axes held at zero
    for i, (k, cname) in enumerate(rot):
        axes.append(TransformAxis(f"rotation{i + 1}", "rotation", _E[k], (cname,), _IDENTITY))
    for k in range(3):
        if len(axes) == 3:
            break
        if k not in used:
            axes.append(TransformAxis(f"rotation{len(axes) + 1}", "rotation", _E[k], (), _ZERO))
    used_t = [k for k, _ in trans]
    taxes = [TransformAxis(f"translation{i + 1}", "translation", _E[k], (cname,), _IDENTITY)
             for i, (k, cname) in enumerate(trans)]
    for k in range(3):
        if len(taxes) == 3:
            break
        if k not in used_t:
            taxes.append(TransformAxis(f"translation{len(taxes) + 1}", "translation", _E[k], (), _ZERO))
    return tuple(axes + taxes)


def custom_joint_axes(node: Node, coordinate_names: set) -> tuple:
    """The six TransformAxis of a CustomJoint's ``<SpatialTransform>``."""
    st = node.child("SpatialTransform")
    if st is None:
        raise node.error("CustomJoint has no <SpatialTransform>", "add the SpatialTransform with its six TransformAxis")
    by_name = {ax.name: ax for ax in st.children("TransformAxis")}
    axes = []
    for i, name in enumerate(("rotation1", "rotation2", "rotation3",
                              "translation1", "translation2", "translation3")):
        kind = "rotation" if i < 3 else "translation"
        ax = by_name.get(name)
        if ax is None:
            axes.append(TransformAxis(name, kind, _E[i % 3], (), _ZERO))
            continue
        coords = ax.names("coordinates")
        if len(coords) > 1:
            raise ax.error(f"a TransformAxis driven by {len(coords)} coordinates is not supported",
                           "drive each TransformAxis by at most one coordinate")
        for c in coords:
            if c not in coordinate_names:
                raise ax.error(f"TransformAxis uses coordinate {c!r} that the joint does not define",
                               "add the <Coordinate> to the joint or fix the name")
        fnode = function_child(ax, "function")
        if fnode is None:
            function = _IDENTITY if coords else _ZERO
        else:
            function = parse_function(fnode)
        if not coords and not isinstance(function, Constant):
            # a function of no coordinate is evaluated at 0 by OpenSim
            function = Constant(float(function.value(0.0)))
        axis = ax.floats("axis", 3, default=_E[i % 3])
        norm = float(np.linalg.norm(axis))
        if norm == 0.0:
            if coords or float(function.value(0.0)) != 0.0:
                raise ax.error("TransformAxis has a zero <axis>", "give a non-zero axis direction",
                               where=f"{ax.path}/axis")
            axis = _E[i % 3]
            norm = 1.0
        axes.append(TransformAxis(name, kind, axis / norm, coords, function))
    return tuple(axes)


def coordinate_order(axes: tuple) -> list:
    """Coordinate names in order of first appearance in the SpatialTransform."""
    out = []
    for ax in axes:
        for c in ax.coordinates:
            if c not in out:
                out.append(c)
    return out


def motion_types(kind: str, axes: tuple, coordinate_names: tuple) -> dict:
    """Coordinate name -> motion type as OpenSim 4.6 assigns it (see module docstring)."""
    out = {}
    if kind != "CustomJoint":
        for (dof_kind, _), c in zip(_JOINT_DOFS[kind], coordinate_names):
            out[c] = "rotational" if dof_kind == "rotation" else "translational"
        return out
    for c in coordinate_names:
        mt = None
        for ax in axes:
            if c not in ax.coordinates:
                continue
            f = ax.function
            if isinstance(f, LinearFunction) and abs(f.slope) == 1.0:
                mt = "rotational" if ax.kind == "rotation" else "translational"
            elif mt is None:
                mt = "coupled"
        out[c] = mt or "coupled"
    return out
