"""fibres.mesh.vtk_reader / fibres.mesh.vtk_xml: the same points and triangles as VTK itself reads, in every
format and data mode VTK writes; damaged cell arrays are one-line InputErrors, never a crash."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from fibres.errors import InputError
from fibres.mesh.surface import read_mesh

pv = pytest.importorskip("pyvista")
vtk = pytest.importorskip("vtk")


def _vtk_arrays(path):
    """VTK's own reading (the oracle): points and triangles (polygons fanned by vtkTriangleFilter)."""
    mesh = pv.read(str(path))
    assert isinstance(mesh, pv.PolyData)
    tri = mesh.triangulate()
    return np.asarray(tri.points, float), np.asarray(tri.faces).reshape(-1, 4)[:, 1:]


@pytest.fixture(scope="module")
def sphere():
    return pv.Sphere(theta_resolution=12, phi_resolution=9).triangulate()


def _xml_file(path, mesh, mode, comp, encode, header, order):
    w = vtk.vtkXMLPolyDataWriter() if path.suffix == ".vtp" else vtk.vtkXMLUnstructuredGridWriter()
    w.SetInputData(mesh)
    getattr(w, f"SetDataModeTo{mode}")()
    w.SetEncodeAppendedData(encode)
    w.SetHeaderTypeToUInt64() if header == 64 else w.SetHeaderTypeToUInt32()
    {"none": w.SetCompressorTypeToNone, "zlib": w.SetCompressorTypeToZLib,
     "lzma": w.SetCompressorTypeToLZMA}[comp]()
    w.SetByteOrderToBigEndian() if order == "big" else w.SetByteOrderToLittleEndian()
    w.SetFileName(str(path))
    assert w.Write() == 1
    return path


@pytest.mark.parametrize("mode,comp,encode,header,order", [
    c for c in itertools.product(("Ascii", "Binary", "Appended"), ("none", "zlib", "lzma"), (True, False),
                                 (32, 64), ("little", "big"))
    if not (c[0] != "Appended" and not c[2])])
def test_vtp_every_data_mode_reads_as_vtk_does(tmp_path, sphere, mode, comp, encode, header, order):
    path = _xml_file(tmp_path / "s.vtp", sphere, mode, comp, encode, header, order)
    v, f = read_mesh(path)
    v0, f0 = _vtk_arrays(path)
    np.testing.assert_array_equal(v, v0)
    np.testing.assert_array_equal(f, f0)


@pytest.mark.parametrize("version,binary", [(42, True), (42, False), (51, True), (51, False)])
def test_legacy_vtk_reads_as_vtk_does(tmp_path, sphere, version, binary):
    mesh = sphere.copy()
    mesh.point_data["n"] = np.arange(mesh.n_points, dtype=float)   # attributes after the cells
    mesh.field_data["note"] = np.array([1.0, 2.0])                  # a FIELD block before POINTS
    w = vtk.vtkPolyDataWriter()
    w.SetInputData(mesh)
    w.SetFileVersion(version)
    w.SetFileTypeToBinary() if binary else w.SetFileTypeToASCII()
    w.SetFileName(str(tmp_path / "s.vtk"))
    assert w.Write() == 1
    v, f = read_mesh(tmp_path / "s.vtk")
    v0, f0 = _vtk_arrays(tmp_path / "s.vtk")
    np.testing.assert_array_equal(v, v0)
    np.testing.assert_array_equal(f, f0)


def test_strips_quads_and_unstructured_grids(tmp_path, sphere):
    strips = sphere.strip()
    assert strips.n_strips > 0
    strips.save(tmp_path / "strip.vtp")
    strips.save(tmp_path / "strip.vtk")
    for name in ("strip.vtp", "strip.vtk"):
        v, f = read_mesh(tmp_path / name)
        v0, f0 = _vtk_arrays(tmp_path / name)
        np.testing.assert_array_equal(v, v0)
        np.testing.assert_array_equal(f, f0)                       # same alternating orientation
    grid = sphere.cast_to_unstructured_grid()
    grid.save(tmp_path / "s.vtu")
    grid.save(tmp_path / "u.vtk")
    p0 = np.asarray(sphere.points, dtype=float)
    for name in ("s.vtu", "u.vtk"):                    # the same oriented triangles, any order
        v, f = read_mesh(tmp_path / name)
        assert {tuple(v[t].ravel()) for t in f} == {tuple(p0[t].ravel()) for t in sphere.faces.reshape(-1, 4)[:, 1:]}
    quad = pv.Plane(i_resolution=2, j_resolution=2)                # 4 quads -> 8 fanned triangles
    quad.save(tmp_path / "q.vtp")
    v, f = read_mesh(tmp_path / "q.vtp")
    assert f.shape == (8, 3)
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum()
    assert area == pytest.approx(1.0)


