"""The fibre-model TOML: a valid file loads with defaults and units applied; every mistake is ONE
InputError naming the TOML file, the key and the fix."""
from __future__ import annotations

import textwrap

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.spec import load_spec
from motion.osim.model import Body, Coordinate, Joint, Model, Path, PathPoint


def _model():
    """A two-body model with one muscle (no kinematics needed to validate a spec)."""
    eye = np.eye(4)
    coord = Coordinate("elbow", "rotational", 0.0, [-1.0, 2.0], False, False, "elbow_joint")
    joints = (Joint("shoulder", "WeldJoint", "ground", "upper", eye, eye, (), ()),
              Joint("elbow_joint", "PinJoint", "upper", "lower", eye, eye, ("elbow",), ()))
    path = Path("bic", "Millard2012EquilibriumMuscle", (
        PathPoint("o", "fixed", "upper", [0.0, 0.01, 0.2]),
        PathPoint("i", "fixed", "lower", [0.0, 0.02, -0.05])))
    path2 = Path("bic2", "Millard2012EquilibriumMuscle", path.points)
    return Model("m", "m.osim", 40000, (Body("ground"), Body("upper"), Body("lower")), joints,
                 (coord,), paths=(path, path2))


GOOD = """
model = "m.osim"
units = "mm"
[defaults]
fibres = 20
resolution = 7
[muscles.biceps]
action_lines = ["bic", "bic2"]
mesh = "biceps.stl"
frame = "upper"
rest_pose = { elbow = 0.5 }
origin = { body = "upper", points = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]] }
insertion = { body = "lower", file = "lm.csv", where = { muscle = "biceps", type = "insertion" } }
[muscles.other]
action_lines = "bic"
template = "fanned"
fibres = 5
"""

LANDMARKS = "muscle,type,cloud,x_mm,y_mm,z_mm\nbiceps,origin,1,1,1,1\nbiceps,insertion,1,10,20,30\n" \
            "biceps,insertion,2,40,50,60\nother,insertion,1,7,8,9\n"


def _write(tmp_path, text, files=("m.osim", "biceps.stl")):
    for f in files:
        (tmp_path / f).write_text("x")
    (tmp_path / "lm.csv").write_text(LANDMARKS)
    spec = tmp_path / "spec.toml"
    spec.write_text(textwrap.dedent(text))
    return spec


def test_good_spec_loads_with_defaults_units_and_selected_rows(tmp_path):
    spec = load_spec(_write(tmp_path, GOOD), model=_model())
    assert spec.muscle_names == ("biceps", "other")
    b, o = spec.muscles
    assert b.action_lines == ("bic", "bic2") and o.action_lines == ("bic",)
    assert b.mesh == (tmp_path / "biceps.stl").resolve() and o.mesh is None
    assert (b.n_fibres, b.resolution, b.template, b.frame) == (20, 7, "parallel", "upper")
    assert (o.n_fibres, o.resolution, o.template, o.frame) == (5, 7, "fanned", "ground")
    assert dict(b.rest_pose) == {"elbow": 0.5}
    # units = "mm": points are converted to metres
    np.testing.assert_allclose(b.origin.points, [[1e-3, 2e-3, 3e-3], [4e-3, 5e-3, 6e-3]])
    # x_mm columns are millimetres; the where-table keeps the two biceps insertion rows
    np.testing.assert_allclose(b.insertion.points, [[0.01, 0.02, 0.03], [0.04, 0.05, 0.06]])
    assert b.insertion.body == "lower" and not b.insertion.in_body_frame
    # omitted attachments default to the first / last path point of the first action line
    assert o.origin.body == "upper" and o.origin.in_body_frame
    np.testing.assert_allclose(o.origin.points, [[0.0, 0.01, 0.2]])
    np.testing.assert_allclose(o.insertion.points, [[0.0, 0.02, -0.05]])
    assert b.origin.points.flags.writeable is False
    assert b.bones == () and b.volume is None


def test_bones_and_volume_keys(tmp_path):
    text = GOOD.replace('frame = "upper"', 'frame = "upper"\nbones = [{ body = "upper", mesh = "biceps.stl" }]')
    text = text.replace('template = "fanned"', 'template = "fanned"\nvolume = 2.5e-4')
    spec = load_spec(_write(tmp_path, text), model=_model())
    assert spec.muscles[0].bones == (("upper", (tmp_path / "biceps.stl").resolve()),)
    assert spec.muscles[1].volume == 2.5e-4


