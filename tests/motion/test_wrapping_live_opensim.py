"""Wrapping against live OpenSim 4.6 on small models built here with its Python API.

Each model: ground + body "arm" on a PinJoint (coordinate q about z), a PathActuator from a
ground point to an arm point, and wrap objects on ground or arm. For a sweep of q we compare
with OpenSim:
- path length (GeometryPath::getLength): 1e-6 m (the acceptance; we get ~1e-15 m);
- -dL/dq against OpenSim's own central difference of the length (h = 1e-6 rad: truncation
  ~h^2 L''' < 1e-10 m, round-off ~1e-16/h = 1e-10 m) on frames where that difference is smooth
  (h = 1e-6 and h = 1e-5 agree within 1e-6 m; a wrap engaging inside +-h is a jump): 1e-5 m;
- current path points incl. tangent points (getCurrentPath, getLocationInGround): 1e-5 m.
Each case also checks that its sweep actually wraps.
"""
from __future__ import annotations

import numpy as np
import pytest

from motion.osim.kinematics import body_pose_derivatives
from motion.osim.reader import load_model
from motion.wrapping.path_points import path_points
from motion.wrapping.batch import wrap_path
from wrap_oracle.cylinder import cylinder_wrap_line     # tests/motion (rootdir-relative import)


def _build(osim, path_file, wraps, points, q_range=(-3.0, 3.0), method=None):
    model = osim.Model()
    model.setName("wraptest")
    arm = osim.Body("arm", 1.0, osim.Vec3(0), osim.Inertia(0.01, 0.01, 0.01))
    model.addBody(arm)
    pin = osim.PinJoint("pin", model.getGround(), osim.Vec3(0), osim.Vec3(0), arm, osim.Vec3(0),
                        osim.Vec3(0))
    pin.updCoordinate().setName("q")
    pin.updCoordinate().setRangeMin(q_range[0])
    pin.updCoordinate().setRangeMax(q_range[1])
    model.addJoint(pin)
    frames = {"ground": model.getGround(), "arm": arm}
    for body, w in wraps:
        frames[body].addWrapObject(w)
    act = osim.PathActuator()
    act.setName("line")
    for i, (body, xyz) in enumerate(points):
        act.addNewPathPoint(f"line-P{i + 1}", frames[body], osim.Vec3(*xyz))
    model.addForce(act)
    for _, w in wraps:
        act.updGeometryPath().addPathWrap(w)
    model.finalizeConnections()
    model.printToXML(str(path_file))
    if method is not None:
        text = path_file.read_text().replace("<method>hybrid</method>", f"<method>{method}</method>")
        path_file.write_text(text)
    return path_file


def _opensim(osim, model_file, qs):
    model = osim.Model(str(model_file))
    state = model.initSystem()
    coord = model.getCoordinateSet().get("q")
    path = osim.PathActuator.safeDownCast(model.getForceSet().get("line")).getGeometryPath()

    def length(q):
        coord.setValue(state, q, False)
        model.realizePosition(state)
        return path.getLength(state)

    lengths, fd6, fd5, ma, points = [], [], [], [], []
    for q in qs:
        fd6.append(-(length(q + 1e-6) - length(q - 1e-6)) / 2e-6)
        fd5.append(-(length(q + 1e-5) - length(q - 1e-5)) / 2e-5)
        lengths.append(length(q))
        ma.append(path.computeMomentArm(state, coord))
        cur = path.getCurrentPath(state)
        points.append(np.array([[cur.get(i).getLocationInGround(state)[k] for k in range(3)]
                                for i in range(cur.getSize())]))
    return np.array(lengths), np.array(fd6), np.array(fd5), np.array(ma), points


def _mine(model_file, qs):
    model = load_model(model_file)
    q = np.asarray(qs, dtype=float)[:, None]
    tf, dtf, q_used, jac = body_pose_derivatives(model, q)
    path = model.path("line")
    pp = path_points(path, model, q_used, tf, jac=jac, d_tf_ground_body=dtf)
    return wrap_path(path, model, pp.points, pp.active, pp.d_points, tf, dtf)


