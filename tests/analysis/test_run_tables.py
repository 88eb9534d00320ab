"""Tables, summary, run.json and staged output writing of `fibres run`, on a synthetic RunResult
whose numbers are known (so every statistic is checked against numpy directly)."""
from __future__ import annotations

import hashlib
import json

import numpy as np
import pandas as pd
import pytest

from analysis import cli_run
from analysis.result import MuscleResult, RunResult
from analysis.run import fibre_lengths
from analysis.tables import TABLES, summary_table


def _result(tmp_path=None):
    rng = np.random.default_rng(7)
    n_f, n_n = 4, 6
    a = MuscleResult("a", ("q1", "q2"), 0.1 + rng.random((n_f, n_n)) / 3, rng.normal(size=(n_f, n_n, 2)) / 50,
                     ("l1", "l2"), 0.1 + rng.random((n_f, 2)), rng.normal(size=(n_f, 2, 2)) / 50,
                     0.1 + rng.random(n_n), fibre_points=rng.random((n_f, n_n, 5, 3)))
    b = MuscleResult("b", ("q2",), 0.2 + rng.random((n_f, 3)), rng.normal(size=(n_f, 3, 1)),
                     ("l3",), 0.2 + rng.random((n_f, 1)), rng.normal(size=(n_f, 1, 1)), np.ones(3))
    inputs = {}
    if tmp_path is not None:
        (tmp_path / "in.toml").write_text("model = 'x'\n")
        inputs["spec"] = tmp_path / "in.toml"
    return RunResult(time=np.linspace(0.0, 0.3, n_f), frames=np.arange(2, 2 + n_f), coordinate_names=("q1", "q2"),
                     q=rng.random((n_f, 2)), muscles=(a, b), timings={"wrap": 0.5}, settings={"fibres": 6},
                     inputs=inputs)


def test_columns_and_rows_are_the_contract():
    res = _result()
    want = {
        "fibre_lengths.csv": ["frame", "time", "muscle", "fibre", "length", "normalized_length"],
        "fibre_moment_arms.csv": ["frame", "time", "muscle", "fibre", "coordinate", "moment_arm"],
        "action_lines.csv": ["frame", "time", "muscle", "action_line", "length"],
        "action_line_moment_arms.csv": ["frame", "time", "muscle", "action_line", "coordinate", "moment_arm"],
    }
    rows = {"fibre_lengths.csv": 4 * 6 + 4 * 3, "fibre_moment_arms.csv": 4 * 6 * 2 + 4 * 3,
            "action_lines.csv": 4 * 2 + 4, "action_line_moment_arms.csv": 4 * 2 * 2 + 4}
    for name, cols in want.items():
        df = TABLES[name](res)
        assert list(df.columns) == cols and len(df) == rows[name]
    fl = TABLES["fibre_lengths.csv"](res)
    a = res.muscle("a")
    # every value lands on its (frame, fibre): pivot back and compare with the array
    piv = fl[fl.muscle == "a"].pivot(index="frame", columns="fibre", values="length").to_numpy()
    np.testing.assert_array_equal(piv, a.fibre_lengths)
    fr = TABLES["fibre_moment_arms.csv"](res)
    sel = fr[(fr.muscle == "a") & (fr.coordinate == "q2")]
    np.testing.assert_array_equal(sel.pivot(index="frame", columns="fibre", values="moment_arm"),
                                  a.fibre_moment_arms[:, :, 1])
    np.testing.assert_array_equal(fl.time.unique(), res.time)   # frame is 0..F-1 with the motion's time
    assert fl.frame.max() == 3


def test_summary_statistics_match_numpy():
    res = _result()
    s = summary_table(res)
    a = res.muscle("a")
    # rows: per frame: a length, a normalized_length, a q1, a q2, b length, b normalized_length, b q2
    assert len(s) == 4 * 7
    row = s[(s.frame == 2) & (s.muscle == "a") & (s.quantity == "moment_arm") & (s.coordinate == "q1")].iloc[0]
    v = a.fibre_moment_arms[2, :, 0]
    assert row["mean"] == pytest.approx(v.mean()) and row["std"] == pytest.approx(v.std())
    assert row["p5"] == pytest.approx(np.percentile(v, 5)) and row["median"] == pytest.approx(np.median(v))
    assert row["min"] == v.min() and row["max"] == v.max() and row["n_fibres"] == 6
    al = a.action_line_moment_arms[2, :, 0]
    assert row["action_line_min"] == al.min() and row["action_line_max"] == al.max()
    assert row["action_line_values"] == f"l1={al[0]:.12g};l2={al[1]:.12g}"
    row = s[(s.frame == 0) & (s.muscle == "b") & (s.quantity == "length")].iloc[0]
    assert row["coordinate"] == "" or pd.isna(row["coordinate"])
    assert row["p95"] == pytest.approx(np.percentile(res.muscle("b").fibre_lengths[0], 95))


