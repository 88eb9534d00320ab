"""`analysis.csv_text`: the CSV text of the tables against pandas' ``to_csv`` and Python's csv."""
import csv
import io

import numpy as np
import pandas as pd
import pytest

from analysis.csv_text import DIGITS, csv_bytes


def _table(n=500, seed=3):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=n) * 10.0 ** rng.integers(-9, 9, size=n)
    x[::17] = np.nan
    x[5] = 0.0
    x[6] = -1e-13          # below 1e-11: written as is
    x[7] = 1e30
    names = np.array(["glut_med1_r", "a,b", 'say "hi"', "", "line\nbreak", "é"], dtype=object)
    return pd.DataFrame({"frame": np.arange(n) // 10, "time": np.repeat(np.linspace(0.5, 4.0, n // 10), 10),
                         "muscle": names[np.arange(n) % len(names)], "value": x,
                         "flag": np.arange(n) % 3 == 0})


def test_values_read_back_within_the_digits_and_fields_as_pandas_writes_them():
    df = _table()
    text = csv_bytes(df).decode()
    back = pd.read_csv(io.StringIO(text), keep_default_na=False, na_values=[""])
    ref = pd.read_csv(io.StringIO(df.to_csv(index=False, float_format="%.12g")), keep_default_na=False,
                      na_values=[""])
    assert list(back.columns) == list(df.columns)
    pd.testing.assert_series_equal(back["frame"], ref["frame"])
    pd.testing.assert_series_equal(back["muscle"], ref["muscle"])
    pd.testing.assert_series_equal(back["flag"], ref["flag"])
    v, want = back["value"].to_numpy(), df["value"].to_numpy()
    assert np.array_equal(np.isnan(v), np.isnan(want))
    ok = ~np.isnan(want)
    # 12 significant digits: half a unit of the 12th digit, plus the rounding of x 10^d
    np.testing.assert_allclose(v[ok], want[ok], rtol=0.51 * 10.0 ** (1 - DIGITS) + 1e-15, atol=0)
    assert v[6] == -1e-13 and v[5] == 0.0
    # at most DIGITS significant digits per number (a tiny value is written as is)
    for field in (row[3] for row in csv.reader(io.StringIO(text)) if row and row[3] not in ("", "value")):
        mantissa = field.lstrip("-").split("e")[0].replace(".", "").lstrip("0")
        assert len(mantissa) <= DIGITS or abs(float(field)) < 1e-11, field


def test_quoting_is_minimal_and_round_trips():
    df = _table(60)
    text = csv_bytes(df).decode()
    rows = list(csv.reader(io.StringIO(text)))
    assert rows[0] == list(df.columns)
    assert [r[2] for r in rows[1:]] == list(df["muscle"])
    assert '"glut_med1_r"' not in text and '"a,b"' in text and '"say ""hi"""' in text
    assert text.splitlines()[0] == "frame,time,muscle,value,flag"


def test_empty_table_is_the_header_and_objects_fall_back_to_pandas():
    assert csv_bytes(pd.DataFrame({"a": [], "b": []})) == b"a,b\n"
    odd = pd.DataFrame({"a": [1.0, 2.5], "obj": [{"x": 1}, [2]]})
    text = csv_bytes(odd).decode()
    assert text == odd.to_csv(index=False, float_format="%.12g", lineterminator="\n")


@pytest.mark.parametrize("x,text", [(1.5, "1.5"), (2 / 3, "0.666666666667"), (12.0, "12"), (-3.25e22, "-3.25e+22"),
                                    (0.1 + 0.2, "0.3")])
def test_numbers(x, text):
    assert csv_bytes(pd.DataFrame({"v": [x]}), header=False).decode() == text + "\n"


def test_missing_values_in_repeated_columns_keep_their_rows():
    """The LHDL hip run (its optimal_fiber_length unread: normalized_length all NaN) wrote a
    fibre_lengths.csv of its header alone: a float column of few distinct values over more than
    64 rows was formatted per distinct value, and its missing values (nulls in Arrow) made whole
    lines null, which the join dropped."""
    n = 400
    frame = pd.DataFrame({
        "frame": np.repeat(np.arange(4), n // 4),
        "length": np.linspace(0.1, 0.2, n),
        "normalized_length": np.full(n, np.nan),                       # all missing, one value
        "mixed": np.where(np.arange(n) % 3 == 0, np.nan, np.arange(n) % 2 + 0.5),   # few values + NaN
    })
    text = csv_bytes(frame).decode()
    rows = list(csv.reader(io.StringIO(text)))
    assert rows[0] == list(frame.columns) and len(rows) == n + 1
    assert all(r[2] == "" for r in rows[1:])
    expected = ["" if np.isnan(v) else repr(float(v)) for v in frame["mixed"]]
    assert [r[3] for r in rows[1:]] == expected
    back = pd.read_csv(io.StringIO(text))
    np.testing.assert_allclose(back["length"], frame["length"], rtol=5e-12)   # 12 significant digits
