"""Issue 16: every reader of an untrusted file, fuzzed with hypothesis: whatever the bytes, the only
exception that may come out is our own `InputError` (one line), and nothing crashes natively.

Readers: the fibre-model TOML (`analysis.load_spec`, also with values of every TOML type at every
key), motions (`motion.load_motion`, .mot/.sto), models (`motion.load_model`, .osim) and surfaces
(`fibres.as_surface` on STL, OBJ, PLY, legacy VTK and VTP files: reading, validation and repair).
Inputs are valid seed files mutated by a few byte-level operations (bit flips, random bytes,
insertions, deletions, truncation, duplicated ranges, inserted tokens such as ``nan``, ``-1``,
``1e308``, NUL, quotes and brackets, and big integers written over binary counts and offsets).

`N_EXAMPLES` (2000) examples per reader; derandomized, so the suite is reproducible. The whole
module takes about a minute on one core.
"""
from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

N_EXAMPLES = 2000
ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
FUZZ = settings(max_examples=N_EXAMPLES, deadline=None, database=None, derandomize=True,
                suppress_health_check=list(HealthCheck))

_TOKENS = [b"-1", b"0", b"nan", b"inf", b"-inf", b"1e308", b"99999999999999999999", b"\x00", b"\n",
           b"\r\n", b"\t", b" ", b"=", b'"', b"'", b"[", b"]", b"{", b"}", b"<", b">", b"/>",
           b"endheader", b"inDegrees=", b"nRows=", b"POINTS", b"OFFSETS", b"CONNECTIVITY", b"v ",
           b"f ", b"facet", b"element vertex", b"&amp;", b"<!DOCTYPE x [<!ENTITY a 'b'>]>", b"\xff\xfe"]
_INTS = [0, 1, -1, 2, 3, 255, 2**15, 2**31 - 1, 2**31, 2**32 - 1, 2**40, 2**63 - 1, -2**63]


@st.composite
def mutated(draw, seeds):
    """One of the ``seeds`` (bytes) with 1..6 random mutations."""
    data = bytearray(draw(st.sampled_from(seeds)))
    for _ in range(draw(st.integers(1, 6))):
        op = draw(st.integers(0, 8))
        pos = draw(st.integers(0, max(len(data) - 1, 0)))
        if op == 0 and data:
            data[pos] ^= 1 << draw(st.integers(0, 7))
        elif op == 1 and data:
            data[pos] = draw(st.integers(0, 255))
        elif op == 2:
            data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
        elif op == 3:
            del data[pos:pos + draw(st.integers(1, 64))]
        elif op == 4:
            del data[pos:]
        elif op == 5:
            n = draw(st.integers(1, 64))
            data[pos:pos] = data[pos:pos + n]
        elif op in (6, 7):
            data[pos:pos] = draw(st.sampled_from(_TOKENS))
        else:                                   # a big/negative integer over a binary field
            fmt = draw(st.sampled_from(["<i", ">i", "<q", ">q", "<I", ">Q"]))
            value = draw(st.sampled_from(_INTS))
            try:
                packed = struct.pack(fmt, value)
            except struct.error:
                packed = struct.pack(fmt, 0)
            data[pos:pos + len(packed)] = packed
    return bytes(data)


def _errors():
    import analysis.errors
    import fibres.errors
    import motion.errors

    return (analysis.errors.InputError, motion.errors.InputError, fibres.errors.InputError)


def _only_input_errors(call):
    """Run ``call``; an InputError must be one line; anything else fails the test."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            call()
        except _errors() as exc:
            assert "\n" not in str(exc) and str(exc), repr(exc)


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    if not (MODELS / "arm_example.toml").is_file():
        pytest.skip("the bundled example model is not in this checkout")
    return tmp_path_factory.mktemp("fuzz")


# ----------------------------------------------------------------------------- TOML
_TOML_SEED = """model = "arm_example.osim"
motion = "elbow_flexion.mot"
units = "m"

[defaults]
fibres = 16
resolution = 6
frame = "ground"
rest_pose = { elbow_flexion = 0.0 }