def test_to_frame_holds_every_number():
    res = _result()
    df = res.to_frame()
    n = sum(2 * m.fibre_lengths.size + m.fibre_moment_arms.size + m.action_line_lengths.size
            + m.action_line_moment_arms.size for m in res.muscles)     # lengths and normalized lengths
    assert len(df) == n
    total = sum(m.fibre_lengths.sum() + m.fibre_moment_arms.sum() + m.action_line_lengths.sum()
                + m.action_line_moment_arms.sum() for m in res.muscles)
    assert df.value.sum() == pytest.approx(total, rel=1e-12)     # no l_opt here: normalized are NaN


def test_normalized_length_is_length_over_optimal_length():
    res = _result()
    a = res.muscle("a")
    opt = np.linspace(0.1, 0.2, a.n_fibres)
    line_norm = np.full(a.action_line_lengths.shape, 0.9)
    a2 = MuscleResult(a.name, a.coordinates, a.fibre_lengths, a.fibre_moment_arms, a.action_lines,
                      a.action_line_lengths, a.action_line_moment_arms, a.rest_lengths,
                      optimal_lengths=opt, line_normalized_lengths=line_norm)
    res2 = RunResult(time=res.time, frames=res.frames, coordinate_names=res.coordinate_names, q=res.q,
                     muscles=(a2, res.muscle("b")), timings={}, settings={}, inputs={})
    fl = TABLES["fibre_lengths.csv"](res2)
    piv = fl[fl.muscle == "a"].pivot(index="frame", columns="fibre", values="normalized_length").to_numpy()
    np.testing.assert_allclose(piv, a.fibre_lengths / opt[None], rtol=1e-15)
    assert fl[fl.muscle == "b"].normalized_length.isna().all()
    s = summary_table(res2)
    row = s[(s.frame == 1) & (s.muscle == "a") & (s.quantity == "normalized_length")].iloc[0]
    assert row["median"] == pytest.approx(np.median(a.fibre_lengths[1] / opt))
    assert row["action_line_mean"] == pytest.approx(0.9)


def test_fibre_lengths_is_polyline_arc_length():
    # a quarter circle of radius 2 sampled at 1001 points: chord sum -> pi (1 - O(1/n^2))
    t = np.linspace(0, np.pi / 2, 1001)
    pts = np.stack([2 * np.cos(t), 2 * np.sin(t), 0 * t], -1)[None]
    assert fibre_lengths(pts)[0] == pytest.approx(np.pi, rel=1e-6)


