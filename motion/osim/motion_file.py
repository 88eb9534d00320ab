"""Motions: OpenSim .mot/.sto files in (`load_motion`) and out (`write_sto`), and the `Motion` record.

File format (OpenSim's ``Storage``, read here as OpenSim 4.6 reads it)
-----------------------------------------------------------------------
A header of free text and ``key=value`` lines closed by a line ``endheader``, then one line of
column labels, then one row of numbers per time step. The first column is time. Three header
dialects occur in real files and are all accepted:

- version 1 (``Storage`` / IK / SIMM-era OpenSim): a name line, ``version=1``, ``nRows=``,
  ``nColumns=``, ``inDegrees=yes|no``, free comment lines.
- version 3 (``STOFileAdapter`` of OpenSim 4): ``key=value`` metadata only (``inDegrees``,
  ``DataType``, ``version=3``, ``OpenSimVersion``), no ``nRows``.
- the old SIMM dialect (no ``version=``): ``datacolumns N``, ``datarows N``, ``range a b``. OpenSim
  assumes degrees for these files when ``inDegrees`` is absent, and so do we. Otherwise an absent
  ``inDegrees`` means radians, as in OpenSim.

Like OpenSim, ``nRows``/``nColumns``/``datarows`` are not trusted: the rows and labels actually
present are read (the LHDL hip motions say ``nRows=51`` and hold 36 rows; OpenSim reads 36). Unlike
OpenSim, a count that disagrees with the data (or is not a whole number) gives ONE
`MotionFileWarning`: the file may be truncated or edited by hand.

``inDegrees`` must be ``yes``/``no`` (also ``true``/``false``, ``1``/``0``, any case). Any other
value is an `InputError`: OpenSim silently reads ``inDegrees=Yes please`` as radians, which turned
an elbow flexion of 130 degrees into 7,448 degrees. After the conversion, values far outside a
coordinate's range (beyond the range widened by its own width, and by at least 90 degrees or
1 m) give ONE `MotionFileWarning` naming the coordinates: typically degrees read as radians.
Labels are tab-separated (whitespace-separated when a label line has no tab); numbers are
separated by any whitespace.

Column labels and the model
---------------------------
A label is either a coordinate name (``r_elbow_flex``) or a state path
(``/jointset/r_elbow/r_elbow_flex/value``). Speed columns (``.../speed`` and the 3.x ``<coord>_u``)
are ignored quietly: they belong to state files and carry no information the values do not.
Every other label that is not a coordinate of the model is ignored with ONE `MotionFileWarning`
listing all of them (`Motion.unknown`). Coordinates of the model absent from the file take their
default value (`Motion.missing`); ONE `MotionFileWarning` lists those that matter, i.e. all but the
locked ones and the dependent coordinates of a CoordinateCouplerConstraint (their values are
overwritten by the lock or the coupler anyway).

``inDegrees=yes`` converts only the columns of *rotational* coordinates to radians; coupled and
translational coordinates are left as they are (OpenSim's ``SimbodyEngine::convertDegreesToRadians``
tests ``Coordinate::getMotionType() == Rotational``).

Every problem with the file is a `motion.errors.InputError` naming the file, the line and the fix.
"""
from __future__ import annotations

import contextlib
import dataclasses
import itertools
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["Motion", "MotionFileWarning", "load_motion", "write_sto"]

#: bytes read to decide whether a file is text
_SNIFF = 8192


class MotionFileWarning(UserWarning):
    """A motion file's column does not match the model (ignored or defaulted); the run goes on."""


