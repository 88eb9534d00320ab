"""Parquet tables equal the CSVs; the .sto files (on by default, MuscleAnalysis names) load in
OpenSim's TimeSeriesTable with the run's numbers; the per-fibre .sto option."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis import cli_run
from analysis.tables import TABLES

from test_run_tables import _result


@pytest.fixture
def written(tmp_path):
    res = _result(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    cli_run.write_outputs(res, out, plots=False, vtk=False, sto_fibres=True)
    return res, out


def test_every_table_has_an_equal_parquet(written):
    res, out = written
    for name in TABLES:
        csv = pd.read_csv(out / name, keep_default_na=False)
        pq = pd.read_parquet(out / name.replace(".csv", ".parquet"))
        assert list(pq.columns) == list(csv.columns) and len(pq) == len(csv), name
        for col in csv.columns:
            if pq[col].dtype.kind == "f":
                # the CSV holds 12 significant digits, the Parquet full float64
                # (an empty CSV cell is a NaN: normalized_length without l_opt, a quality share
                # of an empty patch)
                values = pd.to_numeric(csv[col].replace("", np.nan)).to_numpy(float)
                np.testing.assert_allclose(values, pq[col].to_numpy(), rtol=1e-11, atol=0)
            else:
                assert csv[col].astype(str).tolist() == pq[col].astype(str).tolist(), (name, col)
    # and the Parquet is exact: the fibre lengths of muscle a, frame by frame
    pq = pd.read_parquet(out / "fibre_lengths.parquet")
    a = pq[pq.muscle == "a"].pivot(index="frame", columns="fibre", values="length").to_numpy()
    np.testing.assert_array_equal(a, res.muscle("a").fibre_lengths)


def test_sto_files_by_default_and_per_fibre(written):
    res, out = written
    names = {p.name for p in out.glob("*.sto")}
    assert {"MuscleAnalysis_Length.sto", "MuscleAnalysis_MomentArm_q1.sto", "MuscleAnalysis_MomentArm_q2.sto",
            "FibreAnalysis_Length.sto", "FibreAnalysis_a_Length.sto", "FibreAnalysis_a_MomentArm_q2.sto",
            "FibreAnalysis_b_MomentArm_q2.sto"} <= names


@pytest.mark.oracle
def test_sto_files_load_in_opensim(written):
    osim = pytest.importorskip("opensim")
    res, out = written
    t = osim.TimeSeriesTable(str(out / "MuscleAnalysis_Length.sto"))
    assert list(t.getColumnLabels()) == ["l1", "l2", "l3"]
    np.testing.assert_allclose(np.array(t.getIndependentColumn()), res.time, rtol=1e-12)
    np.testing.assert_allclose(t.getDependentColumn("l3").to_numpy(), res.muscle("b").action_line_lengths[:, 0],
                               rtol=1e-9)
    f = osim.TimeSeriesTable(str(out / "FibreAnalysis_a_MomentArm_q1.sto"))
    assert list(f.getColumnLabels()) == [f"a_fibre{k:03d}" for k in range(6)]
    np.testing.assert_allclose(f.getDependentColumn("a_fibre004").to_numpy(),
                               res.muscle("a").fibre_moment_arms[:, 4, 0], rtol=1e-9)
    s = osim.TimeSeriesTable(str(out / "FibreAnalysis_Length.sto"))
    np.testing.assert_allclose(s.getDependentColumn("a_median").to_numpy(),
                               np.median(res.muscle("a").fibre_lengths, axis=1), rtol=1e-9)


def test_no_sto_option(tmp_path):
    from analysis.cli import build_parser

    args = build_parser().parse_args(["run", "--no-sto"])
    assert args.sto is False and build_parser().parse_args(["run"]).sto is True
    res = _result(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    cli_run.write_outputs(res, out, plots=False, vtk=False, sto=False)
    assert not list(out.glob("*.sto")) and (out / "summary.parquet").is_file()
