"""Read an OpenSim model file (.osim, formats 20001, 30000 and 40000) into a `motion.Model`.

Formats:
- 4.x (Version >= 40000): ``<Ground>``, ``BodySet``, ``JointSet`` whose joints connect
  PhysicalOffsetFrames (``<frames>``) through ``socket_parent_frame`` / ``socket_child_frame``;
  path points name their frame by ``socket_parent_frame`` (``/bodyset/tibia_r``).
- 3.x and 2.x (Version 30000, 20001): each ``<Body>`` holds its ``<Joint>`` with
  ``parent_body``, ``location_in_parent`` / ``orientation_in_parent`` (frame F in the parent)
  and ``location`` / ``orientation`` (frame M in the child); the ground is the body with an
  empty ``<Joint/>``; path points name their ``<body>``.

Everything that is unsupported or inconsistent raises `InputError` naming the file, the XML path
of the element and the fix; nothing is silently skipped. Rotations given as three angles are
body-fixed x-y-z Euler angles (OpenSim's convention).
"""
from __future__ import annotations

import os

import numpy as np

from .model import (Body, Coordinate, CouplerConstraint, Geometry, Joint, Model, WeldConstraint,
                    frame_transform)
from .joints import JOINT_TYPES, coordinate_order, custom_joint_axes, joint_axes, motion_types
from .paths import read_paths, read_wrap_objects
from ..errors import read_guarded
from .xml_document import Node, function_child, parse_function, read_document

__all__ = ["load_model", "ModelFileWarning"]

_UNSUPPORTED_JOINTS = ("ScapulothoracicJoint", "ConstantCurvatureJoint")


def load_model(path) -> Model:
    """Read an OpenSim model.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.osim`` file (OpenSim 4.x, 3.x or 2.x format).

    Returns
    -------
    Model
        Frozen model (see `motion.osim.model`).

    Raises
    ------
    InputError
        The file is missing, empty, binary, malformed, not an OpenSim model, or uses an
        element that is unsupported or inconsistent (the message names the XML element).
        Anything unexpected that goes wrong while reading the file (a value of a type the
        reader did not foresee) is also reported as one InputError naming the file.
    """
    return read_guarded(lambda: _load_model(path), path, what="model",
                        fix="check the file against an OpenSim 4.x/3.x model, or re-export it from OpenSim")


def _load_model(path) -> Model:
    doc = read_document(path)
    file = doc.file
    try:
        version = int(float(doc.el.get("Version", "0")))
    except ValueError:
        raise doc.error("the Version attribute is not a number", "write e.g. Version=\"40000\"") from None
    model_node = doc.child("Model")
    if model_node is None:
        raise doc.error("the document holds no <Model>", "give an OpenSim model file, not another OpenSim document")
    version = _content_version(model_node, version, file)
    if version >= 40000:
        bodies, joints, coords, frames = _read_4x(model_node)
    else:
        bodies, joints, coords, frames = _read_3x(model_node)
    joints = _order_joints(joints, model_node)
    coord_by_name = {c.name: c for c in coords}
    # model coordinate order: joints in tree order, each joint's own coordinate order
    ordered = [coord_by_name[n] for j in joints for n in j.coordinates]
    couplers, welds = _read_constraints(model_node, coord_by_name, frames, version)
    wraps = read_wrap_objects(model_node, version, frames)
    paths = read_paths(model_node, version, frames, coord_by_name, {w.name for w in wraps})
    return Model(name=model_node.name or os.path.splitext(os.path.basename(file))[0], file=file,
                 version=version, bodies=bodies, joints=joints, coordinates=ordered,
                 couplers=couplers, welds=welds, paths=paths, wrap_objects=wraps)


class ModelFileWarning(UserWarning):
    """The model file is read, but not quite as it says (e.g. its version header)."""


#: elements only OpenSim 4.x writes (3.x keeps joints inside bodies and names a point's <body>)
_MARKERS_4X = ("JointSet", "Ground")
_SOCKETS_4X = ("socket_parent_frame", "socket_parent", "socket_child_frame")


def _content_version(model_node, version: int, file) -> int:
    """The format to read by, decided by the elements present: a file whose header says 3.x (or
    2.x) but whose content is 4.x (a ``<JointSet>`` or ``<Ground>`` under ``<Model>``, or
    ``socket_*`` elements, as some Rajagopal-family files) is read as 4.x with one
    `ModelFileWarning`, as OpenSim 4.6 loads it."""
    if version >= 40000:
        return version
    found = [t for t in _MARKERS_4X if model_node.child(t) is not None]
    if not found:
        found = sorted({el.tag for el in model_node.el.iter() if el.tag in _SOCKETS_4X})[:2]
    if not found:
        return version
    import warnings

    warnings.warn(f"{file}: the header says Version=\"{version}\" (OpenSim {version // 10000}.x) but the "
                  f"content is OpenSim 4.x ({', '.join('<' + t + '>' for t in found)}): read as 4.x, as "
                  "OpenSim 4.6 does. Save the model from OpenSim 4 to fix the header.",
                  ModelFileWarning, stacklevel=3)
    return 40000


