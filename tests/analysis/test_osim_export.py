"""The fibre-resolved OpenSim model (`analysis.osim_export`, `fibres export-osim`, `fibres run
--osim`), checked in OpenSim 4.6 itself: the model loads, initSystem succeeds, each fibre muscle's
length and computeMomentArm over the motion match our fibre lengths and moment arms, and
AnalyzeTool's MuscleAnalysis runs on it."""
import json
from pathlib import Path

import numpy as np
import pytest

import analysis
from analysis.osim_export import export_osim, fibre_muscle_names
from analysis.spec import load_spec

ROOT = Path(__file__).resolve().parents[2]
ARM = ROOT / "models" / "arm_example.toml"
LHDL = ROOT / "tests" / "data" / "lhdl_hip.toml"

osim = pytest.importorskip("opensim")
pytestmark = [pytest.mark.oracle, pytest.mark.filterwarnings("ignore::UserWarning")]


def opensim_lengths_and_arms(osim_file, result):
    """Per muscle of ``result``: OpenSim's fibre-muscle lengths (F, N) and moment arms (F, N, C)."""
    model = osim.Model(str(osim_file))
    state = model.initSystem()
    cs = model.getCoordinateSet()
    out = {}
    for m in result.muscles:
        muscles = [model.getMuscles().get(n) for n in fibre_muscle_names(m.name, m.n_fibres)]
        coords = [cs.get(c) for c in m.coordinates]
        lengths = np.empty(m.fibre_lengths.shape)
        arms = np.empty(m.fibre_moment_arms.shape)
        for f in range(len(result.time)):
            for i, name in enumerate(result.coordinate_names):
                cs.get(name).setValue(state, float(result.q[f, i]), False)
            model.realizePosition(state)
            for k, mus in enumerate(muscles):
                lengths[f, k] = mus.getLength(state)
                for j, c in enumerate(coords):
                    arms[f, k, j] = mus.computeMomentArm(state, c)
        out[m.name] = (lengths, arms)
    return out


@pytest.fixture(scope="module")
def arm_export(tmp_path_factory):
    spec = load_spec(ARM)
    result = analysis.run(spec, fibres=12, keep_points=False)
    out = tmp_path_factory.mktemp("export") / "arm_fibres.osim"
    record = export_osim(spec, result, out)
    return spec, result, out, record


def test_exported_arm_matches_our_fibres_in_opensim(arm_export):
    spec, result, out, record = arm_export
    got = opensim_lengths_and_arms(out, result)
    for m in result.muscles:
        lengths, arms = got[m.name]
        dl = np.abs(lengths - m.fibre_lengths)
        dr = np.abs(arms - m.fibre_moment_arms)
        assert dl.max() < 5e-4, m.name                        # acceptance: 0.5 mm
        # OpenSim evaluates our polynomial: its errors are the fit's own, reported in the record
        rep = record["muscles"][m.name]
        np.testing.assert_allclose(dl.max(axis=0), rep["motion_length_max_m"], rtol=1e-3, atol=1e-9)
        np.testing.assert_allclose(dr.max(axis=(0, 2)), rep["motion_moment_arm_max_m"], rtol=1e-3, atol=1e-9)
        assert dr.max() < 1e-3, m.name                        # acceptance: 1 mm
        assert rep["within_tolerance"]
    # triceps: its action lines start to wrap the elbow cylinder at 56.7 and 58.2 deg (where
    # `motion.action_lines` gives them tangent points), a sharp bend in the fibre lengths that no
    # polynomial follows: one gate per line there, an ExpressionBasedFunction
    rep = record["muscles"]["triceps"]
    assert rep["length_function"] == "ExpressionBasedFunction"
    starts = sorted(np.degrees(g["active_from"]) for g in rep["gates"])
    np.testing.assert_allclose(starts, [56.74, 58.21], atol=0.05)
    assert record["muscles"]["biceps"]["length_function"] == "MultivariatePolynomialFunction"


