"""motion.wrap_surfaces on real models: Arm26 (generated surfaces) and the LHDL hip (meshes, bones)."""
from __future__ import annotations

import numpy as np
import pytest

from motion import BoneMesh, MuscleSurfaceSpec, SurfaceAttachment, wrap_surfaces
from motion.osim.kinematics import body_poses, motion_from_array
from motion.osim.motion_file import load_motion
from motion.osim.reader import load_model

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


def _sweep(model, coordinate, degrees):
    q = np.tile([c.default_value for c in model.coordinates], (len(degrees), 1))
    q[:, model.coordinate_index(coordinate)] = np.deg2rad(degrees)
    return motion_from_array(model, q)


def test_arm26_generated_surfaces(opensim_dir):
    trimesh = pytest.importorskip("trimesh")
    model = load_model(opensim_dir / "Arm26" / "arm26.osim")
    mot = _sweep(model, "r_elbow_flex", np.linspace(0, 130, 27))
    out = wrap_surfaces(model, mot, [MuscleSurfaceSpec(n, (n,)) for n in model.path_names])
    tf = np.asarray(body_poses(model, mot).tf_ground_body)
    cyl = model.wrap_object("TRI")
    tf_cyl = tf[:, model.body_index(cyl.body)] @ np.asarray(cyl.tf_body_wrap)
    from motion.osim.muscle_parameters import muscle_parameters
    from motion.surface.generate import BELLY_MAX_ASPECT, SPECIFIC_TENSION

    for surf, path in zip(out, model.paths):
        mesh = trimesh.Trimesh(surf.rest_vertices, surf.faces, process=False)
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
        # the belly (tendons: the model's tendon slack lengths) is a straight tube between its cap
        # centres (the first origin / insertion landmarks), of length b and radius r
        assert surf.tendon_slack[0] == pytest.approx(muscle_parameters(model, path.name).tendon_slack_length)
        a, e = surf.rest_origin[0], surf.rest_insertion[0]
        b = np.linalg.norm(e - a)
        u = (e - a) / b
        rel = surf.rest_vertices - a
        r = np.linalg.norm(rel - np.outer(rel @ u, u), axis=1).max()
        # volume rule: F_max / 61 N/cm^2 * optimal fibre length (Arm26 muscles: 50-250 cm^3, upper-arm
        # muscle volumes of adults, Holzbaur et al. 2007: ~50-370 cm^3), unless that belly would
        # be fatter than BELLY_MAX_ASPECT of its length: then r = 0.1 b
        p = muscle_parameters(model, path.name)
        rule = p.max_isometric_force / SPECIFIC_TENSION * p.optimal_fiber_length
        assert 50e-6 < rule < 250e-6
        if surf.rest_volume < rule * (1 - 1e-6):
            assert r == pytest.approx(BELLY_MAX_ASPECT * b, rel=1e-6), surf.name
        else:
            assert surf.rest_volume == pytest.approx(rule, rel=1e-6), surf.name
        assert np.abs(surf.volume_error).max() < 5e-3
        if any(w.wrap_object == "TRI" for w in path.wraps):
            # no bone mesh: the obstacle is the wrap cylinder moved inwards by the belly's
            # half-thickness, at most half its radius (motion.surface.thickness)
            loc = np.matmul(surf.vertices - tf_cyl[:, None, :3, 3], tf_cyl[:, :3, :3])
            within = np.abs(loc[..., 2]) < 0.5 * cyl.length
            rad = np.hypot(loc[..., 0], loc[..., 1])[within]
            assert rad.min() > max(cyl.radius - r, 0.5 * cyl.radius) - 1e-4, surf.name
    # triceps lateral head: its action line wraps the elbow cylinder once flexed, but that part
    # is tendon; the belly's cap centres ride the line, L - tendon slack apart along it (the
    # chord between them is at most that)
    from motion import action_lines

    lines = action_lines(model, mot, muscles=["TRIlat"])
    tri = out[model.path_names.index("TRIlat")]
    chord = np.linalg.norm(tri.insertion[:, 0] - tri.origin[:, 0], axis=-1)
    belly = np.asarray(lines.lengths)[:, 0] - tri.tendon_slack[0]
    assert (chord <= belly + 1e-9).all() and (chord > 0.9 * belly).all()