# --------------------------------------------------------------------------- coordinates
def _read_coordinate(node: Node, joint_name: str, motion_type: str) -> Coordinate:
    rng = node.floats("range", 2, default=[-np.inf, np.inf])
    if rng[0] > rng[1]:
        raise node.error(f"<range> minimum {rng[0]} exceeds maximum {rng[1]}", "swap the two values",
                         where=f"{node.path}/range")
    return Coordinate(name=node.name, motion_type=motion_type,
                      default_value=node.float("default_value", 0.0), range=rng,
                      clamped=node.bool("clamped", False), locked=node.bool("locked", False),
                      joint=joint_name,
                      free_to_satisfy_constraints=node.bool("is_free_to_satisfy_constraints", False))


def _joint_from_nodes(jnode: Node, parent: str, child: str, tf_pf, tf_cf, coord_nodes: list) -> tuple:
    """Build (Joint, [Coordinate]) from a joint element and its coordinate elements."""
    kind = jnode.tag
    if kind not in JOINT_TYPES:
        if kind in _UNSUPPORTED_JOINTS:
            raise jnode.error(f"joint type {kind} is not supported",
                              f"replace it by a CustomJoint or one of {', '.join(JOINT_TYPES)}")
        raise jnode.error(f"unknown joint type <{kind}>", f"use one of {', '.join(JOINT_TYPES)}")
    if jnode.bool("reverse", False):
        raise jnode.error("reversed joints (<reverse>true</reverse>) are not supported",
                          "re-export the model so that the joint goes from parent to child")
    names = [c.name for c in coord_nodes]
    for c in coord_nodes:
        if not c.name:
            raise c.error("a <Coordinate> has no name", "give every coordinate a unique name attribute")
    if len(set(names)) != len(names):
        raise jnode.error("the joint defines a coordinate twice", "give each coordinate a unique name")
    if kind == "CustomJoint":
        axes = custom_joint_axes(jnode, set(names))
        order = coordinate_order(axes)
        order += [n for n in names if n not in order]   # unused coordinates keep their place at the end
    else:
        axes = joint_axes(kind, tuple(names), jnode)
        order = names
    mtypes = motion_types(kind, axes, tuple(order))
    by_name = {c.name: c for c in coord_nodes}
    coords = [_read_coordinate(by_name[n], jnode.name, mtypes[n]) for n in order]
    radii = None
    if kind == "EllipsoidJoint":
        radii = jnode.floats("radii_x_y_z", 3, default=[np.nan] * 3)
        if not np.all(radii > 0):
            raise jnode.error(f"EllipsoidJoint <radii_x_y_z> must be three positive numbers, got {radii.tolist()}",
                              "give the ellipsoid's three semi-axes", where=f"{jnode.path}/radii_x_y_z")
    joint = Joint(name=jnode.name or f"{parent}_to_{child}", kind=kind, parent=parent, child=child,
                  tf_parent_jointframe=tf_pf, tf_child_jointframe=tf_cf, coordinates=tuple(order), axes=axes,
                  radii=radii)
    return joint, coords


def _geometry_4x(node: Node) -> tuple:
    out = []
    ag = node.child("attached_geometry")
    if ag is not None:
        for g in ag.children("Mesh"):
            f = g.text("mesh_file")
            if f:
                out.append(Geometry(f, g.floats("scale_factors", 3, default=[1, 1, 1])))
    return tuple(out)


def _geometry_3x(node: Node) -> tuple:
    out = []
    vo = node.child("VisibleObject")
    if vo is None:
        return ()
    scale = vo.floats("scale_factors", 3, default=[1, 1, 1])
    for f in vo.names("geometry_files"):
        out.append(Geometry(f, scale))
    for dg in vo.objects("GeometrySet"):
        f = dg.text("geometry_file")
        if f:
            tf = frame_transform(dg.floats("location", 3, default=[0, 0, 0]),
                                 dg.floats("rotation", 3, default=[0, 0, 0]))
            out.append(Geometry(f, scale * dg.floats("scale_factors", 3, default=[1, 1, 1]), tf))
    return tuple(out)


# --------------------------------------------------------------------------- 4.x
def _frame_name(socket: str) -> str:
    return socket.rstrip("/").split("/")[-1]


