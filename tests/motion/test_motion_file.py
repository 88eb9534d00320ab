"""motion.osim.motion_file: reading .mot/.sto as OpenSim 4.6 does, writing .sto that OpenSim reads."""
from __future__ import annotations

import dataclasses
import math
import re
import warnings

import numpy as np
import pytest

from motion.errors import InputError
from motion.osim.model import Body, Coordinate, CouplerConstraint, Model
from motion.osim.motion_file import Motion, MotionFileWarning, load_motion, write_sto

# ------------------------------------------------------------------ a small model (no I/O)


def _coordinate(name, motion_type, default=0.0, locked=False, joint="j"):
    return Coordinate(name=name, motion_type=motion_type, default_value=default,
                      range=(-10.0, 10.0), clamped=False, locked=locked, joint=joint)


def _model(coordinates, couplers=()):
    return Model(name="toy", file="toy.osim", version=40000, bodies=(Body("ground"),), joints=(),
                 coordinates=tuple(coordinates), couplers=tuple(couplers))


@pytest.fixture
def toy():
    """rot (rotational), tx (translational), cpl (coupled, a coupler's dependent), lck (locked)."""
    coordinates = [
        _coordinate("rot", "rotational", 0.25, joint="hinge"),
        _coordinate("tx", "translational", 0.5, joint="slide"),
        _coordinate("cpl", "coupled", 0.75, joint="knee"),
        _coordinate("lck", "rotational", 1.5, locked=True, joint="hinge"),
    ]
    coupler = CouplerConstraint(name="c", independent=("rot",), dependent="cpl", function=None)
    return _model(coordinates, [coupler])


def _write(tmp_path, text, name="m.mot"):
    path = tmp_path / name
    path.write_text(text)
    return path


V1 = """demo
version=1
nRows=3
nColumns=5
inDegrees={deg}

Units are S.I. units (second, meters, Newtons, ...)
Angles are in degrees.

endheader
time\trot\ttx\tcpl\tlck
0.0\t10\t0.1\t20\t30
0.5\t20\t0.2\t40\t60
1.0\t30\t0.3\t60\t90
"""


def _load(path, model):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        motion = load_motion(path, model)
    return motion, [w for w in caught if issubclass(w.category, MotionFileWarning)]


# ------------------------------------------------------------------ header variants and degrees