def _readonly(array, dtype=float):
    out = np.array(array, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


@dataclasses.dataclass(frozen=True)
class Motion:
    """Coordinate values over time for one model, in SI units and the model's coordinate order.

    Parameters
    ----------
    time : (F,) float
        Time of each frame in seconds, strictly increasing.
    q : (F, C) float
        Value of every model coordinate at every frame: radians for rotational coordinates,
        metres for translational ones, the coupler's own unit for coupled ones.
    coordinate_names : (C,) tuple of str
        The model's coordinate names, in model order (the columns of ``q``).
    source : str or None
        The file the motion was read from.
    in_degrees : bool
        Whether the file declared ``inDegrees=yes`` (``q`` is in radians regardless).
    missing : tuple of str
        Model coordinates absent from the file, filled with their default value.
    unknown : tuple of str
        Column labels of the file that are not model coordinates (ignored).
    """

    time: np.ndarray
    q: np.ndarray
    coordinate_names: tuple
    source: str | None = None
    in_degrees: bool = False
    missing: tuple = ()
    unknown: tuple = ()

    def __post_init__(self):
        time = _readonly(self.time)
        q = _readonly(self.q)
        names = tuple(str(n) for n in self.coordinate_names)
        if time.ndim != 1:
            raise ValueError(f"time must be (F,), got shape {time.shape}")
        if q.ndim != 2 or q.shape != (time.shape[0], len(names)):
            raise ValueError(f"q must be (F, C) = ({time.shape[0]}, {len(names)}), got shape {q.shape}")
        if len(set(names)) != len(names):
            raise ValueError("coordinate_names has duplicates")
        if time.shape[0] > 1 and not np.all(np.diff(time) > 0):
            raise ValueError("time must be strictly increasing")
        object.__setattr__(self, "time", time)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "coordinate_names", names)
        object.__setattr__(self, "source", None if self.source is None else str(self.source))
        object.__setattr__(self, "in_degrees", bool(self.in_degrees))
        object.__setattr__(self, "missing", tuple(self.missing))
        object.__setattr__(self, "unknown", tuple(self.unknown))

    @property
    def n_frames(self) -> int:
        """F, the number of frames."""
        return int(self.time.shape[0])

    def column(self, name: str) -> np.ndarray:
        """(F,) float: the values of coordinate ``name``."""
        try:
            return self.q[:, self.coordinate_names.index(name)]
        except ValueError:
            raise KeyError(f"no coordinate named {name!r} in this motion") from None

    def select_frames(self, frames) -> "Motion":
        """A motion holding only some frames.

        Parameters
        ----------
        frames : slice or (F2,) int array
            Rows to keep, in increasing order.
        """
        index = np.arange(self.n_frames)[frames]
        return dataclasses.replace(self, time=self.time[index], q=self.q[index])

    @classmethod
    def from_array(cls, model, time, q_or_dict, *, source=None) -> "Motion":
        """Build a motion for ``model`` from arrays (tests and scripts); values in SI units.

        Parameters
        ----------
        model : motion.Model
        time : (F,) float
        q_or_dict : (F, C) float, or dict str -> (F,) float
            Either every coordinate in model order, or some coordinates by name; coordinates
            not in the dict take their default value (listed in ``missing``, no warning).
        """
        time = np.asarray(time, dtype=float).reshape(-1)
        names = tuple(model.coordinate_names)
        if isinstance(q_or_dict, dict):
            unknown = [k for k in q_or_dict if k not in names]
            if unknown:
                raise ValueError(f"not coordinates of the model: {', '.join(map(str, unknown))}")
            q = np.array([c.default_value for c in model.coordinates], dtype=float)
            q = np.tile(q, (time.shape[0], 1))
            for name, values in q_or_dict.items():
                q[:, model.coordinate_index(name)] = np.asarray(values, dtype=float)
            missing = tuple(n for n in names if n not in q_or_dict)
        else:
            q = np.asarray(q_or_dict, dtype=float)
            if q.ndim == 1 and len(names) == 1:
                q = q[:, None]
            missing = ()
        return cls(time=time, q=q, coordinate_names=names, source=source, missing=missing)


# ----------------------------------------------------------------------------- reading