def _read_4x(model: Node):
    ground = model.child("Ground")
    bodies = [Body("ground", _geometry_4x(ground) if ground is not None else ())]
    for b in model.objects("BodySet"):
        if not b.name:
            raise b.error("a <Body> has no name", "give every body a unique name attribute")
        bodies.append(Body(b.name, _geometry_4x(b)))
    body_names = {b.name for b in bodies}
    if len(body_names) != len(bodies):
        raise model.error("two bodies share a name", "give every body a unique name")
    # frames: "ground", "/bodyset/<b>" and every PhysicalOffsetFrame (by name and by path)
    frames = {"ground": ("ground", np.eye(4))}
    for b in body_names:
        frames[b] = (b, np.eye(4))
    joints, coords = [], []
    jset = model.find("JointSet/objects")
    jnodes = jset.children() if jset is not None else []
    for j in jnodes:
        local = {}
        fr = j.child("frames")
        offset_nodes = fr.children("PhysicalOffsetFrame") if fr is not None else []
        pending = list(offset_nodes)
        for _ in range(len(pending) + 1):        # resolve chains of offset frames
            rest = []
            for f in pending:
                parent_name = _frame_name(f.text("socket_parent", "") or "")
                base = local.get(parent_name) or frames.get(parent_name)
                if base is None:
                    rest.append(f)
                    continue
                tf = base[1] @ frame_transform(f.floats("translation", 3, default=[0, 0, 0]),
                                               f.floats("orientation", 3, default=[0, 0, 0]))
                local[f.name] = (base[0], tf)
                frames[f"/jointset/{j.name}/{f.name}"] = (base[0], tf)
            if len(rest) == len(pending):
                break
            pending = rest
        pending = rest
        for f in pending:
            raise f.error(f"PhysicalOffsetFrame's socket_parent {f.text('socket_parent')!r} is not a body or frame",
                          "point socket_parent at an existing body, e.g. /bodyset/femur_r",
                          where=f"{f.path}/socket_parent")

        def resolve(tag):
            socket = j.text(tag)
            if not socket:
                raise j.error(f"the joint has no <{tag}>", f"add <{tag}> naming a frame", where=f"{j.path}/{tag}")
            name = _frame_name(socket)
            hit = local.get(name) or frames.get(socket) or frames.get(name)
            if hit is None:
                raise j.error(f"<{tag}> {socket!r} names no body or frame", "fix the frame name",
                              where=f"{j.path}/{tag}")
            return hit
        parent, tf_pf = resolve("socket_parent_frame")
        child, tf_cf = resolve("socket_child_frame")
        cnode = j.child("coordinates")
        coord_nodes = cnode.children("Coordinate") if cnode is not None else []
        joint, jc = _joint_from_nodes(j, parent, child, tf_pf, tf_cf, coord_nodes)
        joints.append(joint)
        coords.extend(jc)
    return bodies, joints, coords, frames


# --------------------------------------------------------------------------- 3.x / 2.x
def _read_3x(model: Node):
    bnodes = model.objects("BodySet")
    bodies, joints, coords = [], [], []
    ground = None
    for b in bnodes:
        jholder = b.child("Joint")
        jn = jholder.children() if jholder is not None else []
        if not jn:
            if ground is not None:
                raise b.error(f"bodies {ground!r} and {b.name!r} both have no joint",
                              "connect every body except the ground by a <Joint>")
            ground = b.name
    if ground is None:
        raise model.error("no ground body (a <Body> with an empty <Joint/>)", "add a ground body")
    names = [b.name for b in bnodes]
    if len(set(names)) != len(names):
        raise model.error("two bodies share a name", "give every body a unique name")
    rename = {ground: "ground"}
    for b in bnodes:
        name = rename.get(b.name, b.name)
        bodies.append(Body(name, _geometry_3x(b)))
    frames = {b.name: (b.name, np.eye(4)) for b in bodies}
    frames[ground] = ("ground", np.eye(4))
    for b in bnodes:
        jholder = b.child("Joint")
        jn = jholder.children() if jholder is not None else []
        if not jn:
            continue
        j = jn[0]
        parent = j.text("parent_body")
        if not parent or parent not in frames:
            raise j.error(f"<parent_body> {parent!r} is not a body of the model", "name an existing body",
                          where=f"{j.path}/parent_body")
        tf_pf = frame_transform(*(_six_digits(j.floats(t, 3, default=[0, 0, 0]))
                                  for t in ("location_in_parent", "orientation_in_parent")))
        tf_cf = frame_transform(*(_six_digits(j.floats(t, 3, default=[0, 0, 0])) for t in ("location", "orientation")))
        coord_nodes = j.objects("CoordinateSet")
        joint, jc = _joint_from_nodes(j, rename.get(parent, parent), b.name, tf_pf, tf_cf, coord_nodes)
        joints.append(joint)
        coords.extend(jc)
    return bodies, joints, coords, frames