def test_exported_model_structure(arm_export):
    spec, result, out, record = arm_export
    model = osim.Model(str(out))
    model.initSystem()
    names = [model.getForceSet().get(i).getName() for i in range(model.getForceSet().getSize())]
    for m in spec.muscles:
        for line in m.action_lines:
            assert line not in names                          # replaced
        fib = fibre_muscle_names(m.name, 12)
        assert all(n in names for n in fib)
        mus = model.getMuscles().get(fib[0])
        assert mus.getConcreteClassName() == "Thelen2003Muscle"
        assert mus.getPath().getConcreteClassName() == "FunctionBasedPath"
    # forces are an equal share of the action lines' total (biceps: BIClong 624.3 + BICshort 435.6 N)
    bic = model.getMuscles().get("biceps_fibre000")
    assert bic.getMaxIsometricForce() == pytest.approx((624.3 + 435.6) / 12)
    # optimal fibre length scales with the fibre's rest length
    rest = result.muscle("biceps").rest_lengths
    ratios = [model.getMuscles().get(n).getOptimalFiberLength() / r
              for n, r in zip(fibre_muscle_names("biceps", 12), rest)]
    np.testing.assert_allclose(ratios, ratios[0], rtol=1e-12)
    assert "biceps_fibre000" in json.dumps(record)


def test_muscle_class_and_keep_original(arm_export, tmp_path):
    spec, result, _, _ = arm_export
    out = tmp_path / "dgf.osim"
    export_osim(spec, result, out, muscles=["brachialis"], keep_original=True,
                muscle_class="DeGrooteFregly2016Muscle")
    model = osim.Model(str(out))
    model.initSystem()
    assert model.getMuscles().get("BRA").getConcreteClassName() == "Thelen2003Muscle"     # kept
    mus = model.getMuscles().get("brachialis_fibre003")
    assert mus.getConcreteClassName() == "DeGrooteFregly2016Muscle"
    assert mus.getMaxIsometricForce() == pytest.approx(987.3 / 12)


def test_muscle_analysis_runs_on_the_exported_model(arm_export, tmp_path):
    """AnalyzeTool + MuscleAnalysis (OpenSim's own tool) on the exported model: its Length table
    holds every fibre muscle and equals our fibre lengths within 0.5 mm."""
    spec, result, out, _ = arm_export
    tool = osim.AnalyzeTool()
    tool.setModelFilename(str(out))
    tool.setName("fibre_arm")
    tool.setCoordinatesFileName(str(spec.motion_path))
    tool.setInitialTime(0.0)
    tool.setFinalTime(float(result.time[-1]))
    tool.setResultsDir(str(tmp_path))
    ma = osim.MuscleAnalysis()
    ma.setComputeMoments(False)
    tool.getAnalysisSet().cloneAndAppend(ma)
    setup = tmp_path / "setup.xml"
    tool.printToXML(str(setup))
    assert osim.AnalyzeTool(str(setup)).run()
    table = osim.TimeSeriesTable(str(tmp_path / "fibre_arm_MuscleAnalysis_Length.sto"))
    labels = list(table.getColumnLabels())
    assert "biceps_fibre011" in labels and "BIClong" not in labels
    times = np.array(table.getIndependentColumn())
    col = table.getDependentColumn("biceps_fibre005").to_numpy()
    ours = np.interp(times, result.time, result.muscle("biceps").fibre_lengths[:, 5])
    # between frames the linear interpolation of ours differs from the smooth curve by < 0.1 mm
    assert np.abs(col - ours).max() < 5e-4


def test_cli_run_osim(tmp_path):
    from analysis.cli import main

    out = tmp_path / "run"
    code = main(["run", str(ARM), "--out", str(out), "--fibres", "6", "--frames", "::2", "--no-plots",
                 "--osim", "--quiet"])
    assert code == 0
    record = json.loads((out / "run.json").read_text())
    assert record["osim_export"]["file"] == "arm_example_fibres.osim"
    assert set(record["osim_export"]["muscles"]) == {"biceps", "brachialis", "triceps"}
    assert len(record["osim_export"]["muscles"]["biceps"]["order"]) == 6
    model = osim.Model(str(out / "arm_example_fibres.osim"))
    model.initSystem()
    assert model.getMuscles().getSize() == 18
    assert not any(p.name.startswith(".fibres-run-") for p in out.iterdir())