def _compare(osim, model_file, qs, *, point_tol=1e-5):
    lengths, fd6, fd5, _, points = _opensim(osim, model_file, qs)
    res = _mine(model_file, qs)
    assert sum(len(p) > 2 for p in points) >= 3, "the sweep must wrap"
    np.testing.assert_allclose(res.length, lengths, rtol=0, atol=1e-6)
    smooth = np.abs(fd6 - fd5) < 1e-6
    assert smooth.sum() >= len(qs) - 3
    err = np.abs(-res.d_length[:, 0] - fd6)[smooth]
    assert err.max() < 1e-5, f"moment arm error {err.max():.3g} m"
    ordered = res.ordered_points
    for f, pts in enumerate(points):
        n = len(pts)
        assert np.all(np.isfinite(ordered[f, :n])) and np.all(np.isnan(ordered[f, n:])), f"frame {f}"
        assert np.abs(ordered[f, :n] - pts).max() < point_tol, f"frame {f}"
    return res


@pytest.mark.parametrize("quadrant", ["all", "-y", "x"])
def test_sphere_on_moving_body(osim, tmp_path, quadrant):
    w = osim.WrapSphere()
    w.setName("sph")
    w.set_radius(0.05)
    w.set_quadrant(quadrant)
    w.set_translation(osim.Vec3(0.01, 0.0, 0.005))
    w.set_xyz_body_rotation(osim.Vec3(0.2, 0.1, -0.3))
    f = _build(osim, tmp_path / "sphere.osim", [("arm", w)],
               [("ground", (-0.2, 0.01, 0.0)), ("arm", (0.2, 0.0, 0.01))])
    _compare(osim, f, np.linspace(-0.6, 0.6, 25))


@pytest.mark.parametrize("quadrant", ["all", "y"])
def test_torus(osim, tmp_path, quadrant):
    # path through the hole of a tilted torus; OpenSim puts a cylinder of the tube radius at
    # its (odd) "closest" ring point -- reproduced, see motion.wrapping.sphere_torus_line
    w = osim.WrapTorus()
    w.setName("tor")
    w.set_inner_radius(0.02)
    w.set_outer_radius(0.06)
    w.set_quadrant(quadrant)
    w.set_xyz_body_rotation(osim.Vec3(0.1, -0.15, 0.3))
    f = _build(osim, tmp_path / "torus.osim", [("ground", w)],
               [("ground", (0.01, 0.005, 0.2)), ("arm", (0.08, 0.0, -0.2))])
    _compare(osim, f, np.linspace(-0.8, 0.8, 33))


@pytest.mark.parametrize("config", [0, 1])
def test_two_cylinders_in_series(osim, tmp_path, config):
    # c1 on ground and c2 on the arm, both on one path: several applyWrapObjects passes with
    # tangent points that move between passes (OpenSim's cached ground positions matter here)
    ra, rb, tb, p1, p2, q_range = [
        (0.03, 0.03, (0.0, -0.15, 0.0), (-0.05, 0.2, 0.01), (-0.05, -0.3, -0.01), (0.0, 1.2)),
        (0.04, 0.02, (0.0, -0.2, 0.0), (0.05, 0.25, 0.0), (0.03, -0.35, 0.0), (-1.2, 0.0)),
    ][config]
    c1 = osim.WrapCylinder()
    c1.setName("c1")
    c1.set_radius(ra)
    c1.set_length(0.3)
    c2 = osim.WrapCylinder()
    c2.setName("c2")
    c2.set_radius(rb)
    c2.set_length(0.3)
    c2.set_translation(osim.Vec3(*tb))
    f = _build(osim, tmp_path / "cylinders.osim", [("ground", c1), ("arm", c2)],
               [("ground", p1), ("arm", p2)])
    res = _compare(osim, f, np.linspace(*q_range, 31))
    assert (res.mask[:, 2:].all(axis=1)).sum() >= 3, "both cylinders must wrap in some frames"


