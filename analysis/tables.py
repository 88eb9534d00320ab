"""The tables of `fibres run` (INTERFACE.md): long/tidy pandas DataFrames built from a RunResult.

- ``fibre_lengths.csv``: frame, time, muscle, fibre, length, normalized_length (l / l_opt)
- ``fibre_moment_arms.csv``: frame, time, muscle, fibre, coordinate, moment_arm
- ``action_lines.csv``: frame, time, muscle, action_line, length
- ``action_line_moment_arms.csv``: frame, time, muscle, action_line, coordinate, moment_arm
- ``summary.csv``: one row per frame x muscle for the length and the normalized length, and per
  frame x muscle x coordinate for the moment arm: frame, time, muscle, quantity ("length" |
  "normalized_length" | "moment_arm"), coordinate ("" for the lengths), n_fibres, mean, std, min, p5, median, p95, max of the fibres, then the action
  lines: n_action_lines, action_line_mean, action_line_min, action_line_max and
  action_line_values ("name=value;name=value", values with 12 significant digits).

Each is also written as ``<name>.parquet`` (same columns, full precision; `write_tables`).
``frame`` is 0-based over the frames actually used; SI units throughout. Every table is built
with array operations (repeat/tile), no loop over frames or fibres.
"""
from __future__ import annotations

import numpy as np

__all__ = ["fibre_lengths_table", "fibre_moment_arms_table", "action_lines_table",
           "action_line_moment_arms_table", "summary_table", "result_long_frame", "TABLES",
           "write_tables", "TableStreams"]

#: file name -> table builder
TABLES = {}


def _grid(n_f, time, *inner):
    """frame, time columns for an (F, *inner) array flattened in C order."""
    k = int(np.prod(inner)) if inner else 1
    frame = np.repeat(np.arange(n_f), k)
    return frame, np.repeat(np.asarray(time, dtype=float), k)


def _concat(frames, columns):
    import pandas as pd

    if not frames:
        return pd.DataFrame({c: [] for c in columns})
    return pd.concat(frames, ignore_index=True)[columns]


def _normalized(m):
    """(F, N) l / l_opt of a MuscleResult (NaN where unknown or not provided)."""
    value = getattr(m, "normalized_lengths", None)
    return np.full(m.fibre_lengths.shape, np.nan) if value is None else np.asarray(value, dtype=float)


def _line_normalized(m):
    """(F, L) (L_path - l_ts) / l_opt of the action lines (NaN where unknown)."""
    value = getattr(m, "line_normalized_lengths", None)
    return np.full(m.action_line_lengths.shape, np.nan) if value is None else np.asarray(value, dtype=float)


def _long(result, values_of, item, labels_of, value, extra=None):
    """One long table of per-muscle arrays ``values_of(m)``: (F, I) or, with a coordinate axis,
    (F, I, C) (muscles spanning no coordinate give no rows). Columns: frame, time, muscle,
    ``item`` (``labels_of(m)``, I labels), coordinate (with a coordinate axis), ``value``, then
    ``extra`` (name -> function of the muscle giving an (F, I) array)."""
    import pandas as pd

    out = []
    for m in result.muscles:
        values = np.asarray(values_of(m))
        n_f, n_i = values.shape[:2]
        inner = values.shape[1:]
        if values.ndim == 3 and values.shape[2] == 0:
            continue
        n_c = values.shape[2] if values.ndim == 3 else 1
        frame, time = _grid(n_f, result.time, *inner)
        labels = np.asarray(labels_of(m))
        labels = labels.astype(object) if labels.dtype.kind in "US" else labels   # names: Python str
        data = {"frame": frame, "time": time, "muscle": m.name, item: np.tile(np.repeat(labels, n_c), n_f)}
        if values.ndim == 3:
            data["coordinate"] = np.tile(np.array(m.coordinates, dtype=object), n_f * n_i)
        data[value] = values.ravel()
        for name, fn in (extra or {}).items():
            data[name] = np.asarray(fn(m), dtype=float).ravel()
        out.append(pd.DataFrame(data))
    return out