def test_version1_in_degrees_converts_only_rotational(tmp_path, toy):
    motion, caught = _load(_write(tmp_path, V1.format(deg="yes")), toy)
    assert caught == []
    assert motion.coordinate_names == ("rot", "tx", "cpl", "lck")
    assert motion.in_degrees and motion.missing == () and motion.unknown == ()
    np.testing.assert_array_equal(motion.time, [0.0, 0.5, 1.0])
    # rotational columns: degrees -> radians (exact up to one rounding of deg2rad)
    np.testing.assert_allclose(motion.column("rot"), np.radians([10, 20, 30]), rtol=1e-15)
    np.testing.assert_allclose(motion.column("lck"), np.radians([30, 60, 90]), rtol=1e-15)
    # translational and coupled: left as they are (OpenSim's rule)
    np.testing.assert_array_equal(motion.column("tx"), [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(motion.column("cpl"), [20, 40, 60])


def test_version1_in_radians_is_untouched(tmp_path, toy):
    motion, _ = _load(_write(tmp_path, V1.format(deg="no")), toy)
    assert not motion.in_degrees
    np.testing.assert_array_equal(motion.q, [[10, 0.1, 20, 30], [20, 0.2, 40, 60], [30, 0.3, 60, 90]])


def test_version3_sto_adapter_header(tmp_path, toy):
    text = ("inDegrees=yes\nDataType=double\nversion=3\nOpenSimVersion=4.6\nendheader\n"
            "time\trot\ttx\n0\t90\t1\n0.1\t180\t2\n")
    motion, caught = _load(_write(tmp_path, text, "v3.sto"), toy)
    np.testing.assert_allclose(motion.column("rot"), [math.pi / 2, math.pi], rtol=1e-15)
    np.testing.assert_array_equal(motion.column("tx"), [1, 2])
    assert motion.missing == ("cpl", "lck")
    # cpl is a coupler's dependent and lck is locked: their file values would not be used,
    # so their absence is not worth a warning.
    assert caught == []


def test_version3_without_in_degrees_means_radians(tmp_path, toy):
    text = "version=3\nendheader\ntime\trot\n0\t1.5\n"
    motion, _ = _load(_write(tmp_path, text, "v3.sto"), toy)
    assert not motion.in_degrees
    assert motion.column("rot")[0] == 1.5


def test_old_simm_header_is_degrees_and_space_separated(tmp_path, toy):
    # OpenSim: "Old version storage/motion file encountered ... assuming rotations in Degrees".
    text = "old\ndatacolumns 3\ndatarows 2\nrange 0 1\nendheader\ntime rot tx\n0 45 1\n1 90 2\n"
    motion, _ = _load(_write(tmp_path, text), toy)
    assert motion.in_degrees
    np.testing.assert_allclose(motion.column("rot"), [math.pi / 4, math.pi / 2], rtol=1e-15)
    np.testing.assert_array_equal(motion.column("tx"), [1, 2])


def test_spreadsheet_export_trailing_tabs_and_wrong_nrows(tmp_path, toy):
    # As the LHDL hip motions: every header line padded with tabs, nRows larger than the rows.
    pad = "\t" * 4
    text = (f"m{pad}\nversion=1{pad}\nnRows=51{pad}\nnColumns=3{pad}\ninDegrees=no{pad}\n{pad}\n"
            f"\"Units are S.I. units (second, meters, Newtons, ...)\"{pad}\nendheader{pad}\n"
            "time\trot\ttx\n0\t1\t2\n0.01\t3\t4\n\n")
    motion, caught = _load(_write(tmp_path, text), toy)
    assert motion.n_frames == 2
    np.testing.assert_array_equal(motion.column("rot"), [1, 3])
    # the disagreement is reported once, with both numbers
    msgs = [str(w.message) for w in caught if "nRows" in str(w.message)]
    assert len(msgs) == 1 and "nRows=51" in msgs[0] and "2 data rows" in msgs[0]


def test_agreeing_nrows_does_not_warn(tmp_path, toy):
    text = "m\nversion=1\nnRows=2\nnColumns=3\ninDegrees=no\nendheader\ntime\trot\ttx\n0\t1\t2\n0.01\t3\t4\n"
    _, caught = _load(_write(tmp_path, text), toy)
    assert not [w for w in caught if "nRows" in str(w.message)]


def test_crlf_line_ends(tmp_path, toy):
    text = V1.format(deg="no").replace("\n", "\r\n")
    path = tmp_path / "crlf.mot"
    path.write_bytes(text.encode())
    motion, _ = _load(path, toy)
    np.testing.assert_array_equal(motion.column("tx"), [0.1, 0.2, 0.3])


# ------------------------------------------------------------------ labels and warnings


def test_state_path_labels_and_quiet_speeds(tmp_path, toy):
    text = ("states\nversion=1\ninDegrees=no\nendheader\n"
            "time\t/jointset/hinge/rot/value\t/jointset/hinge/rot/speed\t/jointset/slide/tx/value\t"
            "tx_u\n0\t1\t9\t2\t9\n1\t3\t9\t4\t9\n")
    motion, caught = _load(_write(tmp_path, text, "s.sto"), toy)
    np.testing.assert_array_equal(motion.column("rot"), [1, 3])
    np.testing.assert_array_equal(motion.column("tx"), [2, 4])
    assert motion.unknown == ()
    assert caught == []


def test_state_path_with_wrong_joint_is_unknown(tmp_path, toy):
    text = ("s\nversion=1\nendheader\ntime\t/jointset/hinge/rot/value\t/jointset/other/tx/value\n"
            "0\t1\t2\n")
    motion, caught = _load(_write(tmp_path, text), toy)
    assert motion.unknown == ("/jointset/other/tx/value",)
    assert motion.column("tx")[0] == 0.5  # the default
    assert len(caught) == 2  # unknown columns once, missing 'tx' once


def test_unknown_columns_warn_once_listing_all(tmp_path, toy):
    text = ("s\nversion=1\ninDegrees=no\nendheader\ntime\txRotation\trot\tyRotation\tzTranslation\n"
            "0\t1\t2\t3\t4\n")
    motion, caught = _load(_write(tmp_path, text), toy)
    assert motion.unknown == ("xRotation", "yRotation", "zTranslation")
    unknown = [w for w in caught if "xRotation" in str(w.message)]
    assert len(unknown) == 1
    message = str(unknown[0].message)
    assert "yRotation" in message and "zTranslation" in message and "line 5" in message
    assert motion.column("rot")[0] == 2


def test_missing_coordinates_take_defaults_and_warn_once(tmp_path):
    model = _model([_coordinate("a", "rotational", 0.1), _coordinate("b", "translational", 0.2),
                    _coordinate("c", "rotational", -0.3)])
    text = "s\nversion=1\nendheader\ntime\tb\n0\t1\n1\t2\n"
    motion, caught = _load(_write(tmp_path, text), model)
    assert motion.missing == ("a", "c")
    np.testing.assert_array_equal(motion.column("a"), [0.1, 0.1])
    np.testing.assert_array_equal(motion.column("c"), [-0.3, -0.3])
    assert len(caught) == 1
    assert "'a'" not in str(caught[0].message)  # names listed plainly, comma-separated
    assert "a, c" in str(caught[0].message)


def test_missing_spanned_coordinates_are_named_apart(tmp_path):
    """LHDL hip motion without hip_flexion_r: the coordinates the muscles' paths span are named in
    a warning of their own, with the default value they keep, apart from the irrelevant ones."""
    model = _model([_coordinate("a", "rotational", 0.1), _coordinate("b", "translational", 0.2),
                    _coordinate("c", "rotational", -0.3), _coordinate("d", "translational", 0.05)])
    path = _write(tmp_path, "s\nversion=1\nendheader\ntime\tb\n0\t1\n1\t2\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        motion = load_motion(path, model, spanned={"b", "c", "d"})
    messages = [str(w.message) for w in caught if issubclass(w.category, MotionFileWarning)]
    assert motion.missing == ("a", "c", "d")
    np.testing.assert_array_equal(motion.column("c"), [-0.3, -0.3])
    assert len(messages) == 2 and all("\n" not in m for m in messages)
    spanned, other = messages
    # -0.3 rad = -17.19 deg; the translational default in metres
    assert "2 coordinate(s) that the selected muscles' paths span" in spanned
    assert "stay at their default value in every frame: c = -17.19 deg, d = 0.05 m" in spanned
    assert "'a'" not in spanned and " a " not in spanned
    assert other.endswith("(no selected muscle path spans them): a")


def test_two_columns_for_one_coordinate_is_an_error(tmp_path, toy):
    text = "s\nversion=1\nendheader\ntime\trot\t/jointset/hinge/rot/value\n0\t1\t1\n"
    with pytest.raises(InputError, match=r"line 4: columns 'rot' and '/jointset/hinge/rot/value'"):
        load_motion(_write(tmp_path, text), toy)


# ------------------------------------------------------------------ bad input: one line each


GOOD_HEAD = "s\nversion=1\ninDegrees=no\nendheader\ntime\trot\ttx\n"
BAD_FILES = {
    # name: (content, expected 'where', expected words in the problem)
    "non_monotonic": (GOOD_HEAD + "0\t1\t2\n0.2\t1\t2\n0.1\t1\t2\n", "line 8", "not increasing"),
    "repeated_time": (GOOD_HEAD + "0\t1\t2\n0\t1\t2\n", "line 7", "not increasing"),
    "nan": (GOOD_HEAD + "0\t1\t2\n0.1\tNaN\t2\n", "line 7", "nan in column 'rot'"),
    "infinity": (GOOD_HEAD + "0\t1\tinf\n", "line 6", "inf in column 'tx'"),
    "text": (GOOD_HEAD + "0\t1\t2\n0.1\tabc\t2\n", "line 7", "text 'abc' in number column 'rot'"),
    "ragged": (GOOD_HEAD + "0\t1\t2\n0.1\t1\n", "line 7", "ragged row: 2 values but 3"),
    "no_endheader": ("s\nversion=1\nnRows=1\ntime\trot\n0\t1\n", "line 5", "never ends"),
    "no_rows": (GOOD_HEAD, "line 5", "no data rows"),
    "no_labels": ("s\nversion=1\nendheader\n\n", "line 3", "no column labels"),
    "no_coordinate": ("s\nversion=1\nendheader\ntime\tfoo\tbar\n0\t1\t2\n", "line 4",
                      "no column is a coordinate of model 'toy'"),
    "empty": ("", None, "is empty"),
    "blank": ("\n \n\t\n", None, "is empty"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_file_is_one_line_input_error(tmp_path, toy, case):
    content, where, words = BAD_FILES[case]
    path = _write(tmp_path, content, f"{case}.mot")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning may come before the error
        with pytest.raises(InputError) as info:
            load_motion(path, toy)
    err = info.value
    message = str(err)
    assert "\n" not in message
    assert message.startswith(str(path))
    assert err.where == where
    assert words in message
    assert err.fix  # says what to do


def test_missing_file(tmp_path, toy):
    with pytest.raises(InputError, match="does not exist. Check the path"):
        load_motion(tmp_path / "nope.mot", toy)


def test_folder_instead_of_file(tmp_path, toy):
    with pytest.raises(InputError, match="is a folder"):
        load_motion(tmp_path, toy)


def test_binary_file(tmp_path, toy):
    path = tmp_path / "b.mot"
    path.write_bytes(bytes(range(256)) * 8)
    with pytest.raises(InputError, match="binary file"):
        load_motion(path, toy)


def test_gzip_file_is_binary(tmp_path, toy):
    import gzip

    path = tmp_path / "g.mot"
    path.write_bytes(gzip.compress(V1.format(deg="no").encode()))
    with pytest.raises(InputError, match="binary file"):
        load_motion(path, toy)


# ------------------------------------------------------------------ Motion itself


def test_motion_arrays_are_read_only_and_validated(toy):
    motion = Motion.from_array(toy, [0.0, 1.0], {"rot": [1.0, 2.0]})
    assert motion.q.shape == (2, 4)
    assert motion.missing == ("tx", "cpl", "lck")
    np.testing.assert_array_equal(motion.q[:, 1:], [[0.5, 0.75, 1.5]] * 2)
    with pytest.raises(ValueError):
        motion.q[0, 0] = 3.0
    with pytest.raises(ValueError, match="strictly increasing"):
        Motion.from_array(toy, [1.0, 0.0], np.zeros((2, 4)))
    with pytest.raises(ValueError, match=r"\(F, C\)"):
        Motion.from_array(toy, [0.0, 1.0], np.zeros((2, 3)))
    with pytest.raises(ValueError, match="not coordinates"):
        Motion.from_array(toy, [0.0], {"nope": [1.0]})


def test_select_frames(toy):
    q = np.arange(40.0).reshape(10, 4)
    motion = Motion.from_array(toy, np.linspace(0, 1, 10), q)
    part = motion.select_frames(slice(2, 9, 3))
    np.testing.assert_array_equal(part.q, q[[2, 5, 8]])
    np.testing.assert_array_equal(part.time, motion.time[[2, 5, 8]])


# ------------------------------------------------------------------ writing


def test_round_trip_is_exact(tmp_path, toy):
    rng = np.random.default_rng(7)
    time = np.cumsum(rng.uniform(0.001, 0.1, 50))
    q = rng.normal(size=(50, 4)) * np.array([1.0, 1e-3, 1e5, 1e-12])
    source = Motion.from_array(toy, time, q)
    path = write_sto(tmp_path / "rt.sto", source.time, dict(zip(source.coordinate_names, q.T)))
    back, caught = _load(path, toy)
    assert caught == []
    assert not back.in_degrees
    np.testing.assert_array_equal(back.time, time)  # shortest repr: every double survives
    np.testing.assert_array_equal(back.q, q)


def test_written_numbers_are_shortest_round_trip(tmp_path):
    """0.03 is written as 0.03 (Python's repr: the shortest text that reads back as the same
    double), not %.17g's 0.029999999999999999; 1e-12 and -0.0 stay exact."""
    path = write_sto(tmp_path / "s.sto", [0.0, 0.01, 0.03], {"a": [0.1, 1e-12, -0.0]})
    rows = path.read_text().splitlines()[-3:]
    assert rows == ["0.0\t0.1", "0.01\t1e-12", "0.03\t-0.0"]


def test_write_dataframe_and_degrees_flag(tmp_path, toy):
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame({"rot": [90.0, 180.0], "tx": [1.0, 2.0]})
    path = write_sto(tmp_path / "d.mot", [0.0, 1.0], frame, in_degrees=True, name="sweep")
    text = path.read_text().splitlines()
    assert text[:6] == ["sweep", "version=1", "nRows=2", "nColumns=3", "inDegrees=yes", "endheader"]
    motion, _ = _load(path, toy)
    np.testing.assert_allclose(motion.column("rot"), [math.pi / 2, math.pi], rtol=1e-15)


@pytest.mark.parametrize("bad", [
    {"time": [0.0, 1.0]}, {"a\tb": [0.0, 1.0]}, {"": [0.0, 1.0]}, {"a": [0.0, np.nan]},
])
def test_write_rejects_bad_columns(tmp_path, bad):
    with pytest.raises(ValueError):
        write_sto(tmp_path / "x.sto", [0.0, 1.0], bad)
    assert list(tmp_path.iterdir()) == []  # nothing half-written


def test_write_rejects_bad_time(tmp_path):
    with pytest.raises(ValueError, match="increasing"):
        write_sto(tmp_path / "x.sto", [0.0, 0.0], {"a": [1.0, 2.0]})
    with pytest.raises(ValueError, match="rows"):
        write_sto(tmp_path / "x.sto", [0.0, 1.0, 2.0], {"a": [1.0, 2.0]})


def test_opensim_storage_reads_our_sto(tmp_path, osim):
    rng = np.random.default_rng(3)
    time = np.linspace(0.0, 2.0, 21)
    values = {"r_shoulder_elev": rng.normal(size=21), "r_elbow_flex": rng.normal(size=21)}
    path = write_sto(tmp_path / "ours.sto", time, values)
    storage = osim.Storage(str(path))
    labels = storage.getColumnLabels()
    assert [labels.get(i) for i in range(labels.getSize())] == ["time", *values]
    assert storage.getSize() == 21
    assert not storage.isInDegrees()
    for name, expected in values.items():
        column = osim.ArrayDouble()
        storage.getDataColumn(name, column)
        got = np.array([column.get(i) for i in range(column.getSize())])
        # OpenSim parses the shortest round-trip text with strtod: bit-identical doubles.
        np.testing.assert_array_equal(got, expected)
    times = osim.ArrayDouble()
    storage.getTimeColumn(times)
    np.testing.assert_array_equal([times.get(i) for i in range(times.getSize())], time)


def _storage_table(osim, path):
    """Labels and (R, L) values of a file as OpenSim's Storage reads it (no conversion)."""
    storage = osim.Storage(str(path))
    labels = storage.getColumnLabels()
    names = [labels.get(i) for i in range(labels.getSize())]
    times = osim.ArrayDouble()
    storage.getTimeColumn(times)
    table = [[times.get(i) for i in range(times.getSize())]]
    for name in names[1:]:
        column = osim.ArrayDouble()
        storage.getDataColumn(name, column)
        table.append([column.get(i) for i in range(column.getSize())])
    return names, np.array(table).T, storage.isInDegrees()


def test_every_shared_motion_parses_as_opensim_does(shared_dir, osim, tmp_path):
    files = sorted(shared_dir.glob("opensim/**/*.mot")) + sorted(
        shared_dir.glob("muscles/LHDL_hip_r/model/motions/*.mot"))
    assert len(files) >= 17
    for path in files:
        names, expected, in_degrees = _storage_table(osim, path)
        # A model whose coordinates are the file's columns, all translational: no conversion,
        # so the raw numbers must be exactly OpenSim's (ranges wide enough for degrees as metres).
        model = _model([dataclasses.replace(_coordinate(n, "translational"), range=(-1e6, 1e6))
                        for n in names[1:]])
        motion, caught = _load(path, model)
        # the only warning allowed: a header nRows that the rows disagree with (LHDL: 51 vs 36)
        assert all("nRows=" in str(w.message) for w in caught) and len(caught) <= 1, path
        declared = re.search(r"^nRows=(\d+)", path.read_text(), re.M)
        assert len(caught) == (declared is not None and int(declared.group(1)) != len(expected)), path
        assert motion.in_degrees == in_degrees, path
        np.testing.assert_array_equal(np.column_stack([motion.time, motion.q]), expected,
                                      err_msg=str(path))


# ------------------------------------------------------------------ real models (shared data)


def _reference_cases(shared_dir):
    """(model, motion, reference folder) of every OpenSim reference set."""
    import json

    cases = []
    for meta in sorted((shared_dir / "opensim" / "reference").glob("*/*/metadata.json")):
        info = json.loads(meta.read_text())
        # metadata paths are relative to the repository root: ../shared/...
        model = shared_dir.parent / info["model_file"].replace("../", "", 1)
        motion = shared_dir.parent / info["motion_file"].replace("../", "", 1)
        cases.append((model, motion, meta.parent))
    return cases


def test_motions_match_opensim_reference_values(shared_dir):
    """q equals the reference's ``motion_value`` (OpenSim's own deg->rad rule) where the file has
    the column, and the model default where it has not (the reference keeps defaults too)."""
    pd = pytest.importorskip("pandas")
    from motion.osim.reader import load_model

    cases = _reference_cases(shared_dir)
    assert len(cases) >= 14
    for model_file, motion_file, ref_dir in cases:
        model = load_model(model_file)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MotionFileWarning)
            motion = load_motion(motion_file, model)
        ref = pd.read_csv(ref_dir / "coordinates.csv")
        rows = np.searchsorted(motion.time, ref.time.to_numpy() - 1e-9)
        np.testing.assert_allclose(motion.time[rows], ref.time, rtol=0, atol=1e-8)
        cols = [model.coordinate_index(n) for n in ref.coordinate]
        ours = motion.q[rows, cols]
        expected = ref.motion_value.to_numpy()
        defaults = np.array([model.coordinates[c].default_value for c in cols])
        expected = np.where(np.isnan(expected), defaults, expected)
        # the reference CSV prints 17 significant digits: equality to 1 ulp-ish
        np.testing.assert_allclose(ours, expected, rtol=1e-15, atol=1e-15, err_msg=str(ref_dir))


def test_lhdl_motion_warns_once_per_kind(lhdl_dir):
    from motion.osim.reader import load_model

    model = load_model(lhdl_dir / "model" / "LHDL_hip_r.osim")
    motion, caught = _load(lhdl_dir / "model" / "motions" / "hip_flexion.mot", model)
    assert motion.unknown == ("xRotation", "yRotation", "zRotation", "xTranslation",
                              "yTranslation", "zTranslation")
    assert motion.missing == ("pelvis_tilt", "pelvis_list", "pelvis_rotation", "pelvis_tx",
                              "pelvis_ty", "pelvis_tz")
    assert len(caught) == 3      # unknown columns, missing coordinates, nRows=51 for 36 rows
    assert sum("nRows=51" in str(w.message) for w in caught) == 1
    assert sum("xRotation" in str(w.message) for w in caught) == 1
    assert sum("pelvis_tilt" in str(w.message) for w in caught) == 1
    assert sum("nRows=51 but the file holds 36 data rows" in str(w.message) for w in caught) == 1
    assert motion.n_frames == 36  # the header says nRows=51; OpenSim also reads 36 rows
    np.testing.assert_allclose(motion.column("hip_flexion_r")[[0, -1]], np.radians([-10, 60]),
                               rtol=1e-15)


def test_reads_what_opensim_sto_adapter_writes(tmp_path, toy, osim):
    """A version-3 file written by OpenSim 4.6's own STOFileAdapter (no nRows, metadata lines)."""
    table = osim.TimeSeriesTable()
    table.setColumnLabels(["/jointset/hinge/rot/value", "tx"])
    time = [0.0, 0.25, 0.5]
    rows = [[10.0, 0.1], [20.0, 0.2], [30.0, 0.3]]
    for t, row in zip(time, rows):
        table.appendRow(t, osim.RowVector(row))
    table.addTableMetaDataString("inDegrees", "yes")
    path = tmp_path / "adapter.sto"
    osim.STOFileAdapter.write(table, str(path))
    assert "version=3" in path.read_text()
    motion, _ = _load(path, toy)
    assert motion.in_degrees
    np.testing.assert_array_equal(motion.time, time)
    np.testing.assert_allclose(motion.column("rot"), np.radians([10.0, 20.0, 30.0]), rtol=1e-15)
    np.testing.assert_array_equal(motion.column("tx"), [0.1, 0.2, 0.3])


# ------------------------------------------------------------------ untrusted headers (issue 16)
_ELBOW = ("elbow\nversion=1\nnRows={n}\nnColumns=2\ninDegrees={deg}\nendheader\n"
          "time\trot\n" + "".join(f"{0.1 * i:.1f}\t{10 * i}\n" for i in range(13)))


@pytest.mark.parametrize("word", ["Yes please", "maybe", "degrees", "2", ""])
def test_unknown_in_degrees_value_is_an_error(tmp_path, toy, word):
    """OpenSim reads any inDegrees value but 'yes' as radians (130 deg became 7,448 deg)."""
    path = tmp_path / "elbow.mot"
    path.write_text(_ELBOW.format(n=13, deg=word))
    with pytest.raises(InputError, match=r"line 5: inDegrees=.* is neither yes nor no") as err:
        load_motion(path, toy)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


@pytest.mark.parametrize("word,expected", [("YES", True), ("True", True), ("1", True), ("No", False),
                                           ("false", False), ("0", False)])
def test_in_degrees_spellings(tmp_path, toy, word, expected):
    path = tmp_path / "elbow.mot"
    path.write_text(_ELBOW.format(n=13, deg=word))
    motion, _ = _load(path, toy)
    assert motion.in_degrees is expected


def test_row_count_disagreeing_with_the_rows_warns_once(tmp_path, toy):
    path = tmp_path / "elbow.mot"
    path.write_text(_ELBOW.format(n=27, deg="yes"))
    motion, caught = _load(path, toy)
    assert motion.n_frames == 13                     # the rows present are used, as OpenSim does
    counts = [w for w in caught if "nRows=27 but the file holds 13 data rows" in str(w.message)]
    assert len(counts) == 1 and "line 3" in str(counts[0].message)
    path.write_text(_ELBOW.format(n="thirteen", deg="yes"))
    _, caught = _load(path, toy)
    assert sum("not a whole number" in str(w.message) for w in caught) == 1


def test_angles_far_outside_the_range_warn_once(tmp_path):
    """Degrees declared as radians: 0..120 'rad' for a coordinate of range 0..130 deg."""
    model = _model([Coordinate(name="rot", motion_type="rotational", default_value=0.0,
                               range=(0.0, np.radians(130)), clamped=False, locked=False, joint="j"),
                    Coordinate(name="rot2", motion_type="rotational", default_value=0.0,
                               range=(0.0, np.radians(130)), clamped=False, locked=False, joint="j")])
    path = tmp_path / "elbow.mot"
    rows = "".join(f"{0.1 * i:.1f}\t{10 * i}\t0\n" for i in range(13))
    path.write_text("elbow\nversion=1\nnRows=13\nnColumns=3\ninDegrees=no\nendheader\n"
                    "time\trot\trot2\n" + rows)
    motion, caught = _load(path, model)
    far = [w for w in caught if "far outside" in str(w.message)]
    assert len(far) == 1
    assert "rot reaches 6875.49 deg" in str(far[0].message)     # 120 rad
    assert "rot2" not in str(far[0].message)
    path.write_text(path.read_text().replace("inDegrees=no", "inDegrees=yes"))
    _, caught = _load(path, model)
    assert not [w for w in caught if "far outside" in str(w.message)]