LHDL_LINES = {"iliacus_r": ["iliacus_r"], "psoas_r": ["psoas_r"],
              "glut_max_r": ["glut_max1_r", "glut_max2_r", "glut_max3_r"],
              "glut_med_r": ["glut_med1_r", "glut_med2_r", "glut_med3_r"]}


def _vtk_mesh(path):
    pv = pytest.importorskip("pyvista")
    m = pv.read(str(path))
    return np.asarray(m.points, dtype=float) * 1e-3, m.faces.reshape(-1, 4)[:, 1:]


@pytest.fixture(scope="module")
def lhdl(lhdl_dir):
    pd = pytest.importorskip("pandas")
    model = load_model(lhdl_dir / "model" / "LHDL_hip_r.osim")
    lm = pd.read_csv(lhdl_dir / "attachments" / "attachment_landmarks.csv")

    def pts(muscle, kind, cloud=None):
        sel = lm[(lm.muscle == muscle) & (lm.type == kind)]
        if cloud is not None:
            sel = sel[sel.cloud == cloud]
        return sel[["x_mm", "y_mm", "z_mm"]].to_numpy() * 1e-3

    bones = {"femur_r": _vtk_mesh(lhdl_dir / "bones" / "femur_r.vtk"),
             "pelvis": _vtk_mesh(lhdl_dir / "bones" / "iliac_r.vtk")}
    bone_specs = tuple(BoneMesh(body, v, f) for body, (v, f) in bones.items())
    specs = []
    for name, lines in LHDL_LINES.items():
        v, f = _vtk_mesh(lhdl_dir / "muscles_clean" / f"{name}.vtk")
        # psoas origin (lumbar vertebrae) is not in the data: the iliacus pelvic area, as in the TOML
        origin = pts("iliacus_r" if name == "psoas_r" else name, "origin")
        insertion = pts(name, "insertion", 1 if name == "glut_max_r" else None)
        specs.append(MuscleSurfaceSpec(name, tuple(lines), v, f, frame="bodies",
                                       origin=SurfaceAttachment("pelvis", origin),
                                       insertion=SurfaceAttachment("femur_r", insertion), bones=bone_specs))
    return model, specs, bones


def _signed_distance(points, bone, *, band=None):
    """Exact signed distance to the bone mesh (VTK's implicit poly-data distance), negative inside.

    With ``band``: only points within ``band`` of a bone vertex are measured, the others get +inf.
    Used on the deformed frames with band = 15 mm: a vertex that starts outside cannot reach
    15 mm depth without crossing the band in the 2-degree steps before (vertices move < 10 mm
    per step here, asserted), where it would be measured.
    """
    pv = pytest.importorskip("pyvista")
    from scipy.spatial import cKDTree

    v, f = bone
    d = np.full(len(points), np.inf)
    near = np.ones(len(points), bool) if band is None else cKDTree(v).query(points)[0] < band
    if near.any():
        surf = pv.PolyData(v, np.hstack([np.full((len(f), 1), 3), f]).ravel())
        d[near] = pv.PolyData(points[near]).compute_implicit_distance(surf)["implicit_distance"]
    return d


@pytest.fixture(scope="module")
def lhdl_runs(lhdl, lhdl_dir):
    """Per motion: the wrapped surfaces and, per muscle, (max bone depth (m) of vertices that start
    outside [femur, hip bone], max vertex step between frames (m))."""
    model, specs, bones = lhdl
    cache = {}

    def run(motion_name):
        if motion_name in cache:
            return cache[motion_name]
        mot = load_motion(lhdl_dir / "model" / "motions" / f"{motion_name}.mot", model)
        out = wrap_surfaces(model, mot, specs)
        tf = np.asarray(body_poses(model, mot).tf_ground_body)
        measures = {}
        for spec, surf in zip(specs, out):
            depth = []
            for body, bone in bones.items():
                tf_b = tf[:, model.body_index(body)]
                rest_d = _signed_distance(np.asarray(spec.vertices), bone)
                outside = rest_d >= 0
                local = np.matmul(surf.vertices[:, outside] - tf_b[:, None, :3, 3], tf_b[:, :3, :3])
                d = _signed_distance(local.reshape(-1, 3), bone, band=0.015)
                depth.append(max(0.0, -d.min()))
            step = np.linalg.norm(np.diff(surf.vertices, axis=0), axis=-1).max()
            measures[spec.name] = (depth, step)
        print(motion_name, {k: ([f"{x * 1e3:.2f} mm" for x in v[0]], f"step {v[1] * 1e3:.1f} mm")
                            for k, v in measures.items()})
        cache[motion_name] = (tf, out, measures)
        return cache[motion_name]

    return run