def fibre_lengths_table(result):
    """(frame, time, muscle, fibre, length, normalized_length) for every muscle, frame and fibre."""
    out = _long(result, lambda m: m.fibre_lengths, "fibre", lambda m: np.arange(m.fibre_lengths.shape[1]),
                "length", extra={"normalized_length": _normalized})
    cols = ["frame", "time", "muscle", "fibre", "length", "normalized_length"]
    return _concat(out, cols)


def fibre_moment_arms_table(result):
    """(frame, time, muscle, fibre, coordinate, moment_arm) for every spanned coordinate."""
    out = _long(result, lambda m: m.fibre_moment_arms, "fibre",
                lambda m: np.arange(m.fibre_moment_arms.shape[1]), "moment_arm")
    return _concat(out, ["frame", "time", "muscle", "fibre", "coordinate", "moment_arm"])


def action_lines_table(result):
    """(frame, time, muscle, action_line, length)."""
    out = _long(result, lambda m: m.action_line_lengths, "action_line", lambda m: m.action_lines, "length")
    return _concat(out, ["frame", "time", "muscle", "action_line", "length"])


def action_line_moment_arms_table(result):
    """(frame, time, muscle, action_line, coordinate, moment_arm)."""
    out = _long(result, lambda m: m.action_line_moment_arms, "action_line", lambda m: m.action_lines,
                "moment_arm")
    return _concat(out, ["frame", "time", "muscle", "action_line", "coordinate", "moment_arm"])


_STATS = ("mean", "std", "min", "p5", "median", "p95", "max")


def _stats(values):
    """Statistics over the last axis of (..., N) values -> dict of (...) arrays."""
    p5, median, p95 = np.percentile(values, [5.0, 50.0, 95.0], axis=-1)
    return {"mean": values.mean(-1), "std": values.std(-1, ddof=0), "min": values.min(-1), "p5": p5,
            "median": median, "p95": p95, "max": values.max(-1)}


def _line_values(names, values):
    """(R, L) values -> R strings 'name=value;...'."""
    cols = [np.char.add(f"{n}=", np.char.mod("%.12g", values[:, i])) for i, n in enumerate(names)]
    out = cols[0]
    for c in cols[1:]:
        out = np.char.add(np.char.add(out, ";"), c)
    return out.astype(object)


def summary_table(result):
    """One row per frame x muscle (length) and frame x muscle x coordinate (moment arm)."""
    import pandas as pd

    cols = (["frame", "time", "muscle", "quantity", "coordinate", "n_fibres", *_STATS, "n_action_lines",
             "action_line_mean", "action_line_min", "action_line_max", "action_line_values"])
    out = []
    for m in result.muscles:
        n_f, n_n = m.fibre_lengths.shape
        n_l = len(m.action_lines)
        st = _stats(m.fibre_lengths)
        al = m.action_line_lengths
        out.append(pd.DataFrame({
            "frame": np.arange(n_f), "time": result.time, "muscle": m.name, "quantity": "length",
            "coordinate": "", "n_fibres": n_n, **st, "n_action_lines": n_l,
            "action_line_mean": al.mean(-1), "action_line_min": al.min(-1), "action_line_max": al.max(-1),
            "action_line_values": _line_values(m.action_lines, al)}))
        norm, line_norm = _normalized(m), _line_normalized(m)
        with np.errstate(invalid="ignore"):
            st = _stats(norm)
            out.append(pd.DataFrame({
                "frame": np.arange(n_f), "time": result.time, "muscle": m.name, "quantity": "normalized_length",
                "coordinate": "", "n_fibres": n_n, **st, "n_action_lines": n_l,
                "action_line_mean": line_norm.mean(-1), "action_line_min": line_norm.min(-1),
                "action_line_max": line_norm.max(-1), "action_line_values": _line_values(m.action_lines, line_norm)}))
        n_c = len(m.coordinates)
        if n_c == 0:
            continue
        st = _stats(np.moveaxis(m.fibre_moment_arms, 1, 2).reshape(n_f * n_c, n_n))
        ar = np.moveaxis(m.action_line_moment_arms, 1, 2).reshape(n_f * n_c, n_l)
        frame, time = _grid(n_f, result.time, n_c)
        out.append(pd.DataFrame({
            "frame": frame, "time": time, "muscle": m.name, "quantity": "moment_arm",
            "coordinate": np.tile(np.array(m.coordinates, dtype=object), n_f), "n_fibres": n_n, **st,
            "n_action_lines": n_l, "action_line_mean": ar.mean(-1), "action_line_min": ar.min(-1),
            "action_line_max": ar.max(-1), "action_line_values": _line_values(m.action_lines, ar)}))
    df = _concat(out, cols)
    if len(df):
        order = {"length": 0, "normalized_length": 1, "moment_arm": 2}
        df = df.assign(_q=df["quantity"].map(order)).sort_values(
            ["frame", "muscle", "_q", "coordinate"], kind="stable").drop(columns="_q").reset_index(drop=True)
    return df


