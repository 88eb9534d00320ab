"""The 3D scene (`analysis.scene`, ``scene/scene.pvd``) opens in pyvista as one multiblock per
frame with bones, surfaces, action lines and fibres; ``fibres render`` writes a picture."""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest

import analysis
from analysis import cli_run
from analysis.spec import load_spec

pv = pytest.importorskip("pyvista")
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def scene_run(tmp_path_factory):
    spec = load_spec(ROOT / "models" / "arm_example.toml")
    result = analysis.run(spec, fibres=6, resolution=6, frames="0:27:13", keep_surfaces=True)
    out = tmp_path_factory.mktemp("scene_run")
    cli_run.write_outputs(result, out, plots=False, sto=False, scene={"spec": spec, "step": None})
    return spec, result, out


def test_scene_is_one_collection_with_four_parts_per_frame(scene_run):
    spec, result, out = scene_run
    reader = pv.get_reader(str(out / "scene" / "scene.pvd"))
    np.testing.assert_allclose(reader.time_values, result.time)
    names = json.loads((out / "scene" / "names.json").read_text())
    assert names["parts"] == ["bones", "surfaces", "lines", "fibres"] and names["frames"] == [0, 1, 2]
    blocks, tri_points = [], []
    for k, t in enumerate(result.time):
        reader.set_active_time_value(t)
        block = reader.read()
        assert block.n_blocks == 4
        blocks.append([block[i] for i in range(4)])
        bones, surfaces, lines, fibres = blocks[-1]
        # fibres: the run's polylines, in muscle then fibre order, with their lengths
        want = np.concatenate([m.fibre_points[k].reshape(-1, 3) for m in result.muscles])
        # the points are written as float32 (vtk_files.POINT_TYPE): exactly the rounded values
        np.testing.assert_array_equal(fibres.points, want.astype(np.float32))
        np.testing.assert_allclose(fibres.cell_data["length"],
                                   np.concatenate([m.fibre_lengths[k] for m in result.muscles]))
        # surfaces: the wrapped surfaces, one muscle id per cell
        assert surfaces.n_points == sum(m.surface_vertices.shape[1] for m in result.muscles)
        assert set(np.unique(surfaces.cell_data["muscle"])) == {0, 1, 2}
        # action lines: BRA does not wrap, so its polyline length is its path length
        j = names["action_lines"].index("BRA")
        cell = lines.extract_cells([j])
        seg = np.linalg.norm(np.diff(np.asarray(cell.points), axis=0), axis=1).sum()
        # float32 points (|x| < 1 m: each coordinate within 6e-8 m), a few segments
        assert seg == pytest.approx(result.muscle("brachialis").action_line_lengths[k, 0], abs=1e-6)
        # TRIlong wraps over elbow_wrap: drawn with its arc, the polyline is the path (24 chords of
        # the arc on a cylinder of radius 1.8 cm, over at most ~90 deg: < 0.02 mm shorter)
        j = names["action_lines"].index("TRIlong")
        pts = np.asarray(lines.extract_cells([j]).points)
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
        assert seg == pytest.approx(result.muscle("triceps").action_line_lengths[k, 0], abs=2e-5)
        tri_points.append(len(pts))
        assert bones.n_points > 0
    assert tri_points[0] == 2 and max(tri_points) > 20    # straight at 0 deg, wrapped when flexed
    # bones move rigidly: the forearm's vertices keep their distances, the humerus does not move
    body = names["bodies"].index("forearm")
    b0, b2 = blocks[0][0], blocks[2][0]
    fore = np.flatnonzero(b0.cell_data["body"] == body)
    p0 = np.asarray(b0.extract_cells(fore).points)
    p2 = np.asarray(b2.extract_cells(fore).points)
    d0 = np.linalg.norm(p0[:50, None] - p0[None, :50], axis=-1)
    d2 = np.linalg.norm(p2[:50, None] - p2[None, :50], axis=-1)
    np.testing.assert_allclose(d0, d2, atol=4e-7)     # float32 points: 6e-8 m per coordinate
    assert np.abs(p0 - p2).max() > 0.05
    hum = np.flatnonzero(b0.cell_data["body"] == names["bodies"].index("humerus"))
    np.testing.assert_array_equal(b0.extract_cells(hum).points, b2.extract_cells(hum).points)


