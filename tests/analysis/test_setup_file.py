"""``fibres run --setup SETUP.xml``: an AnalyzeTool setup written by OpenSim 4.6 itself runs beside
the fibre model and gives the same tables as the equivalent --motion/--frames/--muscle."""
from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from analysis.cli import main
from analysis.errors import InputError
from analysis.setup_file import SetupFileWarning, apply_setup, read_setup
from analysis.spec import load_spec

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / "models"
TABLE_FILES = ("fibre_lengths.csv", "fibre_moment_arms.csv", "action_lines.csv", "action_line_moment_arms.csv",
               "summary.csv")


def _opensim_setup(tmp_path, *, t0=0.2, t1=0.9, muscles=("BIClong", "BRA"), lowpass=-1.0, extra=False,
                   model=MODELS / "arm_example.osim"):
    osim = pytest.importorskip("opensim")
    tool = osim.AnalyzeTool()
    tool.setName("arm_ma")
    tool.setModelFilename(str(model))
    tool.setCoordinatesFileName(str(MODELS / "elbow_flexion.mot"))
    tool.setInitialTime(t0)
    tool.setFinalTime(t1)
    tool.setLowpassCutoffFrequency(lowpass)
    tool.setResultsDir("results")
    ma = osim.MuscleAnalysis()
    names = osim.ArrayStr()
    for n in muscles:
        names.append(n)
    ma.setMuscles(names)
    ma.setComputeMoments(False)
    tool.getAnalysisSet().cloneAndAppend(ma)
    if extra:
        tool.getAnalysisSet().cloneAndAppend(osim.StaticOptimization())
    path = tmp_path / "setup.xml"
    tool.printToXML(str(path))
    return path


@pytest.mark.oracle
def test_setup_gives_the_same_tables_as_motion_and_frames(tmp_path, capsys):
    setup = _opensim_setup(tmp_path)
    common = [str(MODELS / "arm_example.toml"), "--fibres", "8", "--resolution", "6", "--no-plots", "--quiet"]
    assert main(["run", *common, "--setup", str(setup), "--out", str(tmp_path / "a")]) == 0, capsys.readouterr().err
    # 0.2 .. 0.9 s of a 0.05 s motion: rows 4..18; BIClong drives biceps, BRA brachialis
    assert main(["run", *common, "--motion", str(MODELS / "elbow_flexion.mot"), "--frames", "4:19",
                 "--muscle", "biceps", "--muscle", "brachialis", "--out", str(tmp_path / "b")]) == 0
    for name in TABLE_FILES:
        a = (tmp_path / "a" / name).read_text()
        assert a == (tmp_path / "b" / name).read_text(), name
    assert "triceps" not in (tmp_path / "a" / "fibre_lengths.csv").read_text()
    import json

    record = json.loads((tmp_path / "a" / "run.json").read_text())
    assert record["inputs"]["setup"]["path"] == str(setup.resolve())
    assert capsys.readouterr().err == ""        # nothing unsupported in this setup


@pytest.mark.oracle
def test_unsupported_parts_are_named_in_one_warning(tmp_path):
    setup = _opensim_setup(tmp_path, lowpass=6.0, extra=True, muscles=("BIClong", "nosuch"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plan = apply_setup(read_setup(setup), load_spec(MODELS / "arm_example.toml"))
    ours = [w for w in caught if issubclass(w.category, SetupFileWarning)]
    assert len(ours) == 1
    msg = str(ours[0].message)
    assert "lowpass" in msg and "StaticOptimization" in msg and "nosuch" in msg
    assert plan["muscles"] == ["biceps"] and plan["frames"].tolist() == list(range(4, 19))


def test_setup_errors(tmp_path, capsys):
    text = (MODELS / "arm_example.osim").read_text()
    other = tmp_path / "other.osim"
    other.write_text(text.replace("624.3", "600"))
    setup = tmp_path / "s.xml"
    setup.write_text(f"""<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40600"><AnalyzeTool name="x">
<model_file>{other}</model_file><coordinates_file>{MODELS / 'elbow_flexion.mot'}</coordinates_file>
<initial_time>0</initial_time><final_time>1</final_time></AnalyzeTool></OpenSimDocument>""")
    spec = load_spec(MODELS / "arm_example.toml")
    with pytest.raises(InputError, match="model_file"):
        apply_setup(read_setup(setup), spec)
    # the same content under another name is the same model; a time range outside the motion is not
    same = tmp_path / "same.osim"
    same.write_text(text)
    setup.write_text(setup.read_text().replace(str(other), str(same)).replace("<initial_time>0", "<initial_time>5")
                     .replace("<final_time>1", "<final_time>6"))
    with pytest.raises(InputError, match="no motion row lies between"):
        apply_setup(read_setup(setup), spec)
    not_tool = tmp_path / "n.xml"
    not_tool.write_text('<OpenSimDocument Version="40600"><InverseKinematicsTool/></OpenSimDocument>')
    with pytest.raises(InputError, match="no <AnalyzeTool>"):
        read_setup(not_tool)
    code = main(["run", str(MODELS / "arm_example.toml"), "--setup", str(setup), "--frames", "0:2",
                 "--out", str(tmp_path / "o")])
    assert code == 2 and "--setup" in capsys.readouterr().err and not (tmp_path / "o").exists()