@pytest.mark.parametrize("old,new,key,fix", [
    ('action_lines = ["bic", "bic2"]', 'action_lines = ["bic", "nope"]',
     "muscles.biceps.action_lines[1]", "Use one of"),
    ('mesh = "biceps.stl"', 'mesh = "missing.stl"', "muscles.biceps.mesh", "relative to the TOML"),
    ('template = "fanned"', 'template = "spiral"', "muscles.other.template", "Use one of"),
    ('origin = { body = "upper",', 'origin = { body = "femur",', "muscles.biceps.origin.body",
     "Use one of"),
    ("[muscles.other]", "[muscles.other]\ncolour = 3", "muscles.other.colour", "Allowed keys"),
    ('units = "mm"', 'units = "mm"\nspeed = 1', "speed", "Allowed keys"),
    ("fibres = 20", "fibers = 20", "defaults.fibers", "Allowed keys"),
    ('type = "insertion" }', 'type = "insertion" }, colour = 1', "muscles.biceps.insertion.colour",
     "Allowed keys"),
    ("rest_pose = { elbow = 0.5 }", "rest_pose = { knee = 0.5 }", "muscles.biceps.rest_pose.knee",
     "Use one of"),
    ('frame = "upper"', 'frame = "scanner"', "muscles.biceps.frame", "bodies"),
    ('type = "insertion" }', 'type = "ins" }', "muscles.biceps.insertion.where.type", "Values in"),
    ('file = "lm.csv"', 'file = "nolm.csv"', "muscles.biceps.insertion.file", "relative to the TOML"),
    ("fibres = 5", "fibres = 0", "muscles.other.fibres", ">= 1"),
    ("resolution = 7", "resolution = 2.5", "defaults.resolution", ">= 1"),
    ('model = "m.osim"', 'model = "gone.osim"', "model", "relative to the TOML"),
    ('model = "m.osim"', "", "model", "Add model"),
    ("[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]", "[[1.0, 2.0]]", "muscles.biceps.origin.points", "[x, y, z]"),
    ('file = "lm.csv", where', 'points = [[0,0,0]], file = "lm.csv", where',
     "muscles.biceps.insertion", "exactly one"),
    ('units = "mm"', 'units = "inch"', "units", '"mm"'),
    ('frame = "upper"', 'frame = "upper"\nbones = [{ body = "femur", mesh = "biceps.stl" }]',
     "muscles.biceps.bones[0].body", "Use one of"),
    ('frame = "upper"', 'frame = "upper"\nbones = [{ body = "upper", mesh = "nobone.stl" }]',
     "muscles.biceps.bones[0].mesh", "relative to the TOML"),
    ('frame = "upper"', 'frame = "upper"\nvolume = -1.0', "muscles.biceps.volume", "cubic metres"),
])
def test_each_mistake_is_one_input_error_naming_file_key_and_fix(tmp_path, old, new, key, fix):
    assert old in GOOD
    path = _write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(InputError) as info:
        load_spec(path, model=_model())
    msg = str(info.value)
    assert "\n" not in msg
    assert str(path) in msg
    assert f": {key}:" in msg, msg
    assert fix in msg, msg


def test_not_toml_and_missing_file(tmp_path):
    path = _write(tmp_path, "model = [unclosed\n")
    with pytest.raises(InputError, match="not valid TOML"):
        load_spec(path, model=_model())
    with pytest.raises(InputError, match="does not exist"):
        load_spec(tmp_path / "nope.toml", model=_model())


def test_point_cloud_file_and_explicit_columns(tmp_path):
    pv = pytest.importorskip("pyvista")
    pts = np.array([[1.0, 2.0, 3.0], [3.0, 2.0, 1.0]])
    pv.PolyData(pts).save(tmp_path / "cloud.vtk")
    (tmp_path / "p.csv").write_text("a,b,c,px,py,pz\n0,0,0,1,2,3\n")
    text = GOOD.replace('points = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]', 'file = "cloud.vtk"').replace(
        'file = "lm.csv", where = { muscle = "biceps", type = "insertion" }',
        'file = "p.csv", columns = ["px", "py", "pz"], units = "m"')
    spec = load_spec(_write(tmp_path, text), model=_model())
    np.testing.assert_allclose(spec.muscles[0].origin.points, pts * 1e-3)
    np.testing.assert_allclose(spec.muscles[0].insertion.points, [[1.0, 2.0, 3.0]])


def test_lhdl_fibre_model_loads(lhdl_dir):
    """tests/data/lhdl_hip.toml: four muscles, landmarks selected from the shared CSV, mm -> m."""
    from pathlib import Path

    import pandas as pd

    from motion.osim.reader import load_model

    toml = Path(__file__).resolve().parents[1] / "data" / "lhdl_hip.toml"
    spec = load_spec(toml, model=load_model(lhdl_dir / "model" / "LHDL_hip_r.osim"))
    assert spec.muscle_names == ("glut_max_r", "glut_med_r", "iliacus_r", "psoas_r")
    lm = pd.read_csv(lhdl_dir / "attachments" / "attachment_landmarks.csv")
    # counts from the dataset README: glut max origin 21+22, insertion cloud 1 = 11, ...
    counts = {m.name: (len(m.origin.points), len(m.insertion.points)) for m in spec.muscles}
    assert counts == {"glut_max_r": (43, 11), "glut_med_r": (38, 17), "iliacus_r": (40, 7), "psoas_r": (40, 7)}
    il = lm[(lm.muscle == "iliacus_r") & (lm.type == "origin")][["x_mm", "y_mm", "z_mm"]].to_numpy() / 1000
    np.testing.assert_allclose(spec.muscle("psoas_r").origin.points, il)   # psoas origin = iliacus area
    for m in spec.muscles:
        assert m.frame == "bodies" and m.units == "mm" and (m.n_fibres, m.resolution) == (100, 15)
        assert m.origin.body == "pelvis" and m.insertion.body == "femur_r"
        assert m.mesh.is_file()
