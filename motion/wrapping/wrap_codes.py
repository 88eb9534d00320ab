"""OpenSim's wrap result codes and quadrant names, shared by the compiled wrap lines.

``NO_WRAP, INSIDE_RADIUS, WRAPPED, MANDATORY_WRAP`` are OpenSim's ``WrapObject::WrapAction``;
`quadrant_axis_sign` reads a wrap object's ``quadrant`` property (``x``, ``-y``, ``all`` ...)
as OpenSim's WrapObject::setupQuadrant does: the constrained axis and its active side.
"""
from __future__ import annotations

__all__ = ["NO_WRAP", "INSIDE_RADIUS", "WRAPPED", "MANDATORY_WRAP", "quadrant_axis_sign", "ELLIPSOID_METHODS"]

# OpenSim WrapObject::WrapAction
NO_WRAP, INSIDE_RADIUS, WRAPPED, MANDATORY_WRAP = 0, 1, 2, 3

# WrapEllipsoid methods, numbered as `motion.wrapping.ellipsoid_line.ellipsoid_line` takes them
ELLIPSOID_METHODS = ("hybrid", "midpoint", "axial")


def quadrant_axis_sign(quadrant: str) -> tuple:
    """(axis, sign) of an OpenSim quadrant name; sign 0 means all quadrants."""
    q = str(quadrant).strip()
    table = {"x": (0, 1), "+x": (0, 1), "X": (0, 1), "+X": (0, 1), "-x": (0, -1), "-X": (0, -1),
             "y": (1, 1), "+y": (1, 1), "Y": (1, 1), "+Y": (1, 1), "-y": (1, -1), "-Y": (1, -1),
             "z": (2, 1), "+z": (2, 1), "Z": (2, 1), "+Z": (2, 1), "-z": (2, -1), "-Z": (2, -1),
             "all": (0, 0), "ALL": (0, 0), "All": (0, 0), "Unassigned": (0, 0)}
    if q not in table:
        raise ValueError(f"quadrant must be one of x, -x, y, -y, z, -z, all; got {quadrant!r}")
    return table[q]
