"""CSV text of the toolkit's tables, formatted by pyarrow's compute kernels instead of pandas.

The contract (docs/INTERFACE.md): a header row, ``,`` between fields, ``.`` decimal, no index
column, numbers with ``DIGITS`` (12) significant digits, missing values (NaN, None) as empty
fields. Strings are quoted only where they must be (a ``,``, ``"``, ``\\n`` or ``\\r`` in them;
quotes doubled, as pandas' and Python's ``csv.QUOTE_MINIMAL``), booleans are ``True`` /
``False``, integers plain.

Method. A float is first rounded to ``DIGITS`` significant digits in binary,
``rint(x 10^d) / 10^d`` with ``d = DIGITS - 1 - floor(log10 |x|)``: the integer ``rint(...)`` is
exact and an IEEE division is correctly rounded, so the result is the double nearest to the
decimal of ``DIGITS`` digits, whose shortest round-trip text (what Arrow's float-to-string cast
writes, the Grisu/Ryu "shortest" representation of Steele & White / Loitsch 2010) is that
decimal. For ``|x| < 10^-11`` (``d > 22``, where ``10^d`` is no longer exact) the value is written
as is, with up to 17 digits. The text therefore differs from ``%.12g`` only in the spelling of
the exponent (``1e-07`` there, ``1e-7`` here; every CSV reader takes both) and in trailing
zeros that ``%g`` drops as well. The fields are then joined row by row
(``binary_join_element_wise``) and the lines written as one buffer (timings against
``DataFrame.to_csv(float_format="%.12g")``: bench/README.md).

Not `pyarrow.csv.write_csv`: its least quoting style ("needed") still quotes every string
field, and the contract's text quotes only the fields that need it.

Tables with a column of another type (dates, nested values, Python objects that are not
strings) fall back to pandas' ``to_csv`` with ``%.12g``.
"""
from __future__ import annotations

import numpy as np

__all__ = ["DIGITS", "arrow_table", "csv_bytes", "write_csv_part"]

#: significant digits of the numbers in every CSV table
DIGITS = 12


def _rounded(x: np.ndarray, digits: int) -> np.ndarray:
    """``x`` rounded to ``digits`` significant digits (module docstring); NaN, inf and
    ``|x| < 10^-11`` kept as they are."""
    x = np.asarray(x, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.floor(np.log10(np.abs(x)))
        d = digits - 1 - e
        exact = np.isfinite(d) & (np.abs(d) <= 22)
        d = np.where(exact, d, 0.0)
        scale = 10.0 ** np.abs(d)
        up = np.rint(x * scale) / scale
        down = np.rint(x / scale) * scale
    return np.where(exact, np.where(d >= 0, up, down), x)


def _quoted(values):
    """A string array with the fields that need it quoted (module docstring); the quoting is
    decided once per distinct value (the tables repeat a few names over many rows)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    encoded = pc.dictionary_encode(pc.fill_null(pc.cast(values, pa.string()), ""))
    names = encoded.dictionary
    needs = pc.match_substring_regex(names, r'[,"\r\n]')
    if pc.any(needs).as_py():
        quoted = pc.binary_join_element_wise("", pc.replace_substring(names, '"', '""'), "", '"')
        names = pc.if_else(needs, quoted, names)
    return pc.take(names, encoded.indices)


def _field(column):
    """The CSV text of one pyarrow column (a string array), or None for an unsupported type.

    A column of few distinct values (frame, time, names) is formatted once per value."""
    import pyarrow as pa
    import pyarrow.compute as pc

    t = column.type
    if pa.types.is_string(t) or pa.types.is_large_string(t) or pa.types.is_null(t):
        return _quoted(column)
    if pa.types.is_dictionary(t) and pa.types.is_string(t.value_type):
        return _quoted(column.cast(pa.string()))
    if not (pa.types.is_floating(t) or pa.types.is_integer(t) or pa.types.is_boolean(t)):
        return None
    if len(column) > 64:
        encoded = pc.dictionary_encode(column)     # missing values: null indices, not in the dictionary
        if 4 * len(encoded.dictionary) < len(column):
            return pc.fill_null(pc.take(_field(encoded.dictionary), encoded.indices), "")
    if pa.types.is_floating(t):
        x = _rounded(column.to_numpy(zero_copy_only=False), DIGITS)
        missing = np.isnan(x)
        return pc.fill_null(pc.cast(pa.array(x, mask=missing if missing.any() else None), pa.string()), "")
    if pa.types.is_integer(t):
        return pc.fill_null(pc.cast(column, pa.string()), "")
    return pc.fill_null(pc.if_else(column, "True", "False"), "")


def _header(names) -> bytes:
    import csv
    import io

    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow([str(n) for n in names])
    return buf.getvalue().encode("utf-8")


def arrow_table(frame):
    """``pyarrow.Table.from_pandas(frame, preserve_index=False)``, or None where Arrow cannot
    hold a column (the CSV then falls back to pandas)."""
    import pyarrow as pa

    try:
        return pa.Table.from_pandas(frame, preserve_index=False)
    except (pa.ArrowInvalid, pa.ArrowTypeError, pa.ArrowNotImplementedError):
        return None


def csv_bytes(frame, *, header: bool = True, table=None) -> bytes:
    """The CSV text (UTF-8 bytes) of a pandas DataFrame (module docstring); no index column.
    ``table``: its `arrow_table` when the caller has made it already (for Parquet)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    names = list(frame.columns)
    head = _header(names) if header else b""
    if len(frame) == 0:
        return head
    if table is None:
        table = arrow_table(frame)
    fields = None if table is None else [_field(c.combine_chunks()) for c in table.columns]
    if fields is None or any(f is None for f in fields):
        text = frame.to_csv(index=False, header=header, float_format=f"%.{DIGITS}g", lineterminator="\n")
        return text.encode("utf-8")
    lines = pc.binary_join_element_wise(*fields, ",") if len(fields) > 1 else fields[0]
    lines = pc.binary_join_element_wise(lines, "", "\n")
    if isinstance(lines, pa.ChunkedArray):
        lines = lines.combine_chunks()
    lines = lines.cast(pa.large_string())
    offsets = np.frombuffer(lines.buffers()[1], dtype=np.int64, count=len(lines) + 1,
                            offset=lines.offset * 8)
    return head + memoryview(lines.buffers()[2])[int(offsets[0]):int(offsets[-1])]


def write_csv_part(frame, fh, *, header: bool = True, table=None) -> None:
    """Append the CSV text of ``frame`` to the binary file ``fh`` (``table`` as in `csv_bytes`)."""
    fh.write(csv_bytes(frame, header=header, table=table))
