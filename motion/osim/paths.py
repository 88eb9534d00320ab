"""Read the path forces (GeometryPath: points and PathWrapSet) and the wrap objects of a model.

Any force holding a ``<GeometryPath>`` (Thelen2003Muscle, Millard2012EquilibriumMuscle, any
Muscle subclass, PathActuator, Ligament, PathSpring ...) becomes a `motion.osim.model.Path`.
Points: PathPoint, ConditionalPathPoint and MovingPathPoint in 4.x (``socket_parent_frame``,
``socket_coordinate``, ``socket_x_coordinate`` ...) and 3.x/2.x (``body``, ``coordinate``,
``x_coordinate`` ...) spelling. Wrap objects: WrapCylinder, WrapSphere, WrapEllipsoid, WrapTorus.
"""
from __future__ import annotations

import numpy as np

from .model import Path, PathPoint, PathWrap, WrapObject
from .xml_document import Node, function_child, parse_function

__all__ = ["read_paths", "read_wrap_objects"]

_WRAP_KINDS = {"WrapCylinder": "cylinder", "WrapSphere": "sphere", "WrapEllipsoid": "ellipsoid",
               "WrapTorus": "torus"}
_QUADRANTS = ("all", "x", "+x", "-x", "y", "+y", "-y", "z", "+z", "-z")
_METHODS = ("hybrid", "midpoint", "axial")


def _last(socket: str | None) -> str | None:
    return socket.rstrip("/").split("/")[-1] if socket else None


def _positive(node: Node, tag: str, value: float, fix: str) -> float:
    if not value > 0:
        raise node.error(f"<{tag}> must be positive, got {value}", fix, where=f"{node.path}/{tag}")
    return value


def read_wrap_objects(model: Node, version: int, frames: dict) -> tuple:
    """All wrap objects of the ground and the bodies, in file order."""
    holders = []
    if version >= 40000:
        g = model.child("Ground")
        if g is not None:
            holders.append(("ground", g))
        holders += [(b.name, b) for b in model.objects("BodySet")]
    else:
        holders += [(frames[b.name][0] if b.name in frames else b.name, b) for b in model.objects("BodySet")]
    out, seen = [], set()
    for body, holder in holders:
        for w in holder.objects("WrapObjectSet"):
            kind = _WRAP_KINDS.get(w.tag)
            if kind is None:
                raise w.error(f"wrap object type {w.tag} is not supported",
                              f"use one of {', '.join(_WRAP_KINDS)}")
            if not w.name or w.name in seen:
                raise w.error("a wrap object needs a unique name", "give every wrap object a unique name")
            seen.add(w.name)
            quadrant = (w.text("quadrant") or "all").strip().lower()
            if quadrant not in _QUADRANTS:
                raise w.error(f"<quadrant> {quadrant!r} is not one of {', '.join(_QUADRANTS)}",
                              "write all, x, -x, y, -y, z or -z", where=f"{w.path}/quadrant")
            quadrant = quadrant.replace("+", "")
            params = {}
            if kind == "cylinder":
                params["radius"] = _positive(w, "radius", w.float("radius", 1.0), "give the cylinder a positive radius")
                params["length"] = _positive(w, "length", w.float("length", 1.0), "give the cylinder a positive length")
            elif kind == "sphere":
                params["radius"] = _positive(w, "radius", w.float("radius", 1.0), "give the sphere a positive radius")
            elif kind == "ellipsoid":
                dims = w.floats("dimensions", 3, default=[1.0, 1.0, 1.0])
                if not np.all(dims > 0):
                    raise w.error(f"<dimensions> must be positive, got {dims.tolist()}",
                                  "give three positive semi-axis lengths", where=f"{w.path}/dimensions")
                params["dimensions"] = dims
            else:
                for tag in ("inner_radius", "outer_radius"):
                    if w.text(tag) is None:
                        raise w.error(f"the torus has no <{tag}>", f"add <{tag}>", where=f"{w.path}/{tag}")
                    params[tag] = _positive(w, tag, w.float(tag, np.nan), f"give the torus a positive {tag}")
            out.append(WrapObject(name=w.name, kind=kind, body=body,
                                  xyz_body_rotation=w.floats("xyz_body_rotation", 3, default=[0, 0, 0]),
                                  translation=w.floats("translation", 3, default=[0, 0, 0]),
                                  active=w.bool("active", True), quadrant=quadrant, **params))
    return tuple(out)


