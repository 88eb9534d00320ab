"""motion.wrap_surfaces on OpenSim 4.0 models built in the test: pin-joint cylinder and pulley."""
from __future__ import annotations

import numpy as np
import pytest

from motion import InputError, MuscleSurfaceSpec, SurfaceAttachment, wrap_surfaces
from motion.osim.kinematics import motion_from_array
from motion.osim.builder import ModelBuilder
from motion.osim.reader import load_model
from motion.surface.volume import mesh_volume

from meshes import capped_tube

R_PULLEY, D, A, B = 0.02, 0.03, 0.15, 0.12   # pulley radius, line offset, attachment distances
R_MUSCLE = 0.008                             # < D - R_PULLEY: the rest surface clears the pulley


def tube(start, end, radius, n_around=48, n_rings=61):
    """Closed capped cylinder from ``start`` to ``end`` (outward faces)."""
    return capped_tube(start, end, radius, n_around=n_around, n_rings=n_rings)


def build(tmp_path, *, pulley: bool):
    side = -D if pulley else D
    b = (ModelBuilder("pulley" if pulley else "pin")
         .add_body("upper")
         .add_weld_joint("fix", "ground", "upper")
         .add_body("lower")
         .add_pin_joint("knee", "upper", "lower", "q", range=(-1.0, 2.5)))
    wraps = []
    if pulley:
        b = b.add_wrap_cylinder("upper", "cyl", radius=R_PULLEY, length=0.1, quadrant="-x")
        wraps = ["cyl"]
    b = b.add_muscle("m", [("upper", (side, A, 0)), ("lower", (side, -B, 0))], wraps=wraps)
    return load_model(b.write(tmp_path / "model.osim"))


def spec_for(side):
    origin, insertion = np.array([side, A, 0.0]), np.array([side, -B, 0.0])
    v, f = tube(origin, insertion, R_MUSCLE)
    return MuscleSurfaceSpec("m", ("m",), v, f, frame="ground", rest_pose={"q": 0.0},
                             origin=SurfaceAttachment("upper", origin[None]),
                             insertion=SurfaceAttachment("lower", insertion[None]))


def sweep(model, degrees):
    return motion_from_array(model, np.deg2rad(np.asarray(degrees, float))[:, None])


def test_pin_joint_cylinder_stays_a_cylinder(tmp_path):
    model = build(tmp_path, pulley=False)
    deg = np.linspace(-30, 120, 31)
    out = wrap_surfaces(model, sweep(model, deg), [spec_for(D)])[0]
    # current action line: origin fixed, insertion on the lower body rotating about z
    th = np.deg2rad(deg)
    ins = np.stack([D * np.cos(th) + B * np.sin(th), D * np.sin(th) - B * np.cos(th), 0 * th], -1)
    org = np.array([D, A, 0.0])
    np.testing.assert_allclose(out.insertion[:, 0], ins, atol=1e-9)      # rigid with the lower body
    np.testing.assert_allclose(out.origin[:, 0], np.broadcast_to(org, ins.shape), atol=1e-9)
    u = (ins - org) / np.linalg.norm(ins - org, axis=1, keepdims=True)
    rel = out.vertices - org
    along = np.einsum("fvk,fk->fv", rel, u)
    radial = np.linalg.norm(rel - along[..., None] * u[:, None], axis=-1)
    # the belly: vertices beyond the attachment blend zone (20 % of the 0.27 m line from each end)
    rest_along = out.rest_vertices[:, 1]
    belly = (rest_along < A - 0.06) & (rest_along > -B + 0.06)
    r_f = radial[:, belly]
    r_mean = r_f.mean(axis=1)
    # a 48-gon cylinder is exact at its vertices: any deviation is the deformation's error
    assert np.max(np.abs(r_f - r_mean[:, None])) / R_MUSCLE < 0.01
    # volume kept (exact cubic solve); requirement 0.5 %
    assert np.abs(out.volume_error).max() < 1e-9
    # the belly thins as the line lengthens and thickens as it shortens (volume redistribution)
    length = np.linalg.norm(ins - org, axis=1)
    # (up to 1e-5 m = 0.1 % of the radius: the rigid end regions tilt against the line with the
    # angle, which changes their volume slightly at equal line lengths)
    order = np.argsort(length)
    assert np.all(np.diff(r_mean[order]) < 1e-5)
    assert r_mean[order[0]] > 1.5 * r_mean[order[-1]]


