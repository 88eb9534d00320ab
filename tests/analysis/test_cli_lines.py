"""`fibres lines`: --frames, the long tables, end-to-end against OpenSim 4.6, and every bad input."""
from __future__ import annotations

import argparse

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.frames_option import parse_frames, resolve_frames
from analysis.lines_tables import action_lines_table, body_poses_table, moment_arms_table

# ------------------------------------------------------------------ --frames


@pytest.mark.parametrize("text, n, expected", [
    ("0:10:2", 20, [0, 2, 4, 6, 8]),
    ("::5", 12, [0, 5, 10]),
    ("7:", 10, [7, 8, 9]),
    (":3", 10, [0, 1, 2]),
    ("4", 10, [4]),
    ("0:10", 10, list(range(10))),
    (":", 3, [0, 1, 2]),
])
def test_frames_select_python_slices(text, n, expected):
    got = resolve_frames(parse_frames(text), n)
    np.testing.assert_array_equal(got, expected)
    # the same rows as Python's own slice of range(n)
    parts = (text.split(":") + ["", ""])[:3] if ":" in text else [text, str(int(text) + 1), ""]
    ref = list(range(n))[slice(*[int(p) if p else None for p in parts])]
    assert list(got) == ref


@pytest.mark.parametrize("text", ["", "a:b", "1:2:3:4", "5:2", "0:10:0", "-1:", "1.5:", ":"*4])
def test_frames_bad_syntax_is_a_usage_error(text):
    with pytest.raises(argparse.ArgumentTypeError, match="--frames"):
        parse_frames(text)


@pytest.mark.parametrize("text, word", [("10:", "START 10"), ("0:11", "STOP 11"), ("10", "START 10")])
def test_frames_out_of_range_names_valid_range(text, word):
    with pytest.raises(InputError) as info:
        resolve_frames(parse_frames(text), 10, source="walk.mot")
    message = str(info.value)
    assert message.startswith("walk.mot: --frames")
    assert word in message and "0 to 9" in message and "1 to 10" in message
    assert "\n" not in message


def test_frames_none_is_all():
    np.testing.assert_array_equal(resolve_frames(None, 4), [0, 1, 2, 3])


# ------------------------------------------------------------------ long tables


def test_body_poses_table_layout():
    rng = np.random.default_rng(0)
    tf = rng.normal(size=(3, 2, 4, 4))
    table = body_poses_table([0.0, 0.1, 0.2], tf, ["ground", "femur"])
    assert list(table.columns) == ["frame", "time", "body", "tx", "ty", "tz",
                                   "r00", "r01", "r02", "r10", "r11", "r12", "r20", "r21", "r22"]
    assert len(table) == 6
    row = table.iloc[3]  # frame 1, femur
    assert (row.frame, row.time, row.body) == (1, 0.1, "femur")
    np.testing.assert_array_equal(row[["tx", "ty", "tz"]].to_numpy(float), tf[1, 1, :3, 3])
    np.testing.assert_array_equal(row[[f"r{i}{j}" for i in range(3) for j in range(3)]]
                                  .to_numpy(float), tf[1, 1, :3, :3].reshape(-1))


def test_action_lines_table_layout():
    lengths = np.arange(6.0).reshape(2, 3)
    table = action_lines_table([0.0, 1.0], lengths, ["a", "b", "c"], frames=[5, 6])
    assert list(table.columns) == ["frame", "time", "muscle", "length"]
    assert table.frame.tolist() == [5, 5, 5, 6, 6, 6]
    assert table.muscle.tolist() == ["a", "b", "c"] * 2
    np.testing.assert_array_equal(table.length, lengths.reshape(-1))
    with_lines = action_lines_table([0.0, 1.0], lengths, ["m", "m", "n"],
                                    action_lines=["a", "b", "c"])
    assert list(with_lines.columns) == ["frame", "time", "muscle", "action_line", "length"]


def test_moment_arms_table_keeps_only_spanned_pairs():
    arms = np.arange(2 * 2 * 3, dtype=float).reshape(2, 2, 3)
    spanned = np.array([[True, False, True], [False, True, False]])
    table = moment_arms_table([0.0, 1.0], arms, spanned, ["a", "b"], ["q0", "q1", "q2"])
    assert list(table.columns) == ["frame", "time", "muscle", "coordinate", "moment_arm"]
    assert len(table) == 2 * 3
    assert list(zip(table.muscle, table.coordinate))[:3] == [("a", "q0"), ("a", "q2"), ("b", "q1")]
    expected = [arms[f, m, c] for f in range(2) for m, c in [(0, 0), (0, 2), (1, 1)]]
    np.testing.assert_array_equal(table.moment_arm, expected)


def test_tables_check_shapes():
    with pytest.raises(ValueError, match=r"\(F, M\)"):
        action_lines_table([0.0], np.zeros((2, 1)), ["a"])
    with pytest.raises(ValueError, match=r"\(F, B, 4, 4\)"):
        body_poses_table([0.0], np.zeros((1, 2, 3, 4)), ["a", "b"])
    with pytest.raises(ValueError, match="spanned"):
        moment_arms_table([0.0], np.zeros((1, 1, 2)), np.zeros((2, 1), bool), ["a"], ["x", "y"])
