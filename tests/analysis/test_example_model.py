"""The bundled example (models/): deterministic, loads in OpenSim 4.6, closed plausible surfaces."""
from __future__ import annotations

import importlib.util
import math
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / "models"


def _load_generator():
    spec = importlib.util.spec_from_file_location("make_example", MODELS / "make_example.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("make_example", module)
    spec.loader.exec_module(module)
    return module


me = _load_generator()
TEXT_FILES = ["arm_example.osim", "arm_example.toml", "elbow_flexion.mot"] + [
    f"{m}_{end}.csv" for m in me.MUSCLES for end in ("origin", "insertion")]
MESH_FILES = [f"meshes/{m}.ply" for m in me.MUSCLES] + ["meshes/humerus.stl", "meshes/forearm.stl"]


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    out = tmp_path_factory.mktemp("example")
    paths = me.generate(out)
    return out, paths


def test_generation_is_deterministic_and_matches_the_committed_files(generated, tmp_path):
    out, paths = generated
    rel = sorted(str(p.relative_to(out)) for p in paths)
    assert rel == sorted(TEXT_FILES + MESH_FILES)
    again = me.generate(tmp_path)
    for p, q in zip(paths, again):
        assert p.read_bytes() == q.read_bytes(), p.name          # same machine: identical bytes
    for name in TEXT_FILES:
        assert (out / name).read_text() == (MODELS / name).read_text(), (
            f"models/{name} is stale: rerun python models/make_example.py")
    import trimesh
    for name in MESH_FILES:
        new = trimesh.load(out / name, process=False)
        old = trimesh.load(MODELS / name, process=False)
        np.testing.assert_array_equal(new.faces, old.faces)
        # float32 storage: a libm difference can at most flip the last bit (~3e-8 m at 0.3 m)
        np.testing.assert_allclose(new.vertices, old.vertices, rtol=0, atol=1e-7)


def test_committed_files_are_small():
    total = sum((MODELS / n).stat().st_size for n in TEXT_FILES + MESH_FILES)
    assert total < 400_000, total


@pytest.mark.parametrize("name", MESH_FILES)
def test_meshes_are_closed_outward_and_plausible(name):
    import trimesh
    mesh = trimesh.load(MODELS / name)          # merges STL's duplicated vertices
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume > 0                      # outward normals
    muscle = name.endswith(".ply")
    nv = len(mesh.vertices)
    assert (1500 if muscle else 300) <= nv <= 5000
    length = mesh.extents.max()
    assert 0.1 < length < 0.4                   # arm bones and muscles: 10 to 40 cm
    # volume: a muscle is 20 to 300 cm^3; a bone is thinner than a 3 cm cylinder of its length
    if muscle:
        assert 20e-6 < mesh.volume < 300e-6
    else:
        assert mesh.volume < math.pi * 0.03 ** 2 * length
    # smooth: no sliver edges (shortest edge > 0.1 mm) and no long ones (< 2.5 cm)
    edges = mesh.edges_unique_length
    assert edges.min() > 1e-4 and edges.max() < 0.025


def test_landmarks_lie_on_the_muscle_tips():
    import trimesh
    for muscle, (lines, *_rest) in me.MUSCLES.items():
        mesh = trimesh.load(MODELS / f"meshes/{muscle}.ply", process=False)
        for end, idx in (("origin", 0), ("insertion", 1)):
            pts = np.loadtxt(MODELS / f"{muscle}_{end}.csv", delimiter=",", skiprows=1)
            assert pts.shape[1] == 3 and len(pts) >= 10
            # every landmark is a surface vertex (exactly: both are the float32 values)
            d = np.linalg.norm(pts[:, None, :] - mesh.vertices[None], axis=2).min(axis=1)
            assert d.max() < 1e-7
            # and within 2 cm of the action lines' end points (ground, rest pose)
            ends = np.array([me.ACTION_LINES[a][idx] for a in lines], dtype=float)
            if end == "insertion":
                ends = ends + me.ELBOW
            assert np.linalg.norm(pts.mean(axis=0) - ends.mean(axis=0)) < 0.02


def test_toml_and_motion_are_consistent():
    spec = tomllib.loads((MODELS / "arm_example.toml").read_text())
    assert (MODELS / spec["model"]).is_file() and (MODELS / spec["motion"]).is_file()
    assert spec["units"] == "m"
    assert set(spec["muscles"]) == {"biceps", "brachialis", "triceps"}
    templates = {m: t["template"] for m, t in spec["muscles"].items()}
    assert templates == {"biceps": "parallel", "brachialis": "pennate", "triceps": "bipennate"}
    for m, table in spec["muscles"].items():
        assert (MODELS / table["mesh"]).is_file()
        assert (MODELS / table["origin"]["file"]).is_file()
        assert (MODELS / table["insertion"]["file"]).is_file()
        assert set(table["action_lines"]) <= set(me.ACTION_LINES)
    lines = (MODELS / "elbow_flexion.mot").read_text().splitlines()
    assert "inDegrees=yes" in lines
    data = np.loadtxt(lines[lines.index("endheader") + 2:])
    assert data.shape == (27, 2)
    np.testing.assert_allclose(data[:, 1], np.arange(27) * 5.0)
    assert np.all(np.diff(data[:, 0]) > 0)


def _belt_length(p1, p2, radius):
    """Tangent + arc + tangent around the -x side of a circle at the origin (2D)."""
    t1, t2 = math.sqrt(p1 @ p1 - radius ** 2), math.sqrt(p2 @ p2 - radius ** 2)
    a1 = math.atan2(p1[1], p1[0]) + math.acos(radius / np.hypot(*p1))
    a2 = math.atan2(p2[1], p2[0]) - math.acos(radius / np.hypot(*p2))
    return t1 + t2 + radius * ((a2 - a1) % (2 * math.pi))


def test_opensim_loads_the_example_and_lengths_match_hand_geometry(osim):
    osim.Logger.removeFileSink()   # no opensim.log beside the model files
    model = osim.Model(str(MODELS / "arm_example.osim"))
    state = model.initSystem()
    assert model.getNumBodies() == 2 and model.getMuscles().getSize() == 5
    q = model.getCoordinateSet().get("elbow_flexion")
    assert q.getRangeMax() >= math.radians(130.0)
    wrapped_frames = 0
    for deg in (0.0, 30.0, 45.0, 60.0, 90.0, 130.0):
        th = math.radians(deg)
        q.setValue(state, th)
        model.realizePosition(state)
        rot = np.array([[math.cos(th), -math.sin(th), 0], [math.sin(th), math.cos(th), 0],
                        [0, 0, 1]])
        for name, (o, i, wraps, *_rest) in me.ACTION_LINES.items():
            path = model.getMuscles().get(name).getGeometryPath()
            length = path.getLength(state)
            o, i_ground = np.array(o), rot @ np.array(i) + me.ELBOW
            straight = np.linalg.norm(i_ground - o)
            assert 0.08 < length < 0.45                  # plausible arm muscle-tendon lengths
            if not wraps:
                assert length == pytest.approx(straight, abs=1e-12)
                continue
            # wrapped iff the straight segment enters the cylinder or passes it on the +x side
            p1, p2 = (o - me.ELBOW)[:2], (i_ground - me.ELBOW)[:2]
            d = p2 - p1
            t = np.clip(-(p1 @ d) / (d @ d), 0.0, 1.0)
            closest = p1 + t * d
            wraps_now = np.hypot(*closest) < me.WRAP_RADIUS or closest[0] > 0
            if wraps_now:
                wrapped_frames += 1
                # the path is in the plane z = 0, perpendicular to the cylinder: exact belt length
                assert length == pytest.approx(_belt_length(p1, p2, me.WRAP_RADIUS), abs=1e-9)
                assert length > straight + 1e-6
                # a wrapped path's moment arm is the pulley radius (negative: an extensor)
                assert path.computeMomentArm(state, q) == pytest.approx(-me.WRAP_RADIUS, abs=1e-6)
            else:
                assert length == pytest.approx(straight, abs=1e-12)
    assert wrapped_frames >= 6          # both triceps lines wrap at 60, 90 and 130 degrees