def test_lhdl_meshes_read_as_vtk_does(lhdl_dir):
    files = sorted(lhdl_dir.glob("*/*.vtk"))
    assert len(files) >= 20
    for path in files:
        v, f = read_mesh(path)
        v0, f0 = _vtk_arrays(path)
        np.testing.assert_array_equal(v, v0, err_msg=str(path))
        np.testing.assert_array_equal(f, f0, err_msg=str(path))


def _legacy_51(v, f, offsets=None, conn=None):
    offsets = (3 * np.arange(len(f) + 1)).astype(">i8") if offsets is None else offsets
    conn = np.asarray(f, ">i8").ravel() if conn is None else conn
    return (b"# vtk DataFile Version 5.1\nvtk output\nBINARY\nDATASET POLYDATA\n"
            + f"POINTS {len(v)} double\n".encode() + np.asarray(v, ">f8").tobytes() + b"\n"
            + f"POLYGONS {len(offsets)} {len(conn)}\nOFFSETS vtktypeint64\n".encode()
            + np.asarray(offsets, ">i8").tobytes() + b"\nCONNECTIVITY vtktypeint64\n"
            + np.asarray(conn, ">i8").tobytes() + b"\n")


@pytest.mark.parametrize("damage,message", [
    ("offset_huge", "OFFSETS"), ("offset_negative", "OFFSETS"), ("offset_decreasing", "OFFSETS"),
    ("index_out_of_range", "refers to"), ("index_negative", "refers to"), ("truncated", "ends inside"),
    ("count_huge", "bytes"), ("count_text", "not a whole number"),
])
def test_damaged_legacy_cell_arrays_are_one_line_errors(tmp_path, sphere, damage, message):
    """The files that made VTK's reader die (SIGSEGV / std::bad_alloc) are refused in one line."""
    v = np.asarray(sphere.points, float)
    f = sphere.faces.reshape(-1, 4)[:, 1:]
    offsets = (3 * np.arange(len(f) + 1)).astype(np.int64)
    conn = f.ravel().astype(np.int64)
    if damage == "offset_huge":
        offsets[5] = 2**40
    elif damage == "offset_negative":
        offsets[5] = -7
    elif damage == "offset_decreasing":
        offsets[5], offsets[6] = offsets[6], offsets[5]
    elif damage == "index_out_of_range":
        conn[10] = len(v) + 3
    elif damage == "index_negative":
        conn[10] = -1
    data = _legacy_51(v, f, offsets, conn)
    if damage == "truncated":
        data = data[: len(data) - 40]
    elif damage == "count_huge":
        data = data.replace(b"POLYGONS %d" % len(offsets), b"POLYGONS 99999999999")
    elif damage == "count_text":
        data = data.replace(b"POINTS %d" % len(v), b"POINTS many")
    path = tmp_path / "bad.vtk"
    path.write_bytes(data)
    with pytest.raises(InputError, match=message) as err:
        read_mesh(path)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


@pytest.mark.parametrize("cut", [0.2, 0.5, 0.8, 0.95])
def test_truncated_vtp_is_one_line(tmp_path, sphere, cut, capfd):
    sphere.save(tmp_path / "s.vtp")
    data = (tmp_path / "s.vtp").read_bytes()
    (tmp_path / "t.vtp").write_bytes(data[: int(len(data) * cut)])
    with pytest.raises(InputError) as err:
        read_mesh(tmp_path / "t.vtp")
    assert "\n" not in str(err.value)
    assert capfd.readouterr().err == ""              # VTK is not involved: no error dump


def test_xml_entities_and_3d_cells_are_refused(tmp_path):
    (tmp_path / "e.vtp").write_text('<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "b">]>'
                                    '<VTKFile type="PolyData"><PolyData/></VTKFile>')
    with pytest.raises(InputError, match="entities"):
        read_mesh(tmp_path / "e.vtp")
    pv.ImageData(dimensions=(3, 3, 3)).cast_to_unstructured_grid().save(tmp_path / "hex.vtu")
    with pytest.raises(InputError, match="not a surface cell"):
        read_mesh(tmp_path / "hex.vtu")
