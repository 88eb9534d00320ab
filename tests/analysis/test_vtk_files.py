"""analysis.vtk_files: VTP/PVD files that pyvista reads back exactly (cells, order, ids, points)."""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from analysis import vtk_files

pv = pytest.importorskip("pyvista")

F, N, P = 4, 7, 5


@pytest.fixture()
def fibres():
    rng = np.random.default_rng(3)
    return rng.normal(size=(F, N, P, 3)), 0.1 * np.arange(F) + 0.5


def test_fibre_frames_read_back(fibres, tmp_path):
    pts, times = fibres
    lengths = np.linalg.norm(np.diff(pts, axis=2), axis=3).sum(axis=2)        # (F, N)
    pvd = vtk_files.write_fibre_frames(tmp_path / "fibres", "biceps", pts, times=times,
                                       frames=[10, 11, 12, 13], cell_data={"length": lengths})
    assert pvd == tmp_path / "fibres" / "biceps.pvd"
    names = sorted(p.name for p in (tmp_path / "fibres").iterdir())
    assert names == ["biceps.pvd"] + [f"biceps_{f:04d}.vtp" for f in (10, 11, 12, 13)]
    for i, f in enumerate((10, 11, 12, 13)):
        mesh = pv.read(tmp_path / "fibres" / f"biceps_{f:04d}.vtp")
        assert mesh.n_cells == N and mesh.n_points == N * P
        np.testing.assert_array_equal(mesh.cell_data["fibre"], np.arange(N))
        # written as float32 (vtk_files.POINT_TYPE): exactly the rounded points
        np.testing.assert_array_equal(mesh.points, pts[i].reshape(-1, 3).astype(np.float32))
        np.testing.assert_array_equal(mesh.cell_data["length"], lengths[i])
        for k in (0, N - 1):                          # cell k is fibre k, its points in order
            cell = mesh.get_cell(k)
            assert cell.type == pv.CellType.POLY_LINE
            np.testing.assert_array_equal(cell.point_ids, np.arange(k * P, (k + 1) * P))
        # length recomputed from the polyline cells matches the input geometry
        seg = np.asarray(mesh.points, dtype=float).reshape(N, P, 3)
        np.testing.assert_allclose(np.linalg.norm(np.diff(seg, axis=1), axis=2).sum(1),
                                   lengths[i], rtol=1e-6)      # float32 points: 6e-8 relative each


def test_pvd_collection_times_and_files(fibres, tmp_path):
    pts, times = fibres
    pvd = vtk_files.write_fibre_frames(tmp_path, "m", pts, times=times)
    root = ET.parse(pvd).getroot()
    assert root.get("type") == "Collection"
    ds = root.findall("Collection/DataSet")
    assert [d.get("file") for d in ds] == [f"m_{i:04d}.vtp" for i in range(F)]
    np.testing.assert_array_equal([float(d.get("timestep")) for d in ds], times)
    reader = pv.get_reader(str(pvd))
    np.testing.assert_allclose(reader.time_values, times, rtol=0, atol=1e-15)
    reader.set_active_time_value(times[2])
    block = reader.read()[0]
    np.testing.assert_array_equal(block.points, pts[2].reshape(-1, 3).astype(np.float32))


def test_surface_frames_read_back(tmp_path):
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=2)
    verts = np.stack([sphere.vertices, 2.0 * sphere.vertices + 1.0])
    pvd = vtk_files.write_surface_frames(tmp_path, "tri", verts, sphere.faces, times=[0.0, 1.0])
    assert pvd.name == "tri_surface.pvd"
    mesh = pv.read(tmp_path / "tri_surface_0001.vtp")
    assert mesh.n_cells == len(sphere.faces) and mesh.is_all_triangles
    np.testing.assert_array_equal(mesh.points, verts[1].astype(np.float32))   # float32 points
    np.testing.assert_array_equal(mesh.faces.reshape(-1, 4)[:, 1:], sphere.faces)
    # closed surface: volume of the scaled sphere is 8x the unit one (same polyhedron)
    # (float32 points: 6e-8 relative per coordinate)
    assert mesh.volume == pytest.approx(8.0 * sphere.volume, rel=1e-6)