def result_long_frame(result):
    """Every number of a RunResult in one long DataFrame (see `RunResult.to_frame`)."""
    import pandas as pd

    cols = ["frame", "time", "muscle", "kind", "fibre", "action_line", "quantity", "coordinate", "value"]
    parts = []
    fl = fibre_lengths_table(result)
    parts.append(fl.drop(columns="normalized_length").rename(columns={"length": "value"}).assign(
        kind="fibre", action_line="", quantity="length", coordinate=""))
    parts.append(fl.drop(columns="length").rename(columns={"normalized_length": "value"}).assign(
        kind="fibre", action_line="", quantity="normalized_length", coordinate=""))
    fr = fibre_moment_arms_table(result)
    parts.append(fr.rename(columns={"moment_arm": "value"}).assign(kind="fibre", action_line="",
                                                                   quantity="moment_arm"))
    al = action_lines_table(result)
    parts.append(al.rename(columns={"length": "value"}).assign(kind="action_line", fibre=-1, quantity="length",
                                                               coordinate=""))
    ar = action_line_moment_arms_table(result)
    parts.append(ar.rename(columns={"moment_arm": "value"}).assign(kind="action_line", fibre=-1,
                                                                   quantity="moment_arm"))
    df = pd.concat([p[cols] for p in parts], ignore_index=True)
    return df.astype({"frame": np.int64, "fibre": np.int64, "value": float})


def fibre_quality_table(result):
    """One row per muscle: the rest-pose fibres' quality (`fibres.finishing.quality.FibreQuality`)."""
    import pandas as pd

    rows = [dict(muscle=m.name, **(m.quality or {})) for m in result.muscles]
    return pd.DataFrame(rows)


TABLES.update({
    "fibre_lengths.csv": fibre_lengths_table,
    "fibre_moment_arms.csv": fibre_moment_arms_table,
    "action_lines.csv": action_lines_table,
    "action_line_moment_arms.csv": action_line_moment_arms_table,
    "summary.csv": summary_table,
    "fibre_quality.csv": fibre_quality_table,
})


#: tables `write_tables` writes at the same time (threads)
TABLE_THREADS = 2
#: tables written muscle by muscle (`write_tables`): their rows are muscle-major anyway
PER_MUSCLE = ("fibre_lengths.csv", "fibre_moment_arms.csv", "action_lines.csv", "action_line_moment_arms.csv")


def write_tables(result, out_dir, *, parquet: bool = True, streamed=None) -> list:
    """Write the tables into ``out_dir`` atomically, as CSV and (``parquet=True``) as Parquet
    beside it (``<name>.parquet``: the same columns, full float64 precision, pyarrow).

    The per-fibre and per-line tables (`PER_MUSCLE`) are built and appended one muscle at a
    time (a Parquet row group per muscle), so a whole model's tables never sit in memory at once;
    the files are the same as if written at once. ``streamed``: a `TableStreams` that already
    received every muscle of ``result`` during the run (its files are finished here, not built
    again). Returns the paths written."""
    import concurrent.futures
    import contextvars
    import dataclasses
    from pathlib import Path

    from .output_files import atomic_path, write_csv

    def one(name, build):
        path = Path(out_dir) / name
        pq = path.with_suffix(".parquet")
        if name not in PER_MUSCLE or len(result.muscles) < 2:
            table = build(result)
            write_csv(table, path)
            if parquet:
                with atomic_path(pq) as tmp:
                    table.to_parquet(tmp, index=False, engine="pyarrow")
        else:
            parts = (build(dataclasses.replace(result, muscles=(m,))) for m in result.muscles)
            _write_streamed(parts, path, pq if parquet else None)
        return [path, pq] if parquet else [path]

    done = streamed.close() if streamed is not None else []
    todo = {name: build for name, build in TABLES.items() if streamed is None or name not in PER_MUSCLE}
    # two tables at a time (pyarrow's kernels and the file writes release the GIL); each thread
    # runs in a copy of this context, so `output_files.confined_to` holds there too
    with concurrent.futures.ThreadPoolExecutor(max_workers=TABLE_THREADS) as pool:
        futures = [pool.submit(contextvars.copy_context().run, one, name, build) for name, build in todo.items()]
        return done + [p for fut in futures for p in fut.result()]


