"""The table of a motion file (`motion.load_motion`): column labels, rows of numbers, time, and
which model coordinate each column gives.

Columns are matched by coordinate name, by OpenSim 4 state paths
(``/jointset/<joint>/<coordinate>/value``; ``.../speed`` and ``<coordinate>_u`` columns are
speeds and ignored) or not at all (reported as unknown). Every problem is one `InputError` naming
the file and its line.
"""
from __future__ import annotations

import itertools

import numpy as np

from ..errors import InputError

__all__ = ["read_labels", "read_numbers", "check_time", "match_columns", "model_name"]


def model_name(model) -> str:
    return str(getattr(model, "name", "") or "?")


def split_labels(line: str):
    parts = line.split("\t") if "\t" in line else line.split()
    return [p.strip() for p in parts]


def read_labels(lines, end_line, path):
    for number in range(end_line + 1, len(lines) + 1):
        line = lines[number - 1]
        if line.strip():
            labels = split_labels(line.strip())
            if any(not label for label in labels):
                raise InputError("an empty column label", file=path, where=f"line {number}",
                                 fix="Give every column a label, separated by single tabs.")
            return labels, number
    raise InputError("no column labels after 'endheader'", file=path, where=f"line {end_line}",
                     fix="Add a line of column labels (time, then coordinate names) and the rows.")


def read_numbers(lines, label_line, labels, path):
    """(R, L) float table of the data rows and (R,) 1-based line numbers of each row."""
    numbers = np.arange(label_line + 1, len(lines) + 1)
    rows = [lines[n - 1].split() for n in numbers]
    keep = np.fromiter((len(r) > 0 for r in rows), dtype=bool, count=len(rows))
    numbers = numbers[keep]
    rows = [r for r in rows if r]
    if not rows:
        raise InputError("the motion file has no data rows", file=path,
                         where=f"line {label_line}",
                         fix="Add one row of numbers per time step after the column labels.")
    widths = np.fromiter(map(len, rows), dtype=int, count=len(rows))
    bad = np.flatnonzero(widths != len(labels))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"a ragged row: {widths[i]} values but {len(labels)} column labels",
                         file=path, where=f"line {numbers[i]}",
                         fix="Give every row one value per column label (tab-separated).")
    try:  # float() per token is the fastest exact parse here (numpy's str->float is slower)
        data = np.fromiter(map(float, itertools.chain.from_iterable(rows)), dtype=float,
                           count=len(rows) * len(labels))
    except ValueError:
        data = None
    if data is None:
        # The error path only: find the first token that is not a number.
        for i, row in enumerate(rows):
            for j, token in enumerate(row):
                try:
                    float(token)
                except ValueError:
                    raise InputError(f"text {token!r} in number column '{labels[j]}'", file=path,
                                     where=f"line {numbers[i]}",
                                     fix="Every value after the labels must be a number.") from None
    data = data.reshape(len(rows), len(labels))
    finite = np.isfinite(data)
    if not finite.all():
        i, j = (int(k) for k in np.argwhere(~finite)[0])
        raise InputError(f"{data[i, j]} in column '{labels[j]}'", file=path,
                         where=f"line {numbers[i]}",
                         fix="Fill the gap (interpolate) or remove the row; values must be finite.")
    return data, numbers


def check_time(time, row_lines, path):
    step = np.diff(time)
    bad = np.flatnonzero(~(step > 0))
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(f"time is not increasing: {time[i]:.9g} s follows {time[i - 1]:.9g} s",
                         file=path, where=f"line {row_lines[i]}",
                         fix="Sort the rows by time and remove duplicated time steps.")


def match_columns(labels, model, label_line, path):
    """Map model coordinate index -> file column, and list the unknown labels (in file order)."""
    names = tuple(model.coordinate_names)
    known = set(names)
    joint_of = {c.name: c.joint for c in model.coordinates}
    columns, unknown, first_label = {}, [], {}
    for column, label in enumerate(labels[1:], start=1):
        coordinate = coordinate_of(label, known, joint_of)
        if coordinate is None:
            unknown.append(label)
            continue
        if coordinate == "":
            continue  # a speed column: ignored quietly
        index = model.coordinate_index(coordinate)
        if index in columns:
            raise InputError(f"columns '{first_label[index]}' and '{label}' both give coordinate "
                             f"'{coordinate}'", file=path, where=f"line {label_line}",
                             fix="Keep one column per coordinate.")
        columns[index] = column
        first_label[index] = label
    if not columns:
        shown = ", ".join(labels[1:6]) + (" ..." if len(labels) > 6 else "")
        model_names = ", ".join(names[:6]) + (" ..." if len(names) > 6 else "")
        raise InputError(f"no column is a coordinate of model '{model_name(model)}' "
                         f"(columns: {shown or 'none'}; model coordinates: {model_names})",
                         file=path, where=f"line {label_line}",
                         fix="Pass the motion made for this model, or rename the columns to the "
                             "model's coordinate names.")
    return columns, unknown


def coordinate_of(label, known, joint_of):
    """Coordinate name of a label; '' for a speed column; None for an unknown label."""
    if label in known:
        return label
    if label.startswith("/"):
        parts = label.strip("/").split("/")
        if len(parts) >= 3 and parts[0] == "jointset" and parts[-2] in known:
            coordinate = parts[-2]
            joint = joint_of.get(coordinate)
            if isinstance(joint, str) and joint and len(parts) == 4 and parts[1] != joint:
                return None
            if parts[-1] == "value":
                return coordinate
            if parts[-1] == "speed":
                return ""
        return None
    if label.endswith("_u") and label[:-2] in known:
        return ""
    return None