MOTIONS = ["hip_flexion", "hip_adduction", "hip_rotation"]


@pytest.mark.slow
@pytest.mark.parametrize("motion_name", MOTIONS)
def test_lhdl_volume_and_landmarks(lhdl, lhdl_runs, motion_name):
    model, specs, _ = lhdl
    tf, out, _ = lhdl_runs(motion_name)
    for spec, surf in zip(specs, out):
        assert np.abs(surf.volume_error).max() < 5e-3, (spec.name, surf.volume_error)
        # landmarks ride their bones: back in the body frame they are the data points (bodies = S)
        for att, moved in ((spec.origin, surf.origin), (spec.insertion, surf.insertion)):
            tf_b = tf[:, model.body_index(att.body)]
            back = np.matmul(moved - tf_b[:, None, :3, 3], tf_b[:, :3, :3])
            np.testing.assert_allclose(back, np.broadcast_to(att.points, back.shape), atol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("muscle", list(LHDL_LINES))
@pytest.mark.parametrize("motion_name", MOTIONS)
def test_lhdl_bones_not_penetrated(lhdl_runs, motion_name, muscle):
    _, _, measures = lhdl_runs(motion_name)
    depth, step = measures[muscle]
    # the band argument of _signed_distance needs steps below 10 mm
    assert step < 1e-2, (muscle, step)
    # requirement: no vertex that starts outside a bone ends more than 1 mm inside it
    assert max(depth) < 1e-3, (muscle, depth)


def test_lhdl_bodies_rest_pose(lhdl):
    """frame = "bodies": the solved pose makes the femur frame coincide with the pelvis frame, and
    wrapping at that pose gives back the rest mesh (in the scanner frame placed in ground)."""
    from motion.surface.rest import rest_pose

    model, specs, _ = lhdl
    spec = specs[0]
    rest = rest_pose(model, spec)
    tf = np.asarray(body_poses(model, motion_from_array(model, rest.q[None])).tf_ground_body)[0]
    rel = np.linalg.inv(tf[model.body_index("pelvis")]) @ tf[model.body_index("femur_r")]
    # hip joint centre given as 0.432670 / 0.432669 in parent / child: 1e-6 m is the model's own
    np.testing.assert_allclose(rel, np.eye(4), atol=2e-6)
    assert rest.residual < 2e-6
    # the default pose is not that pose (documented in motion.surface.rest)
    q0 = np.array([c.default_value for c in model.coordinates])
    tf0 = np.asarray(body_poses(model, motion_from_array(model, q0[None])).tf_ground_body)[0]
    rel0 = np.linalg.inv(tf0[model.body_index("pelvis")]) @ tf0[model.body_index("femur_r")]
    assert np.abs(rel0 - np.eye(4)).max() > 0.05
    out = wrap_surfaces(model, motion_from_array(model, rest.q[None]), [specs[0].__class__(
        spec.name, spec.action_lines, spec.vertices, spec.faces, frame="bodies", origin=spec.origin,
        insertion=spec.insertion)])[0]
    expect = np.asarray(spec.vertices) @ rest.tf_ground_data[:3, :3].T + rest.tf_ground_data[:3, 3]
    # exact up to the solved pose's residual (1e-6 rad/m) times the 0.2 m lever of the muscle
    np.testing.assert_allclose(out.vertices[0], expect, atol=1e-6)