def load_motion(path, model) -> Motion:
    """Read an OpenSim .mot or .sto file as the coordinates of ``model``; anything unexpected
    that goes wrong while reading it becomes one `InputError` naming the file.

    Parameters
    ----------
    path : str or os.PathLike
    model : motion.Model

    Returns
    -------
    Motion
        All model coordinates in model order, SI units (see the module docstring for the rules).

    Raises
    ------
    InputError
        Missing, empty or binary file; no ``endheader``; no data rows; a ragged row; text, NaN
        or infinity in a number column; time not strictly increasing; no column is a coordinate
        of the model; two columns for one coordinate.

    Warns
    -----
    MotionFileWarning
        Once for the unknown columns, once for the missing coordinates, once for header counts
        that disagree with the data, once for values far outside coordinate ranges (see module
        docstring).
    """
    try:
        return _load_motion(path, model)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - bad input must not crash (MemoryError included)
        raise InputError(f"cannot read the motion file ({type(exc).__name__}: {exc})", file=path,
                         fix="Export the motion again from OpenSim (a header, 'endheader', labels, "
                             "rows of numbers).") from None


def _load_motion(path, model) -> Motion:
    path = Path(path)
    text = _read_text(path)
    lines = text.splitlines()
    header, end_line = _read_header(lines, path)
    in_degrees = _in_degrees(header, path)
    labels, label_line = _read_labels(lines, end_line, path)
    data, row_lines = _read_numbers(lines, label_line, labels, path)
    time = data[:, 0]
    _check_time(time, row_lines, path)
    _check_counts(header, data.shape, path)

    columns, unknown = _match_columns(labels, model, label_line, path)
    names = tuple(model.coordinate_names)
    coords = model.coordinates
    q = np.tile(np.array([c.default_value for c in coords], dtype=float), (time.shape[0], 1))
    for index, column in columns.items():
        values = data[:, column]
        if in_degrees and coords[index].motion_type == "rotational":
            values = np.deg2rad(values)
        q[:, index] = values
    missing = tuple(n for i, n in enumerate(names) if i not in columns)
    _check_ranges(q, columns, coords, in_degrees, path)

    if unknown:
        warnings.warn(f"{path}: line {label_line}: ignored {len(unknown)} column(s) that are not "
                      f"coordinates of model '{_model_name(model)}': {', '.join(unknown)}",
                      MotionFileWarning, stacklevel=3)
    silent = _locked_or_dependent(model)
    loud = [n for n in missing if n not in silent]
    if loud:
        warnings.warn(f"{path}: {len(loud)} coordinate(s) of model '{_model_name(model)}' are not "
                      f"in the file and keep their default value: {', '.join(loud)}",
                      MotionFileWarning, stacklevel=3)
    return Motion(time=time, q=q, coordinate_names=names, source=str(path), in_degrees=in_degrees,
                  missing=missing, unknown=tuple(unknown))


def _model_name(model) -> str:
    return str(getattr(model, "name", "") or "?")


def _locked_or_dependent(model) -> set:
    """Names of coordinates whose file value would not be used: locked, or a coupler's dependent."""
    quiet = {c.name for c in model.coordinates if c.locked}
    quiet.update(coupler.dependent for coupler in model.couplers)
    return quiet


def _read_text(path: Path) -> str:
    fix_missing = "Check the path of the motion file (.mot or .sto)."
    if not path.exists():
        raise InputError("the motion file does not exist", file=path, fix=fix_missing)
    if path.is_dir():
        raise InputError("is a folder, not a motion file", file=path,
                         fix="Pass the .mot or .sto file inside it.")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read the motion file ({exc.strerror})", file=path,
                         fix="Check the file's permissions.") from None
    if not raw.strip():
        raise InputError("the motion file is empty", file=path,
                         fix="Export the motion again (a header, 'endheader', labels, rows).")
    sniff = raw[:_SNIFF]
    controls = sum(sniff.count(bytes([b])) for b in range(32) if b not in (9, 10, 12, 13))
    if b"\x00" in sniff or controls > 0.01 * len(sniff):
        raise InputError("is a binary file, not a text .mot/.sto motion file", file=path,
                         fix="Pass a text motion file written by OpenSim (or write_sto).")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _read_header(lines, path):
    """Parse header lines up to ``endheader``: dict of lower-case keys -> (value, 1-based line),
    and the 1-based end line."""
    header = {}
    for number, line in enumerate(lines, start=1):
        stripped = line.strip()
        if stripped.lower() == "endheader":
            return header, number
        if "=" in stripped:
            key, _, value = stripped.partition("=")
            header[key.strip().lower()] = (value.strip(), number)
        else:
            words = stripped.split()
            if len(words) >= 2 and words[0].lower() in ("datacolumns", "datarows", "range"):
                header[words[0].lower()] = (" ".join(words[1:]), number)
    raise InputError(f"the header never ends: no 'endheader' line in {len(lines)} lines",
                     file=path, where=f"line {len(lines)}",
                     fix="Add a line 'endheader' between the header and the column labels.")


