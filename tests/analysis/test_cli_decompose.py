"""`fibres decompose`: outputs (.csv, .vtp, .npz) and bad input (exit 2, one line, no file)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import trimesh

from analysis.cli import main

pytest.importorskip("fibres.decompose")

RADII = np.array([0.02, 0.03, 0.12])  # a spindle-shaped "muscle" in metres
ORIGIN = "0.004,0,-0.117;-0.004,0,-0.117;0,0.005,-0.117;0,-0.005,-0.117"
INSERTION = "0.004,0,0.117;-0.004,0,0.117;0,0.005,0.117;0,-0.005,0.117"


@pytest.fixture()
def spindle(tmp_path):
    m = trimesh.creation.icosphere(subdivisions=3)
    m.vertices = np.asarray(m.vertices) * RADII
    path = tmp_path / "spindle.ply"
    m.export(path)
    return path, m


def _run(capsys, *argv):
    code = main(["decompose", *map(str, argv)])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


@pytest.mark.parametrize("fmt", ["csv", "vtp", "npz"])
def test_outputs(tmp_path, capsys, spindle, fmt):
    mesh, m = spindle
    out = tmp_path / f"fib.{fmt}"
    n, r = 12, 9
    code, stdout, err = _run(capsys, mesh, "--origin", ORIGIN, "--insertion", INSERTION,
                             "--fibres", n, "--resolution", r, "--out", out)
    assert code == 0, err
    assert out.is_file() and f"wrote {n} fibres" in stdout and "(coordinates in metres)" in stdout
    assert not list(tmp_path.glob(".*.part"))
    if fmt == "csv":
        tab = pd.read_csv(out)
        assert list(tab.columns) == ["fibre", "point", "x", "y", "z"]
        assert len(tab) == n * (r + 1)
        assert (tab.groupby("fibre").point.apply(list) == [list(range(r + 1))] * n).all()
        pts = tab[["x", "y", "z"]].to_numpy().reshape(n, r + 1, 3)
    elif fmt == "vtp":
        import pyvista as pv

        poly = pv.read(out)
        assert poly.n_cells == n
        np.testing.assert_array_equal(poly.cell_data["fibre"], np.arange(n))
        pts = np.asarray(poly.points).reshape(n, r + 1, 3)
        lines = poly.lines.reshape(n, r + 2)
        np.testing.assert_array_equal(lines[:, 0], r + 1)
        np.testing.assert_array_equal(lines[:, 1:], np.arange(n * (r + 1)).reshape(n, r + 1))
    else:
        data = np.load(out)
        pts = data["points"]
        assert pts.shape == (n, r + 1, 3) and data["rs"].shape == (n, 2)
        assert str(data["template"]) == "parallel"
    # every fibre point lies inside the (convex) ellipsoid: sum (p/a)^2 <= 1 (+ facet slack:
    # the icosphere's inscribed polyhedron is inside the ellipsoid, so this bound is safe)
    assert (((pts / RADII) ** 2).sum(axis=-1) <= 1 + 1e-6).all()
    # fibres run from the origin end to the insertion end
    assert (pts[:, 0, 2] < -0.08).all() and (pts[:, -1, 2] > 0.08).all()


def test_csv_points_files_and_mm_units(tmp_path, capsys, spindle):
    _, m = spindle
    mesh = tmp_path / "spindle_mm.stl"
    mm = m.copy()
    mm.vertices = np.asarray(m.vertices) * 1000
    mm.export(mesh)
    o = tmp_path / "o.csv"
    o.write_text("x,y,z\n" + "\n".join(f"{float(a)*1000},{float(b)*1000},{float(c)*1000}"
                 for a, b, c in (p.split(",") for p in ORIGIN.split(";"))) + "\n")
    i = tmp_path / "i.csv"  # header optional
    i.write_text("\n".join(f"{float(a)*1000},{float(b)*1000},{float(c)*1000}"
                 for a, b, c in (p.split(",") for p in INSERTION.split(";"))) + "\n")
    out = tmp_path / "f.npz"
    code, stdout, err = _run(capsys, mesh, "--origin", o, "--insertion", i, "--units", "mm",
                             "--fibres", 5, "--out", out)
    assert code == 0, err
    assert "(coordinates in metres, converted from mm)" in stdout
    pts = np.load(out)["points"]
    # output in metres
    assert np.abs(pts).max() < 0.13


def _assert_refused(code, err, out, *words):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err  # one line, no traceback
    for w in words:
        assert w in lines[0], lines[0]
    assert not out.exists()
    assert not list(out.parent.glob(".*.part"))


def test_open_mesh(tmp_path, capsys, spindle):
    _, m = spindle
    mesh = tmp_path / "open.ply"
    trimesh.Trimesh(m.vertices, m.faces[:-3], process=False).export(mesh)
    out = tmp_path / "f.csv"
    code, _, err = _run(capsys, mesh, "--origin", ORIGIN, "--insertion", INSERTION, "--out", out)
    _assert_refused(code, err, out, "open.ply", "open", "Close the holes")


def test_points_instead_of_triangles(tmp_path, capsys, spindle):
    import pyvista as pv

    _, m = spindle
    mesh = tmp_path / "cloud.vtp"
    pv.PolyData(np.asarray(m.vertices)).save(mesh)
    out = tmp_path / "f.csv"
    code, _, err = _run(capsys, mesh, "--origin", ORIGIN, "--insertion", INSERTION, "--out", out)
    _assert_refused(code, err, out, "cloud.vtp", "no triangles")


def test_nan_vertices(tmp_path, capsys, spindle):
    _, m = spindle
    v = np.asarray(m.vertices).copy()
    v[5] = np.nan
    mesh = tmp_path / "nan.obj"
    lines = [f"v {a} {b} {c}" for a, b, c in v] + [f"f {a+1} {b+1} {c+1}" for a, b, c in m.faces]
    mesh.write_text("\n".join(lines) + "\n")
    out = tmp_path / "f.csv"
    code, _, err = _run(capsys, mesh, "--origin", ORIGIN, "--insertion", INSERTION, "--out", out)
    _assert_refused(code, err, out, "nan.obj", "NaN")


def test_empty_attachment_set(tmp_path, capsys, spindle):
    mesh, _ = spindle
    empty = tmp_path / "origin.csv"
    empty.write_text("x,y,z\n")
    out = tmp_path / "f.csv"
    code, _, err = _run(capsys, mesh, "--origin", empty, "--insertion", INSERTION, "--out", out)
    _assert_refused(code, err, out, "origin.csv", "empty")


def test_origin_equal_to_insertion(tmp_path, capsys, spindle):
    mesh, _ = spindle
    out = tmp_path / "f.csv"
    code, _, err = _run(capsys, mesh, "--origin", ORIGIN, "--insertion", ORIGIN, "--out", out)
    _assert_refused(code, err, out, "origin", "insertion")


def test_unknown_template(tmp_path, capsys, spindle):
    mesh, _ = spindle
    out = tmp_path / "f.csv"
    code, _, err = _run(capsys, mesh, "--origin", ORIGIN, "--insertion", INSERTION,
                        "--template", "spiral", "--out", out)
    _assert_refused(code, err, out, "spiral", "parallel")


def test_mm_mesh_declared_as_metres(tmp_path, capsys, spindle):
    _, m = spindle
    mesh = tmp_path / "mm.stl"
    mm = m.copy()
    mm.vertices = np.asarray(m.vertices) * 1000
    mm.export(mesh)
    out = tmp_path / "f.csv"
    code, _, err = _run(capsys, mesh, "--origin", ORIGIN, "--insertion", INSERTION, "--out", out)
    _assert_refused(code, err, out, "mm.stl", "millimetres", "--units mm")


def test_metres_declared_as_mm(tmp_path, capsys, spindle):
    """A 0.24 m spindle declared as mm is 0.24 mm across: refused at once (it used to be
    decomposed for a minute into fibres that turn by 180 degrees)."""
    mesh, _ = spindle
    out = tmp_path / "f.csv"
    code, _, err = _run(capsys, mesh, "--origin", ORIGIN, "--insertion", INSERTION, "--units", "mm",
                        "--out", out)
    _assert_refused(code, err, out, "spindle.ply", "too small for a muscle", "--units m")


def test_landmarks_in_other_units(tmp_path, capsys, spindle):
    mesh, _ = spindle
    out = tmp_path / "f.csv"
    scaled = ";".join(",".join(str(float(c) * 1000) for c in p.split(","))
                      for p in ORIGIN.split(";"))
    code, _, err = _run(capsys, mesh, "--origin", scaled, "--insertion", INSERTION, "--out", out)
    _assert_refused(code, err, out, "origin", "same units")


def test_bad_out_suffix_and_usage(tmp_path, capsys, spindle):
    mesh, _ = spindle
    out = tmp_path / "f.txt"
    code, _, err = _run(capsys, mesh, "--origin", ORIGIN, "--insertion", INSERTION, "--out", out)
    _assert_refused(code, err, out, ".vtp, .csv or .npz")
    with pytest.raises(SystemExit) as exc:
        main(["decompose", str(mesh), "--origin", ORIGIN, "--insertion", INSERTION,
              "--fibres", "0"])
    assert exc.value.code == 2
    assert "positive integer" in capsys.readouterr().err


def test_lhdl_original_mesh_one_warning_line(tmp_path, capsys, lhdl_dir):
    out = tmp_path / "glut_med.vtp"
    att = lhdl_dir / "attachments"
    code, stdout, err = _run(capsys, lhdl_dir / "muscles" / "glut_med_r.vtk",
                             "--origin", att / "glut_med_r_origin_1.vtk",
                             "--insertion", att / "glut_med_r_insertion_1.vtk",
                             "--units", "mm", "--fibres", 20, "--out", out)
    assert code == 0, err
    lines = err.strip().splitlines()
    # one line for the repair; the others (20 fibres only) say which fibre-quality limits fail,
    # or are the decomposition's notes (here: a stray piece of the origin patch dropped)
    repairs = [line for line in lines if "repaired" in line]
    assert len(repairs) == 1 and "warning" in repairs[0]
    assert all("warning: fibre quality:" in line or "fibres decompose: note: " in line
               for line in lines if line not in repairs)
    import pyvista as pv

    poly = pv.read(out)
    assert poly.n_cells == 20
    # metres: gluteus medius is ~0.2 m long, its landmarks lie within the surface's box
    assert 0.1 < np.linalg.norm(np.ptp(np.asarray(poly.points), axis=0)) < 0.4


def test_notes_reach_the_user(tmp_path, capsys):
    """A tube whose origin lies on its side halfway up (fibres.slicing.harmonic_sections.
    dead_end_levels): the decomposition's note on the dead end beyond it is printed."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fibres"))
    from test_dead_end import L, _circle, _side_patch
    from test_decompose_analytic import straight, tube

    v, f = tube(_circle, *straight(L), n_sect=40, n_path=65)
    mesh = tmp_path / "tube.ply"
    trimesh.Trimesh(v, f, process=False).export(mesh)
    origin = ";".join(",".join(f"{c:.6f}" for c in p) for p in _side_patch(0.08, 0.11))
    insertion = ";".join(f"{0.005 * np.cos(t):.6f},{0.005 * np.sin(t):.6f},0" for t in
                         np.linspace(0, 2 * np.pi, 8, endpoint=False))
    code, _, err = _run(capsys, mesh, "--origin", origin, "--insertion", insertion,
                        "--fibres", 30, "--resolution", 10, "--out", tmp_path / "f.npz")
    assert code == 0, err
    assert "fibres decompose: note: " in err and "beyond the origin patch" in err
