"""Action lines: OpenSim 4.6 references, live OpenSim on models built with its API (speed: bench/lines.py)."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from motion.wrapping.action_lines import action_lines, polyline_length, spanned_coordinates
from motion.osim.kinematics import body_poses, motion_from_array
from motion.wrapping.moment_arms import opensim_moment_arms
from motion.osim.reader import load_model

from meshes import opensim_ground_transforms
from reference import CASES, ReferenceCase, case_id


def _have_wrapping() -> bool:
    try:
        return importlib.util.find_spec("motion.wrapping.batch") is not None and \
            importlib.import_module("motion.wrapping.batch") is not None
    except ImportError:
        return False


def _compute(opensim_dir, case, wrapped: bool):
    rc = ReferenceCase(opensim_dir, *case)
    model = load_model(rc.model_file)
    names = [p.name for p in model.paths if bool(p.wraps) == wrapped]
    if not names:
        pytest.skip("no such paths in this model")
    lines = action_lines(model, motion_from_array(model, rc.q_used(model), rc.time), muscles=names)
    return rc, model, lines


def _long(rc, model, lines):
    ma = rc.moment_arms
    ma = ma[ma.muscle.isin(lines.muscle_names)]
    m_idx = np.array([lines.muscle_names.index(n) for n in ma.muscle])
    c_idx = np.array([model.coordinate_index(c) for c in ma.coordinate])
    mine = lines.moment_arms[ma.frame.to_numpy(), m_idx, c_idx]
    return ma, m_idx, c_idx, mine


@pytest.mark.parametrize("case", CASES, ids=[case_id(c) for c in CASES])
def test_unwrapped_paths_match_opensim(opensim_dir, case):
    rc, model, lines = _compute(opensim_dir, case, wrapped=False)
    ref_len = rc.path_lengths(model)[:, [model.path_names.index(n) for n in lines.muscle_names]]
    # acceptance 1e-6 m; measured <1e-13 (same arithmetic as OpenSim)
    np.testing.assert_allclose(lines.lengths, ref_len, rtol=0, atol=1e-9)
    ma, m_idx, c_idx, mine = _long(rc, model, lines)
    # the reference lists exactly the coordinates each path spans
    spanned = np.zeros_like(lines.spanned)
    spanned[m_idx, c_idx] = True
    np.testing.assert_array_equal(lines.spanned, spanned)
    # -dL/dq vs OpenSim's central differences (h = 1e-5, error ~h^2 |L'''| < 1e-6): all statuses
    np.testing.assert_allclose(mine, ma.neg_dLdq_fd.to_numpy(), rtol=0, atol=1e-5)
    # OpenSim's computeMomentArm equals -dL/dq for independent coordinates of unwrapped paths,
    # except about BallJoint coordinates (angular-velocity mobilities, see motion.wrapping.action_lines)
    ball = {c for j in model.joints if j.kind == "BallJoint" for c in j.coordinates}
    sel = ((ma.coord_status == "independent") & ~ma.coordinate.isin(ball)).to_numpy()
    np.testing.assert_allclose(mine[sel], ma.moment_arm.to_numpy()[sel], rtol=0, atol=1e-6)
    # OpenSim's own convention, BallJoint mobilities included, for every independent coordinate
    ours_osim = opensim_moment_arms(model, lines)[ma.frame.to_numpy(), m_idx, c_idx]
    sel = (ma.coord_status == "independent").to_numpy()
    np.testing.assert_allclose(ours_osim[sel], ma.moment_arm.to_numpy()[sel], rtol=0, atol=1e-6)
    # not spanned: exactly zero
    assert np.all(lines.moment_arms[:, ~lines.spanned] == 0.0)


WRAPPED = [c for c in CASES if c[0].startswith("Arm26") or "WrapPath" in c[0]]


@pytest.mark.skipif(not _have_wrapping(), reason="motion.wrapping.batch (the wrap helper's part) is not available yet")
@pytest.mark.parametrize("case", WRAPPED, ids=[case_id(c) for c in WRAPPED])
def test_wrapped_paths_match_opensim(opensim_dir, case):
    rc, model, lines = _compute(opensim_dir, case, wrapped=True)
    ref_len = rc.path_lengths(model)[:, [model.path_names.index(n) for n in lines.muscle_names]]
    np.testing.assert_allclose(lines.lengths, ref_len, rtol=0, atol=1e-6)
    ma, m_idx, c_idx, mine = _long(rc, model, lines)
    ind = (ma.coord_status == "independent").to_numpy()
    np.testing.assert_allclose(mine[ind], ma.neg_dLdq_fd.to_numpy()[ind], rtol=0, atol=1e-5)


def test_polyline_length_analytic():
    # a unit square traversed with the third point inactive in frame 1
    pts = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]] * 2, dtype=float)
    act = np.array([[True, True, True, True], [True, True, False, True]])
    d_pts = np.zeros((2, 4, 1, 3))
    d_pts[:, 3, 0] = [0.0, 1.0, 0.0]                  # last point moves along +y per unit q
    length, d_length = polyline_length(pts, act, d_pts)
    np.testing.assert_allclose(length, [3.0, 1.0 + np.sqrt(2.0)])
    np.testing.assert_allclose(d_length[:, 0], [0.0, np.sqrt(0.5)])


def test_single_pin_moment_arm_is_the_perpendicular_distance(tmp_path):
    """Analytic pulley-free case: a two-point path across a pin joint; r = d1 d2 sin(theta) / L."""
    from motion.osim.builder import ModelBuilder

    xml = (ModelBuilder("pin")
           .add_body("upper").add_weld_joint("fix", "ground", "upper")
           .add_body("lower")
           .add_pin_joint("knee", "upper", "lower", "knee_angle", location_in_parent=(0, 0, 0), range=(-3.0, 3.0))
           .add_muscle("m", [("upper", (0.0, 0.3, 0.0)), ("lower", (0.0, -0.2, 0.0))])
           .to_xml())
    path = tmp_path / "pin.osim"
    path.write_text(xml)
    model = load_model(path)
    theta = np.linspace(-2.5, 2.5, 11)
    lines = action_lines(model, theta[:, None])
    a, b = 0.3, 0.2                                   # distances of the two points from the axis
    length = np.sqrt(a * a + b * b + 2 * a * b * np.cos(theta))   # law of cosines (angle pi - theta)
    np.testing.assert_allclose(lines.lengths[:, 0], length, atol=1e-15)
    np.testing.assert_allclose(lines.moment_arms[:, 0, 0], a * b * np.sin(theta) / length, atol=1e-15)


def test_muscle_selection_and_errors(opensim_dir):
    from motion.errors import InputError

    model = load_model(opensim_dir / "Gait2392_Simbody" / "gait2392_thelen2003muscle.osim")
    q = np.tile([c.default_value for c in model.coordinates], (3, 1))
    lines = action_lines(model, q, muscles=["semimem_r", "rect_fem_r"])
    assert lines.muscle_names == ("semimem_r", "rect_fem_r")
    assert lines.moment_arms.shape == (3, 2, len(model.coordinates))
    np.testing.assert_array_equal(lines.spanned[0], spanned_coordinates(model, model.path("semimem_r")))
    with pytest.raises(InputError, match="no path force named 'biceps'"):
        action_lines(model, q, muscles=["biceps"])
    # points: the inactive conditional point of semimem_r is masked out at full knee extension
    assert lines.point_labels[0][: len(model.path("semimem_r").points)] == tuple(
        p.name for p in model.path("semimem_r").points)



# ------------------------------------------------------------------ live OpenSim on built models
BUILD_SCRIPT = textwrap.dedent('''
    import os, sys
    import opensim as osim
    osim.Logger.setLevelString("error")
    KEEP = []
    m = osim.Model(); m.setName("live_test")
    g = m.getGround()
    bodies = [osim.Body(n, 1.0, osim.Vec3(0), osim.Inertia(0.1)) for n in ("b1", "b2", "b3")]
    for b in bodies:
        m.addBody(b)
    b1, b2, b3 = bodies
    pin = osim.PinJoint("pin", g, osim.Vec3(0.01, 0.5, 0.02), osim.Vec3(0.1, 0.2, 0.3),
                        b1, osim.Vec3(0, 0.2, 0), osim.Vec3(0, 0, 0.1))
    uni = osim.UniversalJoint("uni", b1, osim.Vec3(0.02, -0.3, 0.01), osim.Vec3(0.3, -0.1, 0.2),
                              b2, osim.Vec3(0, 0.1, 0), osim.Vec3(0.05, 0, 0))
    st = osim.SpatialTransform()
    for k, ax in enumerate([(0.1, 0.2, 1.0), (1, 0, 0), (0, 1, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]):
        st.updTransformAxis(k).setAxis(osim.Vec3(*ax))
        st.updTransformAxis(k).set_function(osim.Constant(0.0))
    st.updTransformAxis(0).setCoordinateNames(osim.ArrayStr("knee", 1))
    st.updTransformAxis(0).set_function(osim.LinearFunction(1, 0))
    spl = osim.SimmSpline()
    for x, y in [(-2, 0.01), (-1, 0.03), (0, 0.0), (0.5, -0.02), (1.5, 0.01)]:
        spl.addPoint(x, y)
    st.updTransformAxis(3).setCoordinateNames(osim.ArrayStr("knee", 1))
    st.updTransformAxis(3).set_function(spl)
    st.updTransformAxis(4).setCoordinateNames(osim.ArrayStr("knee_ty", 1))
    st.updTransformAxis(4).set_function(osim.LinearFunction(1, 0))
    cj = osim.CustomJoint("custom", b2, osim.Vec3(0, -0.25, 0), osim.Vec3(0, 0, 0),
                          b3, osim.Vec3(0, 0.05, 0), osim.Vec3(0, 0, 0), st)
    for j in (pin, uni, cj):
        m.addJoint(j)
    cc = osim.CoordinateCouplerConstraint(); cc.setName("ty_coupler")
    cc.setIndependentCoordinateNames(osim.ArrayStr("knee", 1)); cc.setDependentCoordinateName("knee_ty")
    spl2 = osim.SimmSpline()
    for x, y in [(-2, -0.01), (-1, 0.02), (0, 0.0), (1, 0.015), (2, -0.005)]:
        spl2.addPoint(x, y)
    cc.setFunction(spl2); KEEP.append(spl2)
    m.addConstraint(cc)
    for name, pts in [("m1", [(g, (0.02, 0.6, 0.05)), (b1, (0.03, -0.1, 0.02)), (b2, (0.01, -0.05, 0.03)),
                              (b3, (0.02, -0.1, 0.0))]),
                      ("m2", [(b1, (-0.03, 0.0, 0.01)), (b3, (-0.02, -0.05, 0.01))])]:
        a = osim.PathActuator(); a.setName(name)
        for k, (body, p) in enumerate(pts):
            a.addNewPathPoint(f"{name}_p{k}", body, osim.Vec3(*p))
        m.addForce(a)
    m.finalizeConnections(); m.initSystem()
    m.printToXML(sys.argv[1])
    sys.stdout.flush()
    os._exit(0)   # skip SWIG destructors (shared ownership of the functions)
''')


@pytest.fixture(scope="module")
def live_model(osim, tmp_path_factory):
    """A 4.x model made with the OpenSim API: PinJoint, UniversalJoint, a CustomJoint with a
    MultiplierFunction(SimmSpline) translation and a SimmSpline CoordinateCouplerConstraint."""
    folder = tmp_path_factory.mktemp("live")
    raw = folder / "live_raw.osim"
    subprocess.run([sys.executable, "-c", BUILD_SCRIPT, str(raw)], check=True, timeout=120)
    # OpenSim 4.6's Python MultiplierFunction crashes on use; put it in the XML as OpenSim prints it
    tree = ET.parse(raw)
    for axis in tree.getroot().iter("TransformAxis"):
        if axis.get("name") == "translation1":
            spline = axis.find("SimmSpline")
            axis.remove(spline)
            spline.attrib.pop("name", None)
            mult = ET.SubElement(axis, "MultiplierFunction", name="function")
            ET.SubElement(mult, "function").append(spline)
            ET.SubElement(mult, "scale").text = "1.7"
    path = folder / "live.osim"
    tree.write(path)
    return path


def test_live_opensim_models(osim, live_model):
    model = load_model(live_model)
    assert [j.kind for j in model.joints] == ["PinJoint", "UniversalJoint", "CustomJoint"]
    assert type(model.joints[2].axes[3].function).__name__ == "MultiplierFunction"
    om = osim.Model(str(live_model))
    state = om.initSystem()
    cs = om.getCoordinateSet()
    assert [cs.get(i).getName() for i in range(cs.getSize())] == list(model.coordinate_names)
    rng = np.random.default_rng(11)
    indep = [c for c in model.coordinate_names if c != "knee_ty"]
    q_ref, tf_ref, len_ref, ma_ref = [], [], [], []
    bodies = [om.getBodySet().get(i) for i in range(om.getBodySet().getSize())]
    paths = [osim.PathActuator.safeDownCast(om.getForceSet().get(i)).getGeometryPath()
             for i in range(om.getForceSet().getSize())]
    for _ in range(6):
        for c in indep:
            cs.get(c).setValue(state, float(rng.uniform(-1.2, 1.2)), False)
        om.assemble(state)
        om.realizePosition(state)
        q_ref.append([cs.get(c).getValue(state) for c in model.coordinate_names])
        tf_ref.append(opensim_ground_transforms(bodies, state))
        len_ref.append([p.getLength(state) for p in paths])
        ma_ref.append([[p.computeMomentArm(state, cs.get(c)) for c in indep] for p in paths])
    q_ref = np.array(q_ref)
    # give only the independent coordinates (dependent at 0): our couplers must rebuild knee_ty
    q_in = q_ref.copy()
    q_in[:, model.coordinate_index("knee_ty")] = 0.0
    poses = body_poses(model, q_in)
    np.testing.assert_allclose(poses.q, q_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(poses.tf_ground_body[:, 1:], np.array(tf_ref), rtol=0, atol=1e-12)
    lines = action_lines(model, q_in)
    np.testing.assert_allclose(lines.lengths, np.array(len_ref), rtol=0, atol=1e-12)
    cols = [model.coordinate_index(c) for c in indep]
    np.testing.assert_allclose(lines.moment_arms[:, :, cols], np.array(ma_ref), rtol=0, atol=1e-12)


def test_frame_blocks_give_the_same_answer(opensim_dir, monkeypatch):
    import importlib

    al_mod = importlib.import_module("motion.wrapping.action_lines")   # the module (motion.wrapping.action_lines is the function)

    rc = ReferenceCase(opensim_dir, *CASES[0])            # Arm26: wrapped and unwrapped paths
    model = load_model(rc.model_file)
    q = rc.q_used(model)[:40]
    whole = action_lines(model, q)
    monkeypatch.setattr(al_mod, "FRAME_BLOCK", 7)
    parts = action_lines(model, q)
    for key in ("lengths", "moment_arms", "q", "points", "point_mask"):
        np.testing.assert_array_equal(getattr(parts, key), getattr(whole, key), err_msg=key)
    assert parts.point_labels == whole.point_labels



@pytest.mark.parametrize("case", [CASES[0], CASES[2], CASES[4]], ids=case_id)
def test_compiled_kernel_equals_numpy_path(opensim_dir, monkeypatch, case):
    """The numba polyline kernel and the numpy path are two independent implementations of the
    same sums (arm26: wrapped + unwrapped paths; gait2392: conditional points; moving points):
    they agree to rounding (1e-13 m: ~100 ulp of lengths of order 1 m) and the point data exactly."""
    import importlib

    al_mod = importlib.import_module("motion.wrapping.action_lines")
    pytest.importorskip("numba")
    rc = ReferenceCase(opensim_dir, *case)
    model = load_model(rc.model_file)
    q = rc.q_used(model)[:60]
    compiled = action_lines(model, q)
    from polyline_oracle import unwrapped_paths_numpy   # tests/motion (rootdir-relative import)

    monkeypatch.setattr(al_mod, "_unwrapped_paths", unwrapped_paths_numpy)
    plain = action_lines(model, q)
    for key in ("lengths", "moment_arms", "points"):
        np.testing.assert_allclose(getattr(compiled, key), getattr(plain, key), rtol=0, atol=1e-13, err_msg=key)
    for key in ("point_mask", "point_order", "spanned"):
        np.testing.assert_array_equal(getattr(compiled, key), getattr(plain, key), err_msg=key)
    assert compiled.point_labels == plain.point_labels



@pytest.mark.parametrize("case", [CASES[0], CASES[3], CASES[7], CASES[12]], ids=case_id)
def test_body_twists_from_the_chain_equal_those_from_d_tf(opensim_dir, case):
    """The twists propagated along the joint chain (used when no path wraps) equal the ones
    read off d tf / dq (omega = vee(dR R^T), v = dt/dq) to rounding (1e-13: ~100 ulp of unit
    rates); arm26 (pins), couplers + moving points, a ball joint, a constrained model."""
    import importlib

    from motion.osim.kinematics import _pose_twists, body_pose_derivatives

    al_mod = importlib.import_module("motion.wrapping.action_lines")
    rc = ReferenceCase(opensim_dir, *case)
    model = load_model(rc.model_file)
    q = rc.q_used(model)[:50]
    tf, dtf, q_used, _ = body_pose_derivatives(model, q)
    tf2, twist, q_used2, _ = _pose_twists(model, q)
    n_bodies, n_coords = dtf.shape[1:3]
    b, c = np.meshgrid(np.arange(n_bodies), np.arange(n_coords), indexing="ij")
    expected = al_mod._twists(tf, dtf, b.ravel(), c.ravel()).reshape(twist.shape)
    np.testing.assert_array_equal(tf2, tf)
    np.testing.assert_array_equal(q_used2, q_used)
    np.testing.assert_allclose(twist, expected, rtol=0, atol=1e-13)
    assert np.abs(twist).max() > 0.1      # not trivially zero


ELLIPSOID_SCRIPT = textwrap.dedent('''
    import os, sys
    import opensim as osim
    osim.Logger.setLevelString("error")
    m = osim.Model(); m.setName("ellipsoid")
    b = osim.Body("b", 1.0, osim.Vec3(0), osim.Inertia(0.1)); m.addBody(b)
    m.addJoint(osim.EllipsoidJoint("ell", m.getGround(), osim.Vec3(0.1, 0.2, 0.3), osim.Vec3(0.2, -0.1, 0.3),
                                   b, osim.Vec3(0.01, 0.02, 0.03), osim.Vec3(0.1, 0.0, -0.2),
                                   osim.Vec3(0.07, 0.05, 0.12)))
    a = osim.PathActuator(); a.setName("act")
    a.addNewPathPoint("p0", m.getGround(), osim.Vec3(0.3, 0.1, -0.1))
    a.addNewPathPoint("p1", b, osim.Vec3(0.05, -0.1, 0.02))
    m.addForce(a)
    m.initSystem()
    m.printToXML(sys.argv[1])
    sys.stdout.flush()
    os._exit(0)
''')


def test_live_opensim_ellipsoid_joint(osim, tmp_path):
    """EllipsoidJoint: M's origin at radii * z_M; OpenSim's moment arms in angular-velocity mobilities."""
    path = tmp_path / "ellipsoid.osim"
    subprocess.run([sys.executable, "-c", ELLIPSOID_SCRIPT, str(path)], check=True, timeout=120)
    model = load_model(path)
    np.testing.assert_array_equal(model.joints[0].radii, [0.07, 0.05, 0.12])
    om = osim.Model(str(path))
    state = om.initSystem()
    cs = om.getCoordinateSet()
    body = om.getBodySet().get(0)
    gp = osim.PathActuator.safeDownCast(om.getForceSet().get(0)).getGeometryPath()
    q = np.random.default_rng(5).uniform(-1.0, 1.0, (5, 3))
    tf_ref, len_ref, ma_ref = [], [], []
    for row in q:
        for i in range(3):
            cs.get(i).setValue(state, float(row[i]), False)
        om.realizePosition(state)
        tf_ref.append(opensim_ground_transforms([body], state)[0])
        len_ref.append(gp.getLength(state))
        ma_ref.append([gp.computeMomentArm(state, cs.get(i)) for i in range(3)])
    np.testing.assert_allclose(body_poses(model, q).tf_ground_body[:, 1], np.array(tf_ref), rtol=0, atol=1e-12)
    lines = action_lines(model, q)
    np.testing.assert_allclose(lines.lengths[:, 0], len_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(opensim_moment_arms(model, lines)[:, 0], np.array(ma_ref), rtol=0, atol=1e-12)
    # and -dL/dq itself is the derivative of the length (central differences, h = 1e-6)
    h = 1e-6
    for k in range(3):
        dq = np.zeros(3)
        dq[k] = h
        fd = -(action_lines(model, q + dq).lengths - action_lines(model, q - dq).lengths)[:, 0] / (2 * h)
        np.testing.assert_allclose(lines.moment_arms[:, 0, k], fd, rtol=0, atol=1e-8)


JOINTS_SCRIPT = """
import os, sys
import opensim as osim
osim.Logger.setLevelString("error")
m = osim.Model(); m.setName("joints")
B = [osim.Body(f"b{i}", 1.0, osim.Vec3(0), osim.Inertia(0.1)) for i in range(5)]
for b in B: m.addBody(b)
g = m.getGround()
V = osim.Vec3
m.addJoint(osim.FreeJoint("free", g, V(0.1, 0.2, 0.3), V(0.2, -0.1, 0.3), B[0], V(0.01, 0.02, 0.03), V(0.1, 0.0, -0.2)))
m.addJoint(osim.GimbalJoint("gimbal", B[0], V(0.0, -0.2, 0.1), V(0.3, 0.1, -0.2), B[1], V(0.02, 0.01, 0.0), V(0.0, 0.2, 0.1)))
m.addJoint(osim.SliderJoint("slider", B[1], V(0.05, -0.1, 0.0), V(0.1, 0.4, -0.3), B[2], V(0.0, 0.03, 0.01), V(0.2, 0.0, 0.0)))
m.addJoint(osim.PlanarJoint("planar", B[2], V(0.0, -0.15, 0.02), V(-0.2, 0.1, 0.3), B[3], V(0.01, 0.0, 0.02), V(0.0, -0.1, 0.2)))
m.addJoint(osim.BallJoint("ball", B[3], V(0.02, -0.1, 0.0), V(0.1, 0.1, 0.1), B[4], V(0.0, 0.05, 0.0), V(-0.1, 0.2, 0.0)))
a = osim.PathActuator(); a.setName("act")
a.addNewPathPoint("p0", g, V(0.3, 0.1, -0.1))
for i, b in enumerate(B):
    a.addNewPathPoint(f"p{i + 1}", b, V(0.03 * (i + 1), -0.05, 0.02 * (-1) ** i))