def test_cylinder_tangent_readjustment(osim, tmp_path):
    # A quadrant cylinder that wraps long arcs on a path with two wrap objects: OpenSim
    # re-adjusts the tangent points along the axis (0.1-degree tangency loop, up to 13 passes
    # here). OpenSim 4.6 computes r2's spiral point from r1 as already moved in the same pass
    # (see motion.wrapping.cylinder_line.wrap_line); reproduced, the tangent points agree to ~4e-15 m.
    # Bound 1e-9 m: the loop is replayed step for step, so only round-off remains (~1e-15 m);
    # a different number of passes would move the points by >= 1e-6 m (one 0.1-degree step
    # at r = 0.03 m), so this bound catches any departure from OpenSim's iteration.
    c1 = osim.WrapCylinder()
    c1.setName("c1")
    c1.set_radius(0.03)
    c1.set_length(0.3)
    c1.set_quadrant("-x")
    c2 = osim.WrapCylinder()
    c2.setName("c2")
    c2.set_radius(0.03)
    c2.set_length(0.3)
    c2.set_quadrant("-x")
    c2.set_translation(osim.Vec3(0.0, -0.15, 0.0))
    f = _build(osim, tmp_path / "readjust.osim", [("ground", c1), ("arm", c2)],
               [("ground", (-0.05, 0.2, 0.01)), ("arm", (-0.05, -0.3, -0.01))])
    qs = np.linspace(0.0, 1.2, 31)
    res = _compare(osim, f, qs, point_tol=1e-9)
    # the case must exercise the re-adjustment: c1 (on ground, wrap frame = ground) without it
    # would put the tangent points elsewhere by more than 1e-5 m in some frames
    wraps = res.mask[:, 2] & ~res.mask[:, 4]
    p1, p2 = res.points[wraps, 0], res.points[wraps, 1]
    _, r1, r2, _ = cylinder_wrap_line(p1, p2, radius=0.03, length=0.3, quadrant="-x",
                                      adjust_tangents=False)
    moved = np.maximum(np.abs(r1.v - res.points[wraps, 2]).max(axis=1),
                       np.abs(r2.v - res.points[wraps, 3]).max(axis=1))
    assert wraps.sum() >= 10 and moved.max() > 1e-5


@pytest.mark.parametrize("config", [0, 1])
def test_cylinder_long_wraps_signed_angle(osim, tmp_path, config):
    # A tilted quadrant cylinder on ground and a second one on the arm, with long wraps whose
    # helix turns clockwise about the axis: OpenSim 4.6 measures the angle signed (atan2), so
    # such a long wrap spans 2 pi + |theta|, not 2 pi - |theta| (an implementation using the
    # unsigned angle is off by up to 0.66 m in length here). Lengths and points must match
    # OpenSim to round-off (measured 7e-12 m, 1e-13 m over 40 random cases like these).
    quadrant, rot, p1, p2 = [
        ("y", (-0.4184, 0.3552, 0.3613), (-0.0056, 0.2, -0.0986), (0.0291, -0.3, 0.0671)),
        ("-y", (-0.2848, 0.1393, 0.3051), (-0.0699, 0.2, 0.0789), (-0.0155, -0.3, -0.0951)),
    ][config]
    c1 = osim.WrapCylinder()
    c1.setName("c1")
    c1.set_radius(0.03)
    c1.set_length(0.4)
    c1.set_quadrant(quadrant)
    c1.set_xyz_body_rotation(osim.Vec3(*rot))
    c2 = osim.WrapCylinder()
    c2.setName("c2")
    c2.set_radius(0.02)
    c2.set_length(0.3)
    c2.set_quadrant("-x")
    c2.set_translation(osim.Vec3(0.0, -0.15, 0.0))
    f = _build(osim, tmp_path / "longwrap.osim", [("ground", c1), ("arm", c2)],
               [("ground", p1), ("arm", p2)])
    qs = np.linspace(-1.5, 1.5, 13)
    lengths, _, _, _, points = _opensim(osim, f, qs)
    res = _mine(f, qs)
    assert (res.arc[:, 0] > np.pi * 0.03).any(), "c1 must wrap the long way in some frames"
    np.testing.assert_allclose(res.length, lengths, rtol=0, atol=1e-9)
    for i, pts in enumerate(points):
        assert np.abs(res.ordered_points[i, :len(pts)] - pts).max() < 1e-9, f"frame {i}"


@pytest.mark.parametrize("method", ["hybrid", "midpoint", "axial"])
@pytest.mark.parametrize("quadrant", ["all", "-y"])
def test_ellipsoid_methods(osim, tmp_path, method, quadrant):
    w = osim.WrapEllipsoid()
    w.setName("ell")
    w.set_dimensions(osim.Vec3(0.06, 0.04, 0.05))
    w.set_quadrant(quadrant)
    w.set_xyz_body_rotation(osim.Vec3(0.2, -0.3, 0.4))
    w.set_translation(osim.Vec3(0.01, 0.0, 0.005))
    f = _build(osim, tmp_path / "ellipsoid.osim", [("arm", w)],
               [("ground", (-0.2, 0.01, 0.0)), ("arm", (0.2, 0.0, 0.01))], method=method)
    assert f"<method>{method}</method>" in f.read_text()
    _compare(osim, f, np.linspace(-0.6, 0.6, 25))