def test_cli_export_osim_bad_options(tmp_path, capsys):
    from analysis.cli import main

    assert main(["export-osim", str(ARM), "--max-order", "0"]) == 2
    assert "--max-order" in capsys.readouterr().err
    assert main(["export-osim", str(ARM), "--out", str(tmp_path / "x.txt")]) == 2
    assert ".osim" in capsys.readouterr().err


def test_cli_export_osim_unwritable_folder_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    """The export wrote its model only after minutes of fitting, and an unwritable folder then
    ended as an internal error (exit 1, PermissionError). The folder is read-only (0o555); the
    superuser, whom modes do not bind, is given the answer a user would get from os.access."""
    import os

    from analysis.cli import main

    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if Path(p) == folder and mode & os.W_OK
                        else real_access(p, mode, **kw))
    try:
        assert main(["export-osim", str(ARM), "--out", str(folder / "x.osim"), "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "not writable" in err[0] and str(folder) in err[0], err
        (tmp_path / "m.osim").mkdir()
        assert main(["export-osim", str(ARM), "--out", str(tmp_path / "m.osim"), "--quiet"]) == 2
        assert "is a folder" in capsys.readouterr().err
    finally:
        folder.chmod(0o755)


@pytest.mark.shared
@pytest.mark.slow
def test_lhdl_export_from_a_3x_model(tmp_path):
    """The LHDL hip model is an OpenSim 3.x file: OpenSim upgrades it and the fibres replace the
    action lines. Gluteus medius (smooth paths): OpenSim's fibre lengths match ours within 0.5 mm
    and its moment arms within 1 mm over the flexion task. Psoas: its action line has a
    ConditionalPathPoint that drops out at 40 degrees of flexion (a 0.96 mm step in the OpenSim
    path length), which the fibres inherit; no polynomial follows a step, so its fibres get an
    ExpressionBasedFunction (polynomial + a polynomial gated by the point's range): OpenSim then
    matches our lengths within 0.5 mm and moment arms within 1 mm on both sides of the step."""
    if not LHDL.is_file() or not (ROOT.parent / "shared" / "muscles" / "LHDL_hip_r").is_dir():
        pytest.skip("../shared/muscles/LHDL_hip_r is absent")
    spec = load_spec(LHDL)
    result = analysis.run(spec, fibres=4, muscles=["glut_med_r", "psoas_r"], frames="::5", keep_points=False)
    out = tmp_path / "lhdl_fibres.osim"
    record = export_osim(spec, result, out)
    got = opensim_lengths_and_arms(out, result)
    lengths, arms = got["glut_med_r"]
    m = result.muscle("glut_med_r")
    assert np.abs(lengths - m.fibre_lengths).max() < 5e-4
    assert np.abs(arms - m.fibre_moment_arms).max() < 1e-3
    lengths, arms = got["psoas_r"]
    m = result.muscle("psoas_r")
    assert np.abs(lengths - m.fibre_lengths).max() < 5e-4
    assert np.abs(arms - m.fibre_moment_arms).max() < 1e-3
    rep = record["muscles"]["psoas_r"]
    assert rep["length_function"] == "ExpressionBasedFunction"
    assert rep["gates"][0]["coordinate"] == "hip_flexion_r"
    assert rep["gates"][0]["active_to"] == pytest.approx(0.698132 + 1e-5)
    assert record["muscles"]["glut_med_r"]["length_function"] == "MultivariatePolynomialFunction"


def test_static_optimisation_runs_on_the_exported_arm(arm_export, tmp_path):
    """docs/OPENSIM_EXPORT.md's example: StaticOptimization with the fibre muscles alone (no reserve
    actuators) solves every frame of the bundled flexion (a quarter of it here)."""
    spec, result, out, _ = arm_export
    tool = osim.AnalyzeTool()
    tool.setModelFilename(str(out))
    tool.setName("arm_so")
    tool.setCoordinatesFileName(str(spec.motion_path))
    tool.setLowpassCutoffFrequency(6)
    tool.setInitialTime(0.0)
    tool.setFinalTime(0.3)
    tool.setResultsDir(str(tmp_path))
    so = osim.StaticOptimization()
    so.setUseModelForceSet(True)
    tool.getAnalysisSet().cloneAndAppend(so)
    tool.printToXML(str(tmp_path / "so_setup.xml"))
    assert osim.AnalyzeTool(str(tmp_path / "so_setup.xml")).run()
    table = osim.TimeSeriesTable(str(tmp_path / "arm_so_StaticOptimization_activation.sto"))
    assert table.getNumRows() >= 6
    labels = list(table.getColumnLabels())
    assert "triceps_fibre011" in labels
    acts = np.array([table.getDependentColumn(n).to_numpy() for n in labels])
    assert np.all(acts >= -1e-6) and np.all(acts <= 1 + 1e-6)


def test_4x_content_behind_a_30000_header_exports_as_4x(arm_export, tmp_path):
    """OpenSim 4.6 cannot load the arm relabelled Version="30000"; the export reads the content
    as 4.x (as our reader does) and writes Version="40000", which OpenSim loads."""
    import dataclasses

    spec, result, _, _ = arm_export
    relabelled = tmp_path / "arm30.osim"
    relabelled.write_text((ROOT / "models" / "arm_example.osim").read_text().replace(
        'Version="40000"', 'Version="30000"', 1))
    spec30 = dataclasses.replace(spec, model_path=relabelled)
    out = tmp_path / "arm30_fibres.osim"
    export_osim(spec30, result, out, muscles=["brachialis"])
    assert 'Version="40000"' in out.read_text()[:200]
    model = osim.Model(str(out))
    model.initSystem()
    assert model.getMuscles().get("brachialis_fibre000").getPath().getConcreteClassName() == "FunctionBasedPath"


def test_dangling_mentions_name_their_owner_and_count():
    """Rajagopal's ObjectGroups list every muscle: the warning said `<members> (vaslat_r)` four
    times without saying which group; it names the owner now, and how many it left out."""
    import warnings
    import xml.etree.ElementTree as ET

    from analysis.osim_export import ExportWarning, _warn_dangling

    groups = "".join(f'<ObjectGroup name="g{k}"><members> a vaslat_r b</members></ObjectGroup>' for k in range(7))
    model = ET.fromstring(f'<Model name="m"><ForceSet><groups>{groups}</groups></ForceSet></Model>')
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        _warn_dangling(model, ["vaslat_r"])
    (w,) = [w for w in seen if issubclass(w.category, ExportWarning)]
    text = str(w.message)
    assert "ObjectGroup 'g0' <members> (vaslat_r)" in text and "ObjectGroup 'g4'" in text
    assert "g5" not in text and "and 2 more" in text


def test_force_groups_name_the_fibre_muscles(arm_export, tmp_path):
    """A ForceSet ObjectGroup (Rajagopal's hip_flex_r, ...) that named a replaced action line names
    the muscle's fibre muscles in its place (beside it with keep_original), read back by OpenSim."""
    import dataclasses

    spec, result, _, _ = arm_export
    src = (ROOT / "models" / "arm_example.osim").read_text()
    tail = src.rindex("<groups />", 0, src.index("</ForceSet>"))
    grouped = tmp_path / "models" / "arm_grouped.osim"
    grouped.parent.mkdir()
    grouped.write_text(src[:tail] + '<groups><ObjectGroup name="elbow_flexors"><members> BIClong BRA BICshort'
                       '</members></ObjectGroup></groups>' + src[tail + len("<groups />"):])
    for name in ("meshes", "elbow_flexion.mot"):       # the model's relative files
        target = ROOT / "models" / name
        if target.exists():
            (tmp_path / "models" / name).symlink_to(target)
    spec = dataclasses.replace(spec, model_path=grouped)
    fibres = fibre_muscle_names("brachialis", 12)
    for keep, want in ((False, ["BIClong"] + fibres + ["BICshort"]),
                       (True, ["BIClong", "BRA"] + fibres + ["BICshort"])):
        out = tmp_path / f"grouped_{keep}.osim"
        export_osim(spec, result, out, muscles=["brachialis"], keep_original=keep)
        model = osim.Model(str(out))
        model.initSystem()
        group = model.getForceSet().getGroup("elbow_flexors")
        assert [group.getMembers().get(i).getName() for i in range(group.getMembers().getSize())] == want