def test_outputs_are_written_with_precision_and_run_json(tmp_path):
    res = _result(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    cli_run.write_outputs(res, out, plots=True, vtk=True, sto=True)
    assert (out / "plots" / "a_moment_arms.png").stat().st_size > 1000
    pv = pytest.importorskip("pyvista")
    files = sorted((out / "fibres").glob("a_*.vtp"))
    assert (out / "fibres" / "a.pvd").is_file() and len(files) == 4
    poly = pv.read(files[2])
    assert poly.n_cells == 6 and list(poly.cell_data["fibre"]) == list(range(6))
    np.testing.assert_allclose(poly.points.reshape(6, 5, 3), res.muscle("a").fibre_points[2], rtol=1e-6)
    back = pd.read_csv(out / "fibre_lengths.csv")
    np.testing.assert_allclose(back[back.muscle == "a"].length.to_numpy(), res.muscle("a").fibre_lengths.ravel(),
                               rtol=1e-11)   # written with 12 significant digits
    record = json.loads((out / "run.json").read_text())
    assert record["inputs"]["spec"]["sha256"] == hashlib.sha256((tmp_path / "in.toml").read_bytes()).hexdigest()
    assert record["versions"]["numpy"] == np.__version__
    assert record["timings_s"]["wrap"] == 0.5 and "write_tables" in record["timings_s"]
    assert (out / "MuscleAnalysis_Length.sto").is_file() and (out / "FibreAnalysis_MomentArm_q2.sto").is_file()
    assert not [p for p in out.iterdir() if p.name.startswith(".")]   # staging removed


def test_interrupt_while_writing_leaves_no_file_and_rerun_works(tmp_path, monkeypatch):
    res = _result(tmp_path)
    out = tmp_path / "out"
    out.mkdir()

    def boom(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_run, "write_sto_files", boom)      # after the tables were written
    with pytest.raises(KeyboardInterrupt):
        cli_run.write_outputs(res, out, plots=False, vtk=False, sto=True)
    assert list(out.iterdir()) == []
    monkeypatch.undo()
    cli_run.write_outputs(res, out, plots=False, vtk=False, sto=True)
    assert (out / "summary.csv").is_file() and (out / "run.json").is_file()


def test_difference_quotients_go_one_sided_across_a_conditional_point_switch():
    import importlib

    mod = importlib.import_module("analysis.fibre_moment_arms")
    h = 1e-4
    q = np.array([0.3, 0.5, 0.7])                       # a point switches off just above q = 0.5
    length = lambda x: 0.2 - 0.03 * x + 0.01 * x ** 2 + np.where(x > 0.5 + 5e-5, 0.004, 0.0)  # noqa: E731
    base = length(q)[:, None]
    plus = length(q + h)[None, :, None]
    minus = length(q - h)[None, :, None]
    switch_plus = np.array([[False, True, False]])
    switch_minus = np.zeros((1, 3), dtype=bool)
    r = mod.difference_quotients(base, plus, minus, np.array([h]), switch_plus, switch_minus)[:, 0, 0]
    exact = 0.03 - 0.02 * q                              # -dL/dq of the smooth part
    # central where nothing switches (error h^2 L'''/6 = 0), backward at the switch (error h/2 * 0.02)
    np.testing.assert_allclose(r, exact, atol=2e-6)
    central = -(plus - minus)[0, :, 0] / (2 * h)
    assert abs(central[1] - exact[1]) > 10.0             # what a central difference would give


def test_tables_written_muscle_by_muscle_equal_the_whole_table(tmp_path):
    """`write_tables` appends the per-fibre tables one muscle at a time (bounded memory): the
    CSV text and the Parquet contents are those of the table built at once, also with a muscle
    that spans no coordinate (no moment-arm rows) in the middle."""
    import dataclasses

    import pandas as pd

    from analysis.csv_text import csv_bytes
    from analysis.tables import PER_MUSCLE, write_tables

    res = _result()
    a, b = res.muscles
    none = dataclasses.replace(b, name="c", coordinates=(), fibre_moment_arms=np.zeros((4, 3, 0)),
                               action_line_moment_arms=np.zeros((4, 1, 0)))
    res = dataclasses.replace(res, muscles=(a, none, b))
    write_tables(res, tmp_path)
    for name in PER_MUSCLE:
        whole = TABLES[name](res)
        written = (tmp_path / name).read_text()
        assert written == csv_bytes(whole).decode()
        back = pd.read_parquet(tmp_path / name.replace(".csv", ".parquet"))
        pd.testing.assert_frame_equal(back, whole.reset_index(drop=True), check_dtype=False)


@pytest.mark.parametrize("order", ["none first", "none between"])
def test_tables_streamed_during_the_run_equal_the_whole_table(tmp_path, order):
    """`TableStreams` (muscles added as a run finishes them, then `write_tables(streamed=)`)
    writes the same CSV text and Parquet contents as the tables built at once, also when the
    first muscle spans no coordinate (its empty moment-arm part gives the header only)."""
    import dataclasses

    from analysis.csv_text import csv_bytes
    from analysis.tables import PER_MUSCLE, TableStreams, write_tables

    res = _result()
    a, b = res.muscles
    none = dataclasses.replace(b, name="c", coordinates=(), fibre_moment_arms=np.zeros((4, 3, 0)),
                               action_line_moment_arms=np.zeros((4, 1, 0)))
    res = dataclasses.replace(res, muscles=(none, a, b) if order == "none first" else (a, none, b))
    streams = TableStreams(tmp_path)
    for m in res.muscles:
        streams.add(res.time, m)
    paths = write_tables(res, tmp_path, streamed=streams)
    assert {p.name for p in paths} == {f"{n[:-4]}.{ext}" for n in TABLES for ext in ("csv", "parquet")}
    for name in PER_MUSCLE:
        whole = TABLES[name](res)
        assert (tmp_path / name).read_text() == csv_bytes(whole).decode()
        back = pd.read_parquet(tmp_path / name.replace(".csv", ".parquet"))
        pd.testing.assert_frame_equal(back, whole.reset_index(drop=True), check_dtype=False)


def test_aborted_table_streams_put_no_file_in_place(tmp_path):
    """Outside a staging folder the streams write temporary files: ``abort()`` removes them and
    no table appears."""
    from analysis.tables import TableStreams

    res = _result()
    streams = TableStreams(tmp_path)
    streams.add(res.time, res.muscles[0])
    streams.abort()
    assert list(tmp_path.iterdir()) == []