def _geometry_path(force: Node) -> Node | None:
    gp = force.child("GeometryPath")
    if gp is not None:
        return gp
    holder = force.child("path")
    if holder is not None:
        inner = holder.children()
        if inner and inner[0].tag == "GeometryPath":
            return inner[0]
        if inner:
            raise inner[0].error(f"path type {inner[0].tag} is not supported",
                                 "use a GeometryPath (path points and wrap objects)")
    for ch in force.children():
        if ch.tag == "FunctionBasedPath":
            raise ch.error("FunctionBasedPath is not supported", "use a GeometryPath (path points and wrap objects)")
    return None


def _point(p: Node, version: int, frames: dict, coords: dict) -> PathPoint:
    if version >= 40000:
        socket = p.text("socket_parent_frame")
        hit = frames.get(socket) if socket else None
        hit = hit or frames.get(_last(socket))
        where = f"{p.path}/socket_parent_frame"
    else:
        socket = p.text("body")
        hit = frames.get(socket) if socket else None
        where = f"{p.path}/body"
    if hit is None:
        raise p.error(f"path point on {socket!r}, which is not a body or frame of the model",
                      "attach the point to an existing body", where=where)
    body, tf_body_frame = hit
    loc = p.floats("location", 3, default=[0, 0, 0])
    loc = tf_body_frame[:3, :3] @ loc + tf_body_frame[:3, 3]

    def coord(tag4, tag3):
        name = _last(p.text(tag4)) if version >= 40000 else p.text(tag3)
        if name and name not in coords:
            raise p.error(f"names coordinate {name!r} that the model does not have", "fix the coordinate name",
                          where=f"{p.path}/{tag4 if version >= 40000 else tag3}")
        return name or None

    if p.tag == "PathPoint":
        return PathPoint(p.name, "fixed", body, loc)
    if p.tag == "ConditionalPathPoint":
        c = coord("socket_coordinate", "coordinate")
        if c is None:
            raise p.error("ConditionalPathPoint has no coordinate", "name the coordinate that switches it")
        rng = p.floats("range", 2, default=[-np.inf, np.inf])
        return PathPoint(p.name, "conditional", body, loc, coordinate=c, range=rng)
    if p.tag == "MovingPathPoint":
        if not np.allclose(tf_body_frame, np.eye(4)):
            raise p.error("MovingPathPoint on an offset frame is not supported", "attach it to a body frame")
        funcs, cnames = [], []
        for axis in "xyz":
            c = coord(f"socket_{axis}_coordinate", f"{axis}_coordinate")
            fnode = function_child(p.child(f"{axis}_location"), "function") if p.child(f"{axis}_location") is not None else None
            f = parse_function(fnode) if fnode is not None else None
            if f is not None and c is None:
                f = None if f is None else _const(f)
            funcs.append(f)
            cnames.append(c if f is not None else None)
        return PathPoint(p.name, "moving", body, loc, moving_functions=tuple(funcs), moving_coordinates=tuple(cnames))
    raise p.error(f"path point type {p.tag} is not supported",
                  "use PathPoint, ConditionalPathPoint or MovingPathPoint")


def _const(f):
    """A moving-point function without its coordinate: OpenSim evaluates it at 0."""
    from .functions import Constant
    return Constant(float(f.value(0.0)))


def read_paths(model: Node, version: int, frames: dict, coords: dict, wrap_names: set) -> tuple:
    """All forces with a GeometryPath, in ForceSet order."""
    out, seen = [], set()
    for force in model.objects("ForceSet"):
        gp = _geometry_path(force)
        if gp is None:
            continue
        if not force.name or force.name in seen:
            raise force.error("a path force needs a unique name", "give every force a unique name")
        seen.add(force.name)
        pts = [_point(p, version, frames, coords) for p in gp.objects("PathPointSet")]
        if len(pts) < 2:
            raise gp.error(f"the path has {len(pts)} point(s); at least 2 are needed", "add path points")
        wraps = []
        for w in gp.objects("PathWrapSet"):
            name = w.text("wrap_object")
            if name not in wrap_names:
                raise w.error(f"<wrap_object> {name!r} is not a wrap object of the model",
                              "name a wrap object defined in a body's WrapObjectSet", where=f"{w.path}/wrap_object")
            method = (w.text("method") or "hybrid").lower()
            if method not in _METHODS:
                raise w.error(f"<method> {method!r} is not one of {', '.join(_METHODS)}", "write hybrid",
                              where=f"{w.path}/method")
            rng = w.floats("range", 2, default=[-1, -1]).astype(int)
            wraps.append(PathWrap(name, method, tuple(rng)))
        out.append(Path(force.name, force.tag, pts, wraps))
    return tuple(out)