def test_bones_fall_back_to_the_fibre_models_meshes(tmp_path):
    """A model without geometry files: the fibre model's `bones` meshes are drawn, placed by the
    rest pose (frame "ground" at rest: the mesh vertices themselves at the rest pose)."""
    from analysis.scene import bone_meshes

    spec = load_spec(ROOT / "models" / "arm_example.toml")
    model = spec.model
    import dataclasses

    import motion

    stripped = dataclasses.replace(model, bodies=tuple(dataclasses.replace(b, geometry=()) for b in model.bodies))
    assert bone_meshes(stripped, None) == []
    mesh = ROOT / "models" / "meshes" / "forearm.stl"
    m0 = dataclasses.replace(spec.muscles[0], bones=(("forearm", mesh),))
    spec2 = dataclasses.replace(spec, model=stripped, muscles=(m0,) + spec.muscles[1:])
    got = bone_meshes(stripped, spec2)
    assert len(got) == 1 and got[0][0] == model.body_index("forearm")
    poses = motion.body_poses(model, np.zeros((1, 1))).tf_ground_body[0, model.body_index("forearm")]
    raw = pv.read(str(mesh)).triangulate()
    placed = got[0][1] @ poses[:3, :3].T + poses[:3, 3]
    np.testing.assert_allclose(placed, np.asarray(raw.points), atol=1e-9)


def test_missing_geometry_files_are_named_once(tmp_path):
    """Rajagopal's folder has no Geometry: the scene had no bones and nothing said why. The bodies
    without a bone are named in one warning; a body the fibre model's `bones` covers is not."""
    import dataclasses
    import warnings

    from analysis.errors import FibreWarning
    from analysis.scene import bone_meshes

    spec = load_spec(ROOT / "models" / "arm_example.toml")
    model = spec.model
    gone = dataclasses.replace(model, bodies=tuple(
        dataclasses.replace(b, geometry=tuple(dataclasses.replace(g, mesh_file=f"gone_{b.name}.vtp")
                                              for g in b.geometry)) for b in model.bodies))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert bone_meshes(gone, None) == []
    (w,) = [w for w in seen if issubclass(w.category, FibreWarning)]
    assert "humerus (gone_humerus.vtp)" in str(w.message) and "forearm (gone_forearm.vtp)" in str(w.message)
    m0 = dataclasses.replace(spec.muscles[0], bones=(("forearm", ROOT / "models" / "meshes" / "forearm.stl"),))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        bone_meshes(gone, dataclasses.replace(spec, model=gone, muscles=(m0,) + spec.muscles[1:]))
    (w,) = [w for w in seen if issubclass(w.category, FibreWarning)]
    assert "humerus" in str(w.message) and "forearm" not in str(w.message)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert len(bone_meshes(model, None)) == 2                   # the example's own meshes
    assert not [w for w in seen if issubclass(w.category, FibreWarning)]


@pytest.mark.slow
def test_render_writes_a_picture(scene_run, tmp_path, capfd):
    from analysis.cli import main

    _, _, out = scene_run
    png = tmp_path / "r.png"
    capfd.readouterr()
    assert main(["render", str(out), "--frame", "1", "--view", "side", "--out", str(png), "--size", "400x300"]) == 0
    # one line of ours: no VTK log line (without a display it logged a coloured "bad X server" WARN)
    assert capfd.readouterr().err == f"fibres render: wrote {png}\n"
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and struct.unpack(">II", data[16:24]) == (400, 300)
    image = pv.read(str(png))
    values = np.asarray(image.point_data[image.point_data.keys()[0]])
    assert len(np.unique(values.reshape(len(values), -1), axis=0)) > 20     # not a blank picture
    assert main(["render", str(out), "--frame", "7"]) == 2                   # not in the scene
    assert "frame 7" in capfd.readouterr().err