_YES = ("yes", "true", "1")
_NO = ("no", "false", "0")
#: "far outside the range": beyond the range widened by its width, and at least by this (SI)
_RANGE_SLACK = {"rotational": np.pi / 2, "translational": 1.0}


def _in_degrees(header, path) -> bool:
    entry = header.get("indegrees")
    if entry is None:
        # OpenSim's Storage: old SIMM files (no 'version=') are assumed to be in degrees.
        return "version" not in header
    value, number = entry
    word = value.strip().lower()
    if word not in _YES + _NO:
        raise InputError(f"inDegrees={value!r} is neither yes nor no, so the angle unit is unknown",
                         file=path, where=f"line {number}",
                         fix="Write inDegrees=yes (angles in degrees) or inDegrees=no (radians).")
    return word in _YES


_SPELLING = {"nrows": "nRows", "ncolumns": "nColumns", "datarows": "datarows",
             "datacolumns": "datacolumns"}


def _check_counts(header, shape, path):
    """ONE warning if nRows/datarows or nColumns/datacolumns disagree with the data read."""
    found = []
    for keys, actual, what in ((("nrows", "datarows"), shape[0], "data rows"),
                               (("ncolumns", "datacolumns"), shape[1], "columns")):
        for key in keys:
            if key not in header:
                continue
            value, number = header[key]
            try:
                declared = int(value.strip())
            except ValueError:
                found.append(f"line {number}: {_SPELLING[key]}={value!r} is not a whole number")
                continue
            if declared != actual:
                found.append(f"line {number}: the header says {_SPELLING[key]}={declared} but the "
                             f"file holds {actual} {what}")
    if found:
        warnings.warn(f"{path}: {'; '.join(found)}; the rows and columns present are used (as "
                      "OpenSim does) -- is the file truncated?", MotionFileWarning, stacklevel=3)


def _check_ranges(q, columns, coords, in_degrees, path):
    """ONE warning naming the coordinates whose values lie far outside their range."""
    far = []
    for index in sorted(columns):
        c = coords[index]
        slack = _RANGE_SLACK.get(c.motion_type)
        lo, hi = (float(x) for x in c.range)
        if slack is None or not (np.isfinite(lo) and np.isfinite(hi)) or hi < lo:
            continue
        margin = max(hi - lo, slack)
        values = q[:, index]
        worst = float(np.max(np.maximum(lo - values, values - hi)))
        if worst > margin:
            value = values[int(np.argmax(np.maximum(lo - values, values - hi)))]
            if c.motion_type == "rotational":
                far.append(f"{c.name} reaches {np.degrees(value):.6g} deg (range "
                           f"{np.degrees(lo):.4g} to {np.degrees(hi):.4g} deg)")
            else:
                far.append(f"{c.name} reaches {value:.6g} (range {lo:.4g} to {hi:.4g})")
    if far:
        unit = "degrees" if in_degrees else "radians"
        warnings.warn(f"{path}: values far outside the coordinate ranges: {'; '.join(far[:5])}"
                      f"{' ...' if len(far) > 5 else ''}; the file was read in {unit} -- check "
                      "inDegrees and the columns", MotionFileWarning, stacklevel=3)


def _split_labels(line: str):
    parts = line.split("\t") if "\t" in line else line.split()
    return [p.strip() for p in parts]


def _read_labels(lines, end_line, path):
    for number in range(end_line + 1, len(lines) + 1):
        line = lines[number - 1]
        if line.strip():
            labels = _split_labels(line.strip())
            if any(not label for label in labels):
                raise InputError("an empty column label", file=path, where=f"line {number}",
                                 fix="Give every column a label, separated by single tabs.")
            return labels, number
    raise InputError("no column labels after 'endheader'", file=path, where=f"line {end_line}",
                     fix="Add a line of column labels (time, then coordinate names) and the rows.")