class _Stream:
    """One CSV (one header) and one Parquet file (a row group per part) appended part by part,
    each atomically (`output_files.atomic_path`): ``write(part)``, then ``close()`` or, on
    failure, ``abort()`` (no file is put in place)."""

    def __init__(self, csv_path, parquet_path):
        import contextlib

        from .output_files import atomic_path

        self.stack = contextlib.ExitStack()
        try:
            self.csv_tmp = self.stack.enter_context(atomic_path(csv_path))
            self.pq_tmp = self.stack.enter_context(atomic_path(parquet_path)) if parquet_path is not None else None
            self.fh = self.stack.enter_context(open(self.csv_tmp, "wb"))
        except BaseException:
            self.abort()
            raise
        self.writer, self.first, self.empty = None, True, None

    def write(self, part) -> None:
        import pyarrow as pa
        import pyarrow.parquet as papq

        from .csv_text import arrow_table, write_csv_part

        if part.empty:
            self.empty = part if self.empty is None else self.empty
            if not self.first:
                return
        table = None if part.empty else arrow_table(part)      # one conversion for both files
        write_csv_part(part, self.fh, header=self.first, table=table)
        self.first = False
        if self.pq_tmp is not None and not part.empty:
            table = pa.Table.from_pandas(part, preserve_index=False) if table is None else table
            if self.writer is None:
                self.writer = self.stack.enter_context(papq.ParquetWriter(self.pq_tmp, table.schema))
            self.writer.write_table(table.cast(self.writer.schema))

    def close(self) -> None:
        try:
            if self.pq_tmp is not None and self.writer is None:       # no rows at all: the empty table
                self.empty.to_parquet(self.pq_tmp, index=False, engine="pyarrow")
        except BaseException:
            self.abort()
            raise
        self.stack.close()

    def abort(self) -> None:
        err = RuntimeError("table stream aborted")
        self.stack.__exit__(type(err), err, None)


def _write_streamed(parts, csv_path, parquet_path):
    """Append DataFrames of the same columns to one CSV (one header) and one Parquet file,
    each atomically (`_Stream`)."""
    stream = _Stream(csv_path, parquet_path)
    try:
        for part in parts:
            stream.write(part)
    except BaseException:
        stream.abort()
        raise
    stream.close()


class TableStreams:
    """The `PER_MUSCLE` tables of a run written while it runs: ``add(time, muscle)`` appends one
    `MuscleResult` (in the order of the run's muscles; e.g. from `analysis.run`'s ``on_muscle``),
    `write_tables` (``streamed=``) finishes them after the run and writes the others; ``abort()``
    drops them. The files are those `write_tables` alone writes."""

    def __init__(self, out_dir, *, parquet: bool = True):
        from pathlib import Path

        self.paths, self.streams = [], {}
        try:
            for name in PER_MUSCLE:
                path = Path(out_dir) / name
                pq = path.with_suffix(".parquet") if parquet else None
                self.streams[name] = _Stream(path, pq)
                self.paths += [path] + ([pq] if parquet else [])
        except BaseException:
            self.abort()
            raise

    def add(self, time, muscle) -> None:
        import types

        one = types.SimpleNamespace(time=time, muscles=(muscle,))
        for name, stream in self.streams.items():
            stream.write(TABLES[name](one))

    def close(self) -> list:
        """Finish the files; returns their paths."""
        for stream in self.streams.values():
            stream.close()
        self.streams = {}
        return self.paths

    def abort(self) -> None:
        for stream in self.streams.values():
            stream.abort()
        self.streams = {}