m.addForce(a)
m.initSystem()
m.printToXML(sys.argv[1])
sys.stdout.flush()
os._exit(0)
"""


def test_live_opensim_every_joint_type(osim, tmp_path):
    """Free, Gimbal, Slider, Planar and Ball joints in one chain: poses, length and OpenSim's own
    moment arms (Free and Ball rotations in angular-velocity mobilities) to rounding."""
    path = tmp_path / "joints.osim"
    subprocess.run([sys.executable, "-c", JOINTS_SCRIPT, str(path)], check=True, timeout=120)
    model = load_model(path)
    om = osim.Model(str(path))
    state = om.initSystem()
    cs = om.getCoordinateSet()
    assert [cs.get(i).getName() for i in range(cs.getSize())] == list(model.coordinate_names)
    gp = osim.PathActuator.safeDownCast(om.getForceSet().get(0)).getGeometryPath()
    bodies = [om.getBodySet().get(i) for i in range(om.getBodySet().getSize())]
    q = np.random.default_rng(2).uniform(-0.8, 0.8, (4, len(model.coordinates)))
    tf_ref, len_ref, ma_ref = [], [], []
    for row in q:
        for i, v in enumerate(row):
            cs.get(i).setValue(state, float(v), False)
        om.realizePosition(state)
        tf_ref.append(opensim_ground_transforms(bodies, state))
        len_ref.append(gp.getLength(state))
        ma_ref.append([gp.computeMomentArm(state, cs.get(i)) for i in range(cs.getSize())])
    np.testing.assert_allclose(body_poses(model, q).tf_ground_body[:, 1:], np.array(tf_ref), rtol=0, atol=1e-12)
    lines = action_lines(model, q)
    np.testing.assert_allclose(lines.lengths[:, 0], len_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(opensim_moment_arms(model, lines)[:, 0], np.array(ma_ref), rtol=0, atol=1e-12)


def test_live_opensim_lhdl_3x_model(osim, lhdl_dir):
    """The LHDL hip (a 3.x file with Latin-1 bytes) against OpenSim 4.6 loading the same file."""
    import warnings

    import motion

    path = lhdl_dir / "model" / "LHDL_hip_r.osim"
    model = load_model(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")             # the file's extra columns and missing pelvis
        mot = motion.load_motion(lhdl_dir / "model" / "motions" / "hip_flexion.mot", model)
    q = mot.q[::5]
    om = osim.Model(str(path))
    state = om.initSystem()
    cs = om.getCoordinateSet()
    muscles = [om.getMuscles().get(n) for n in model.path_names]
    bodies = [om.getBodySet().get(i) for i in range(om.getBodySet().getSize())]
    assert [b.getName() for b in bodies] == list(model.body_names[1:])
    tf_ref, len_ref, ma_ref = [], [], []
    for row in q:
        for name, v in zip(model.coordinate_names, row):
            cs.get(name).setValue(state, float(v), False)
        om.realizePosition(state)
        tf_ref.append(opensim_ground_transforms(bodies, state))
        len_ref.append([mus.getLength(state) for mus in muscles])
        ma_ref.append([[mus.computeMomentArm(state, cs.get(c)) for c in model.coordinate_names] for mus in muscles])
    np.testing.assert_allclose(body_poses(model, q).tf_ground_body[:, 1:], np.array(tf_ref), rtol=0, atol=1e-12)
    lines = action_lines(model, q)
    np.testing.assert_allclose(lines.lengths, np.array(len_ref), rtol=0, atol=1e-12)
    np.testing.assert_allclose(opensim_moment_arms(model, lines), np.array(ma_ref), rtol=0, atol=1e-12)