def _read_numbers(lines, label_line, labels, path):
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


def _check_time(time, row_lines, path):
    step = np.diff(time)
    bad = np.flatnonzero(~(step > 0))
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(f"time is not increasing: {time[i]:.9g} s follows {time[i - 1]:.9g} s",
                         file=path, where=f"line {row_lines[i]}",
                         fix="Sort the rows by time and remove duplicated time steps.")


def _match_columns(labels, model, label_line, path):
    """Map model coordinate index -> file column, and list the unknown labels (in file order)."""
    names = tuple(model.coordinate_names)
    known = set(names)
    joint_of = {c.name: c.joint for c in model.coordinates}
    columns, unknown, first_label = {}, [], {}
    for column, label in enumerate(labels[1:], start=1):
        coordinate = _coordinate_of(label, known, joint_of)
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
        raise InputError(f"no column is a coordinate of model '{_model_name(model)}' "
                         f"(columns: {shown or 'none'}; model coordinates: {model_names})",
                         file=path, where=f"line {label_line}",
                         fix="Pass the motion made for this model, or rename the columns to the "
                             "model's coordinate names.")
    return columns, unknown


def _coordinate_of(label, known, joint_of):
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


# ----------------------------------------------------------------------------- writing


def write_sto(path, time, columns, *, in_degrees=False, name=None) -> Path:
    """Write a version-1 OpenSim storage file (.sto/.mot) that ``opensim.Storage`` reads.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write; written to a temporary name and renamed (never half-written).
    time : (F,) float
        Strictly increasing times in seconds.
    columns : dict str -> (F,) float, or pandas.DataFrame
        Column label -> values, written as given (labels must not contain tabs or newlines).
    in_degrees : bool, keyword-only
        The value of the ``inDegrees`` header flag: say ``True`` only if the rotational
        columns you pass are in degrees. Values are never converted.
    name : str, keyword-only
        The first header line (default: the file's stem).

    Returns
    -------
    pathlib.Path
        The written path.
    """
    path = Path(path)
    time = np.asarray(time, dtype=float).reshape(-1)
    if hasattr(columns, "columns") and hasattr(columns, "to_numpy"):  # a DataFrame
        labels = [str(c) for c in columns.columns]
        values = columns.to_numpy(dtype=float)
    else:
        labels = [str(c) for c in columns]
        values = np.column_stack([np.asarray(columns[c], dtype=float).reshape(-1)
                                  for c in columns]) if labels else np.empty((time.size, 0))
    if values.shape[0] != time.shape[0]:
        raise ValueError(f"columns have {values.shape[0]} rows but time has {time.shape[0]}")
    if time.size == 0:
        raise ValueError("time is empty: a motion needs at least one frame")
    if time.size > 1 and not np.all(np.diff(time) > 0):
        raise ValueError("time must be strictly increasing")
    for label in labels:
        if not label or label.strip() != label or any(ch in label for ch in "\t\r\n"):
            raise ValueError(f"column label {label!r} is empty or holds tabs, newlines or "
                             "surrounding spaces")
    if "time" in labels:
        raise ValueError("pass time separately, not as a column named 'time'")
    if len(set(labels)) != len(labels):
        raise ValueError("duplicated column labels")
    table = np.column_stack([time, values])
    if not np.all(np.isfinite(table)):
        raise ValueError("time and values must be finite (no NaN or infinity)")
    title = path.stem if name is None else str(name)
    if not title.strip() or "\n" in title or "=" in title or title.strip().lower() == "endheader":
        raise ValueError(f"name {title!r} cannot be a header line")
    head = (f"{title}\nversion=1\nnRows={table.shape[0]}\nnColumns={table.shape[1]}\n"
            f"inDegrees={'yes' if in_degrees else 'no'}\nendheader\n"
            + "\t".join(["time"] + labels) + "\n")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent or ".")
    try:
        with os.fdopen(fd, "w", newline="\n") as handle:
            handle.write(head)
            # %.17g: doubles survive the round trip exactly.
            np.savetxt(handle, table, fmt="%.17g", delimiter="\t")
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return path