def _six_digits(values: np.ndarray) -> np.ndarray:
    """Round to 6 significant digits, as OpenSim 4.x does when it converts a 3.x/2.x joint's
    location/orientation (in parent and in child) into PhysicalOffsetFrames: it writes them
    through a default-precision text stream (checked with OpenSim 4.6: an orientation of
    -1.5707963267948966 becomes -1.5708)."""
    return np.array([float(f"{v:.6g}") for v in values])


def _order_joints(joints: list, model: Node) -> tuple:
    """Joints with every parent before its children; each body has exactly one joint."""
    by_child = {}
    for j in joints:
        if j.child == "ground":
            raise model.error(f"joint {j.name!r} has the ground as its child", "make the ground the parent")
        if j.child in by_child:
            raise model.error(f"body {j.child!r} is the child of two joints ({by_child[j.child].name!r}, {j.name!r})",
                              "closed loops need a constraint, not a second joint")
        by_child[j.child] = j
    placed, out = {"ground"}, []
    remaining = list(joints)
    while remaining:
        rest = []
        for j in remaining:             # stable: a file already in tree order keeps its order
            if j.parent in placed:
                out.append(j)
                placed.add(j.child)
            else:
                rest.append(j)
        if len(rest) == len(remaining):
            bad = rest[0]
            raise model.error(f"joint {bad.name!r} connects body {bad.child!r} to {bad.parent!r}, which is not "
                              "connected to the ground", "connect every body to the ground through joints")
        remaining = rest
    return tuple(out)


# --------------------------------------------------------------------------- constraints
def _read_constraints(model: Node, coord_by_name: dict, frames: dict, version: int):
    couplers, welds = [], []
    for c in model.objects("ConstraintSet"):
        if c.bool("isDisabled", False) or not c.bool("isEnforced", True):
            continue
        if c.tag == "CoordinateCouplerConstraint":
            indep = c.names("independent_coordinate_names")
            dep = c.text("dependent_coordinate_name")
            for n in indep + ((dep,) if dep else ()):
                if n not in coord_by_name:
                    raise c.error(f"coupler names coordinate {n!r} that the model does not have",
                                  "fix the coordinate name")
            if not dep or not indep:
                raise c.error("coupler needs independent_coordinate_names and dependent_coordinate_name",
                              "name both coordinates")
            if len(indep) != 1:
                raise c.error(f"couplers with {len(indep)} independent coordinates are not supported",
                              "use one independent coordinate per CoordinateCouplerConstraint")
            fnode = function_child(c, "coupled_coordinates_function")
            if fnode is None:
                raise c.error("coupler has no <coupled_coordinates_function>", "add the coupling function")
            couplers.append(CouplerConstraint(c.name or f"{dep}_coupler", indep, dep, parse_function(fnode),
                                              c.float("scale_factor", 1.0)))
        elif c.tag == "WeldConstraint":
            welds.append(_read_weld(c, frames, version))
        else:
            raise c.error(f"constraint type {c.tag} is not supported",
                          "remove it or use a CoordinateCouplerConstraint / WeldConstraint")
    deps = [c.dependent for c in couplers]
    if len(set(deps)) != len(deps):
        raise model.error("a coordinate is the dependent of two couplers", "keep one coupler per dependent coordinate")
    return tuple(couplers), tuple(welds)


def _read_weld(c: Node, frames: dict, version: int) -> WeldConstraint:
    if c.child("body_1") is not None:
        b1, b2 = c.text("body_1"), c.text("body_2")
        out = []
        for b, k in ((b1, 1), (b2, 2)):
            if b not in frames:
                raise c.error(f"<body_{k}> {b!r} is not a body of the model", "name an existing body",
                              where=f"{c.path}/body_{k}")
            out.append((frames[b][0], frame_transform(c.floats(f"location_body_{k}", 3, default=[0, 0, 0]),
                                                      c.floats(f"orientation_body_{k}", 3, default=[0, 0, 0]))))
    else:
        out = []
        local = {}
        fr = c.child("frames")
        for f in (fr.children("PhysicalOffsetFrame") if fr is not None else []):
            base = frames.get(_frame_name(f.text("socket_parent", "") or ""))
            if base is not None:
                local[f.name] = (base[0], base[1] @ frame_transform(f.floats("translation", 3, default=[0, 0, 0]),
                                                                    f.floats("orientation", 3, default=[0, 0, 0])))
        for k in (1, 2):
            socket = c.text(f"socket_frame{k}") or ""
            hit = local.get(_frame_name(socket)) or frames.get(socket) or frames.get(_frame_name(socket))
            if hit is None:
                raise c.error(f"<socket_frame{k}> {socket!r} names no body or frame", "fix the frame name",
                              where=f"{c.path}/socket_frame{k}")
            out.append(hit)
    return WeldConstraint(c.name or "weld", out[0][0], out[1][0], out[0][1], out[1][1])