def test_pulley_bends_and_stays_out_of_the_derived_bone(tmp_path):
    # the wrap cylinder guides the centre line; with no bone mesh the obstacle is the cylinder
    # moved inwards by the muscle's half-thickness (R_MUSCLE): the inner half of the muscle lies
    # inside the wrap radius, nothing goes below R - R_MUSCLE (0.1 mm: the push-out shell)
    model = build(tmp_path, pulley=True)
    deg = np.linspace(0, 120, 25)
    out = wrap_surfaces(model, sweep(model, deg), [spec_for(-D)])[0]
    rad = np.hypot(out.vertices[..., 0], out.vertices[..., 1])   # pulley axis = ground z
    assert rad.min() > R_PULLEY - R_MUSCLE - 1e-4
    assert rad[-1].min() < R_PULLEY - 0.5 * R_MUSCLE
    assert np.abs(out.volume_error).max() < 5e-3
    th = np.deg2rad(deg)
    ins = np.stack([-D * np.cos(th) + B * np.sin(th), -D * np.sin(th) - B * np.cos(th), 0 * th], -1)
    np.testing.assert_allclose(out.insertion[:, 0], ins, atol=1e-9)
    np.testing.assert_allclose(out.origin[:, 0], np.broadcast_to([-D, A, 0.0], ins.shape), atol=1e-9)
    # it bends around the pulley: at 120 degrees the surface reaches the derived bone (2 mm)
    assert rad[-1].min() < R_PULLEY - R_MUSCLE + 2e-3
    # and the surface is continuous in the angle (no jumps between 5-degree steps)
    step = np.linalg.norm(np.diff(out.vertices, axis=0), axis=-1).max()
    assert step < 0.03


def test_generated_surface_when_no_mesh(tmp_path):
    model = build(tmp_path, pulley=False)
    spec = MuscleSurfaceSpec("m", ("m",), volume=2e-5)
    out = wrap_surfaces(model, sweep(model, [0, 45, 90]), [spec])[0]
    assert out.generated
    np.testing.assert_allclose(out.rest_volume, 2e-5, rtol=1e-9)
    assert np.abs(out.volume_error).max() < 1e-9


def test_input_errors_name_the_muscle(tmp_path):
    model = build(tmp_path, pulley=False)
    mot = sweep(model, [0, 10])
    good = spec_for(D)
    bad_pose = MuscleSurfaceSpec("m", ("m",), good.vertices, good.faces, rest_pose={"knee_angle": 0.1})
    with pytest.raises(InputError, match="muscle 'm'.*rest_pose.knee_angle"):
        wrap_surfaces(model, mot, [bad_pose])
    bad_body = MuscleSurfaceSpec("m", ("m",), good.vertices, good.faces, frame="femur")
    with pytest.raises(InputError, match="muscle 'm': frame"):
        wrap_surfaces(model, mot, [bad_body])
    bad_att = MuscleSurfaceSpec("m", ("m",), good.vertices, good.faces,
                                origin=SurfaceAttachment("femur", [[0, 0, 0]]))
    with pytest.raises(InputError, match="origin.body"):
        wrap_surfaces(model, mot, [bad_att])
    in_mm = MuscleSurfaceSpec("m", ("m",), good.vertices * 1000, good.faces)
    with pytest.raises(InputError, match="units"):
        wrap_surfaces(model, mot, [in_mm])
    with pytest.raises(InputError, match="action_lines"):
        wrap_surfaces(model, mot, [MuscleSurfaceSpec("m", ("nope",), good.vertices, good.faces)])


@pytest.mark.parametrize("q0", [0.3, 1.2])
def test_pulley_surface_is_differentiable_in_the_coordinate(tmp_path, q0):
    # finite-difference moment arms of fibres need the surface to be a smooth function of q:
    # central differences with h and h/2 must agree (a kink or jump would make them differ by
    # O(1) relative; truncation error of the difference is O(h^2 |v'''|) ~ 1e-8 relative)
    model = build(tmp_path, pulley=True)
    h = 1e-4
    q = q0 + np.array([-h, h, -h / 2, h / 2])
    v = wrap_surfaces(model, motion_from_array(model, q[:, None]), [spec_for(-D)])[0].vertices
    d_h = (v[1] - v[0]) / (2 * h)
    d_h2 = (v[3] - v[2]) / h
    scale = np.abs(d_h).max()
    assert scale > 1e-3                       # the surface does move with q
    assert np.abs(d_h - d_h2).max() < 1e-6 * scale, np.abs(d_h - d_h2).max() / scale   # measured ~5e-9