[muscles.biceps]
action_lines = ["BIClong", "BICshort"]
template = "parallel"
mesh = "meshes/biceps.ply"
origin = { body = "humerus", file = "biceps_origin.csv" }
insertion = { body = "forearm", points = [[0.0, -0.1, 0.0], [0.001, -0.1, 0.0]], units = "m" }

[muscles.brachialis]
action_lines = ["BRA"]
template = "pennate"
template_params = { }
seed = 3
volume = 0.0001
bones = [{ body = "humerus", mesh = "meshes/humerus.stl" }]
"""
_KEYS = ["units", "defaults.fibres", "defaults.resolution", "defaults.frame", "defaults.rest_pose",
         "defaults.units", "muscles.biceps.action_lines", "muscles.biceps.template",
         "muscles.biceps.mesh", "muscles.biceps.origin", "muscles.biceps.insertion",
         "muscles.biceps.seed", "muscles.biceps.volume", "muscles.biceps.bones",
         "muscles.biceps.template_params", "muscles.brachialis.action_lines", "model", "motion"]

_scalars = st.one_of(st.integers(-2**63, 2**63 - 1), st.floats(allow_nan=True), st.booleans(),
                     st.text(max_size=12), st.sampled_from(["m", "mm", "humerus", "BRA", "parallel",
                                                            "../../../x", "meshes/biceps.ply"]))
_values = st.recursive(_scalars, lambda kids: st.one_of(
    st.lists(kids, max_size=4), st.dictionaries(st.sampled_from(
        ["body", "points", "file", "units", "where", "columns", "mesh", "x"]), kids, max_size=3)),
    max_leaves=8)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if v != v else ("inf" if v == float("inf") else "-inf" if v == -float("inf")
                                     else repr(v))
    if isinstance(v, str):
        return '"' + "".join(c if c.isprintable() and c not in '"\\' else f"\\u{ord(c):04x}"
                             for c in v) + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"


def _with_value(key: str, value) -> str:
    """The seed with ``key`` set to ``value`` (dotted keys in their table)."""
    *tables, name = key.split(".")
    line = f"{name} = {_toml_value(value)}\n"
    if not tables:
        return line + _TOML_SEED
    header = "[" + ".".join(tables) + "]\n"
    text = _TOML_SEED
    start = text.index(header) + len(header)
    body = [ln for ln in text[start:].split("\n[")[0].splitlines(True) if not ln.startswith(f"{name} =")]
    rest = text[start:][len(text[start:].split("\n[")[0]):]
    return text[:start] + line + "".join(body) + rest


@pytest.fixture(scope="module")
def toml_dir(work):
    import shutil

    folder = work / "toml"
    shutil.copytree(MODELS, folder, ignore=shutil.ignore_patterns("*.py", "__pycache__"))
    return folder


@pytest.fixture(scope="module")
def arm_model():
    import motion

    return motion.load_model(MODELS / "arm_example.osim")


def test_seed_toml_is_valid(toml_dir, arm_model):
    from analysis.spec import load_spec

    (toml_dir / "seed.toml").write_text(_TOML_SEED)
    assert load_spec(toml_dir / "seed.toml", model=arm_model).muscle_names == ("biceps", "brachialis")


@FUZZ
@given(data=st.one_of(mutated([_TOML_SEED.encode()]),
                      st.tuples(st.sampled_from(_KEYS), _values).map(
                          lambda kv: _with_value(*kv).encode("utf-8", "surrogatepass"))))
def test_fuzz_toml_loader(toml_dir, arm_model, data):
    from analysis.spec import load_spec

    path = toml_dir / "fuzz.toml"
    path.write_bytes(data)
    _only_input_errors(lambda: load_spec(path, model=arm_model))


# ----------------------------------------------------------------------------- motions
def _motion_seeds() -> list:
    v1 = (MODELS / "elbow_flexion.mot").read_bytes()
    v3 = (b"inDegrees=no\nDataType=double\nversion=3\nOpenSimVersion=4.6\nendheader\n"
          b"time\t/jointset/elbow/elbow_flexion/value\t/jointset/elbow/elbow_flexion/speed\n"
          + b"".join(b"%g\t%g\t0\n" % (0.1 * i, 0.1 * i) for i in range(8)))
    simm = (b"elbow\ndatacolumns 2\ndatarows 5\nrange 0 1\nendheader\ntime elbow_flexion\n"
            + b"".join(b"%g %g\n" % (0.25 * i, 10 * i) for i in range(5)))
    return [v1, v3, simm]


@FUZZ
@given(data=mutated(_motion_seeds()))
def test_fuzz_motion_reader(work, arm_model, data):
    import motion

    path = work / "fuzz.mot"
    path.write_bytes(data)
    _only_input_errors(lambda: motion.load_motion(path, arm_model))


# ----------------------------------------------------------------------------- models
@FUZZ
@given(data=mutated([(MODELS / "arm_example.osim").read_bytes()]))
def test_fuzz_model_reader(work, data):
    import motion

    path = work / "fuzz.osim"
    path.write_bytes(data)
    _only_input_errors(lambda: motion.load_model(path))


# ----------------------------------------------------------------------------- surfaces
def _surface_seeds():
    """A small closed surface (38 vertices) in every format and data mode we read."""
    import pyvista as pv
    import trimesh
    import vtk

    sphere = pv.Sphere(theta_resolution=8, phi_resolution=6).triangulate()
    v = np.asarray(sphere.points, dtype=float)
    f = np.asarray(sphere.faces).reshape(-1, 4)[:, 1:]
    tm = trimesh.Trimesh(v, f, process=False)
    seeds = {"stl": [tm.export(file_type="stl"), tm.export(file_type="stl_ascii").encode()],
             "obj": [tm.export(file_type="obj").encode()],
             "ply": [tm.export(file_type="ply", encoding="binary"),
                     tm.export(file_type="ply", encoding="ascii")],
             "vtk": [], "vtp": []}
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        for version, binary in ((51, True), (51, False), (42, True), (42, False)):
            w = vtk.vtkPolyDataWriter()
            w.SetInputData(sphere)
            w.SetFileVersion(version)
            w.SetFileTypeToBinary() if binary else w.SetFileTypeToASCII()
            w.SetFileName(f"{tmp}/s.vtk")
            w.Write()
            seeds["vtk"].append(Path(f"{tmp}/s.vtk").read_bytes())
        for mode, comp, enc in (("Binary", "zlib", True), ("Ascii", None, True),
                                ("Appended", None, False), ("Appended", "zlib", True),
                                ("Appended", "zlib", False)):
            w = vtk.vtkXMLPolyDataWriter()
            w.SetInputData(sphere)
            getattr(w, f"SetDataModeTo{mode}")()
            w.SetEncodeAppendedData(enc)
            w.SetCompressorTypeToZLib() if comp else w.SetCompressorTypeToNone()
            w.SetFileName(f"{tmp}/s.vtp")
            w.Write()
            seeds["vtp"].append(Path(f"{tmp}/s.vtp").read_bytes())
    return seeds


_SEEDS = {}


def _seeds(kind):
    if not _SEEDS:
        try:
            _SEEDS.update(_surface_seeds())
        except ImportError:  # pragma: no cover - pyvista/vtk absent
            pytest.skip("pyvista/vtk are needed to write the seed surfaces")
    return _SEEDS[kind]


@pytest.mark.parametrize("kind", ["stl", "obj", "ply", "vtk", "vtp"])
def test_fuzz_surface_readers(work, kind):
    from fibres import as_surface

    for seed in _seeds(kind):                              # the seeds themselves read cleanly
        path = work / f"seed.{kind}"
        path.write_bytes(seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert len(as_surface(path).faces) >= 60    # 72 (STL: float32 corners merge at the poles)

    @FUZZ
    @given(data=mutated(_seeds(kind)))
    def fuzz(data):
        path = work / f"fuzz.{kind}"
        path.write_bytes(data)
        _only_input_errors(lambda: as_surface(path))

    fuzz()
