"""motion.osim.builder: files that OpenSim 4.6 loads, with lengths that match hand geometry."""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from motion.osim.builder import ModelBuilder, TransformAxisSpec

R, D, A, B = 0.02, 0.01, 0.15, 0.12   # pulley radius, offset of the line, attachment distances


def _pulley_builder():
    return (ModelBuilder("pulley")
            .add_body("upper", meshes=["upper.stl"], mesh_scale=(1, 1, 1))
            .add_weld_joint("fix", "ground", "upper", location_in_parent=(0, 1, 0))
            .add_body("lower")
            .add_pin_joint("knee", "upper", "lower", "q", range=(-1.0, 2.5))
            .add_wrap_cylinder("upper", "cyl", radius=R, length=0.1, quadrant="-x")
            .add_muscle("ext", [("upper", (-D, A, 0)), ("lower", (-D, -B, 0))], wraps=["cyl"])
            .add_muscle("flex", [("upper", (0.02, A, 0)), ("lower", (0.03, -B, 0))],
                        kind="PathActuator"))


def _pulley_length(theta):
    """Belt length around the -x side of a circle of radius R (2D, tangent + arc + tangent)."""
    p1 = np.array([-D, A])
    c, s = math.cos(theta), math.sin(theta)
    p2 = np.array([-D * c + B * s, -D * s - B * c])
    t1, t2 = math.sqrt(p1 @ p1 - R * R), math.sqrt(p2 @ p2 - R * R)
    a1 = math.atan2(p1[1], p1[0]) + math.acos(R / np.hypot(*p1))
    a2 = math.atan2(p2[1], p2[0]) - math.acos(R / np.hypot(*p2))
    return t1 + t2 + R * ((a2 - a1) % (2 * math.pi))


def _path(model, name, osim):
    force = model.getForceSet().get(name)
    for cls in (osim.Thelen2003Muscle, osim.PathActuator):
        obj = cls.safeDownCast(force)
        if obj is not None:
            return obj.getGeometryPath()
    raise AssertionError(name)


def test_xml_structure_and_determinism():
    b = _pulley_builder()
    text = b.to_xml()
    assert text == _pulley_builder().to_xml()          # same calls -> same bytes
    doc = ET.fromstring(text.split("\n", 1)[1])
    assert doc.tag == "OpenSimDocument" and doc.get("Version") == "40000"
    names = [e.get("name") for e in doc.find("Model/BodySet/objects")]
    assert names == ["upper", "lower"]
    coord = doc.find("Model/JointSet/objects/PinJoint/coordinates/Coordinate")
    assert coord.get("name") == "q" and coord.find("range").text == "-1 2.5"
    assert doc.find(".//PathWrap/wrap_object").text == "cyl"
    assert doc.find(".//Mesh/mesh_file").text == "upper.stl"


@pytest.mark.parametrize("bad", [
    lambda b: b.add_body("upper"),                                         # duplicate body
    lambda b: b.add_pin_joint("j", "upper", "nobody", "q2"),               # unknown body
    lambda b: b.add_pin_joint("j", "ground", "lower", "q2"),               # second parent
    lambda b: b.add_wrap_cylinder("upper", "c2", radius=0.01, length=0.1, quadrant="w"),
    lambda b: b.add_wrap_sphere("upper", "s", radius=-1.0),
    lambda b: b.add_muscle("m", [("upper", (0, 0, 0))]),                   # one point
    lambda b: b.add_muscle("m", [("upper", (0, 0, 0)), ("lower", (0, 0))]),  # 2-vector
    lambda b: b.add_muscle("m", [("upper", (0, 0, 0)), ("lower", (0, 0, 0))], wraps=["x"]),
    lambda b: b.add_muscle("ext", [("upper", (0, 0, 0)), ("lower", (0, 0, 0))]),  # duplicate
    lambda b: b.add_muscle("m", [("upper", (0, 0, 0)), ("lower", (0, 0, 0))], kind="Hill"),
])
def test_rejects_bad_calls(bad):
    with pytest.raises(ValueError):
        bad(_pulley_builder())


def test_pulley_and_straight_lengths_match_hand_geometry_in_opensim(osim, tmp_path):
    osim.Logger.removeFileSink()   # no opensim.log beside the model files
    path = _pulley_builder().write(tmp_path / "pulley.osim")
    model = osim.Model(str(path))
    state = model.initSystem()
    q = model.getCoordinateSet().get("q")
    ext, flex = _path(model, "ext", osim), _path(model, "flex", osim)
    for theta in np.linspace(0.0, 2.4, 7):
        q.setValue(state, float(theta))
        model.realizePosition(state)
        # OpenSim's wrap is analytic for a cylinder: agreement to round-off (measured 1e-12)
        assert ext.getLength(state) == pytest.approx(_pulley_length(theta), abs=1e-9)
        c, s = math.cos(theta), math.sin(theta)
        p2 = np.array([0.03 * c + B * s, 0.03 * s - B * c])
        assert flex.getLength(state) == pytest.approx(np.hypot(*(p2 - [0.02, A])), abs=1e-12)
        # pulley moment arm = -R exactly while wrapped (extensor lengthens with q)
        assert ext.computeMomentArm(state, q) == pytest.approx(-R, abs=1e-7)


def test_custom_joint_and_sphere_pose_in_opensim(osim, tmp_path):
    osim.Logger.removeFileSink()   # no opensim.log beside the model files
    ax = TransformAxisSpec
    b = (ModelBuilder("cj")
         .add_body("a").add_custom_joint(
             "j", "ground", "a",
             coordinates=[{"name": "rz", "range": (-2, 2), "default": 0.3},
                          {"name": "ty", "range": (-1, 1), "locked": True, "default": 0.05}],
             rotations=[ax(axis=(0, 0, 1), coordinate="rz", slope=2.0, intercept=0.1)],
             translations=[ax(axis=(0, 1, 0), coordinate="ty")],
             location_in_parent=(0.1, 0.2, 0.3))
         .add_wrap_sphere("a", "ball", radius=0.01, translation=(0, 0.01, 0)))
    model = osim.Model(str(b.write(tmp_path / "cj.osim")))
    state = model.initSystem()
    cs = model.getCoordinateSet()
    assert cs.get("ty").getLocked(state)
    assert cs.get("rz").getValue(state) == pytest.approx(0.3)
    model.realizePosition(state)
    tf = model.getBodySet().get("a").getTransformInGround(state)
    p = np.array([tf.p().get(i) for i in range(3)])
    rot = tf.R()
    angle = 2.0 * 0.3 + 0.1
    # rotation about z by 2 q + 0.1 then translation 0.05 along y, after the offset (0.1,0.2,0.3)
    np.testing.assert_allclose(p, [0.1, 0.25, 0.3], atol=1e-12)
    assert rot.get(0, 0) == pytest.approx(math.cos(angle), abs=1e-12)
    assert rot.get(1, 0) == pytest.approx(math.sin(angle), abs=1e-12)
    wraps = model.getBodySet().get("a").getWrapObjectSet()
    assert wraps.getSize() == 1 and wraps.get(0).getConcreteClassName() == "WrapSphere"


def test_write_is_atomic_on_failure(tmp_path, monkeypatch):
    b = _pulley_builder()
    target = tmp_path / "m.osim"

    def boom():
        raise RuntimeError("disk full")

    monkeypatch.setattr(b, "to_xml", boom)
    with pytest.raises(RuntimeError):
        b.write(target)
    assert list(tmp_path.iterdir()) == []