@pytest.mark.parametrize("call", [
    lambda d: vtk_files.write_fibre_frames(d, "m", np.zeros((2, 3, 4)), times=[0, 1]),
    lambda d: vtk_files.write_fibre_frames(d, "m", np.zeros((2, 3, 4, 3)), times=[0]),
    lambda d: vtk_files.write_fibre_frames(d, "m", np.zeros((2, 3, 4, 3)), times=[0, 1],
                                           frames=[0.5, 1.5]),
    lambda d: vtk_files.write_fibre_frames(d, "m", np.zeros((2, 3, 4, 3)), times=[0, 1],
                                           cell_data={"x": np.zeros((2, 4))}),
    lambda d: vtk_files.write_polylines_vtp(d / "x.vtp", np.zeros((3, 4, 3)),
                                            cell_data={"fibre": np.zeros(3)}),
    lambda d: vtk_files.write_polylines_vtp(d / "x.vtp", np.zeros((3, 1, 3))),
    lambda d: vtk_files.write_surface_vtp(d / "x.vtp", np.zeros((3, 3)), [[0, 1, 3]]),
    lambda d: vtk_files.write_surface_vtp(d / "x.vtp", np.zeros((3, 3)), [[0.0, 1.0, 2.0]]),
])
def test_rejects_bad_shapes_and_writes_nothing(tmp_path, call):
    with pytest.raises(ValueError):
        call(tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_nan_fibres_are_written_as_nan(tmp_path):
    pts = np.ones((2, 4, 3))
    pts[1] = np.nan                                    # a failed fibre stays in its slot
    mesh = pv.read(vtk_files.write_polylines_vtp(tmp_path / "n.vtp", pts))
    assert mesh.n_cells == 2
    assert np.isnan(mesh.points[4:]).all() and np.isfinite(mesh.points[:4]).all()


def test_muscle_files_are_written_as_each_muscle_ends_and_only_scene_frames_are_kept(tmp_path):
    """`fibres run`'s ``on_muscle`` hook: a muscle's fibres/ files are complete when the hook
    returns, and the result keeps the scene's frames of its points and surfaces (every
    ``scene_step``-th), or none without a scene."""
    from analysis.cli_run import muscle_files_writer
    from analysis.result import MuscleResult

    rng = np.random.default_rng(5)
    n_f = 7
    m = MuscleResult("a b", ("q",), 0.1 + rng.random((n_f, N)), rng.normal(size=(n_f, N, 1)), ("l",),
                     0.1 + rng.random((n_f, 1)), rng.normal(size=(n_f, 1, 1)), np.ones(N),
                     fibre_points=rng.normal(size=(n_f, N, P, 3)), surface_vertices=rng.normal(size=(n_f, 9, 3)),
                     surface_faces=np.array([[0, 1, 2], [3, 4, 5], [6, 7, 8]]))
    times = np.arange(n_f) * 0.1
    kept = muscle_files_writer(tmp_path, ["a b"], scene_step=3)(times, m)
    np.testing.assert_array_equal(kept.fibre_points, m.fibre_points[[0, 3, 6]])
    np.testing.assert_array_equal(kept.surface_vertices, m.surface_vertices[[0, 3, 6]])
    files = sorted(p.name for p in (tmp_path / "fibres").iterdir())
    assert len([f for f in files if f.endswith(".vtp")]) == n_f     # the fibres (surfaces: the scene's)
    back = pv.read(tmp_path / "fibres" / [f for f in files if f.endswith("_0005.vtp") and "surface" not in f][0])
    np.testing.assert_array_equal(np.asarray(back.points).reshape(N, P, 3), m.fibre_points[5].astype(np.float32))
    none = muscle_files_writer(tmp_path / "x", ["a b"], scene=False)(times, m)
    assert none.fibre_points is None and none.surface_vertices is None
