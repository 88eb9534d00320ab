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
overwritten by the lock or the coupler anyway). A caller that knows which coordinates its muscle
paths span passes them as ``spanned``: the missing ones among them get a warning of their own,
which says that they stay at their default value in every frame (the paths' lengths and moment
arms are then those of that pose), and the other missing ones a second warning.

``inDegrees=yes`` converts only the columns of *rotational* coordinates to radians; coupled and
translational coordinates are left as they are (OpenSim's ``SimbodyEngine::convertDegreesToRadians``
tests ``Coordinate::getMotionType() == Rotational``).

Every problem with the file is a `motion.errors.InputError` naming the file, the line and the fix.
"""
from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np

from ..errors import InputError, read_guarded
from .atomic_file import atomic_write
from .model import readonly_array
from .motion_table import check_time, match_columns, model_name, read_labels, read_numbers

__all__ = ["Motion", "MotionFileWarning", "load_motion", "write_sto"]

#: bytes read to decide whether a file is text
_SNIFF = 8192


class MotionFileWarning(UserWarning):
    """A motion file's column does not match the model (ignored or defaulted); the run goes on."""


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
        time = readonly_array(self.time)
        q = readonly_array(self.q)
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


def load_motion(path, model, *, spanned=None) -> Motion:
    """Read an OpenSim .mot or .sto file as the coordinates of ``model``; anything unexpected
    that goes wrong while reading it becomes one `InputError` naming the file.

    Parameters
    ----------
    path : str or os.PathLike
    model : motion.Model
    spanned : collection of str, optional, keyword-only
        Coordinates the caller's muscle paths span: missing ones among them are named in a
        warning of their own (module docstring).

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
        Once for the unknown columns, once for the missing coordinates (twice with ``spanned``:
        the spanned ones, the others), once for header counts
        that disagree with the data, once for values far outside coordinate ranges (see module
        docstring).
    """
    spanned = None if spanned is None else frozenset(spanned)
    return read_guarded(lambda: _load_motion(path, model, spanned), path, what="motion file",
                        fix="Export the motion again from OpenSim (a header, 'endheader', labels, "
                            "rows of numbers).")


def _load_motion(path, model, spanned=None) -> Motion:
    path = Path(path)
    text = _read_text(path)
    lines = text.splitlines()
    header, end_line = _read_header(lines, path)
    in_degrees = _in_degrees(header, path)
    labels, label_line = read_labels(lines, end_line, path)
    data, row_lines = read_numbers(lines, label_line, labels, path)
    time = data[:, 0]
    check_time(time, row_lines, path)
    _check_counts(header, data.shape, path)

    columns, unknown = match_columns(labels, model, label_line, path)
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
                      f"coordinates of model '{model_name(model)}': {', '.join(unknown)}",
                      MotionFileWarning, stacklevel=3)
    silent = _locked_or_dependent(model)
    loud = [n for n in missing if n not in silent]
    held = [] if spanned is None else [n for n in loud if n in spanned]
    if held:
        values = ", ".join(f"{n} = {_shown_default(coords[names.index(n)])}" for n in held)
        warnings.warn(f"{path}: {len(held)} coordinate(s) that the selected muscles' paths span are "
                      f"not in the file, so they stay at their default value in every frame: {values}",
                      MotionFileWarning, stacklevel=3)
    rest = [n for n in loud if n not in held]
    if rest:
        other = "" if spanned is None else " other"
        beside = "" if spanned is None else " (no selected muscle path spans them)"
        warnings.warn(f"{path}: {len(rest)}{other} coordinate(s) of model '{model_name(model)}' are not "
                      f"in the file and keep their default value{beside}: {', '.join(rest)}",
                      MotionFileWarning, stacklevel=3)
    return Motion(time=time, q=q, coordinate_names=names, source=str(path), in_degrees=in_degrees,
                  missing=missing, unknown=tuple(unknown))


def _shown_default(coordinate) -> str:
    """A coordinate's default value as a person reads it: degrees or metres."""
    if coordinate.motion_type == "rotational":
        return f"{np.degrees(coordinate.default_value):.4g} deg"
    return f"{coordinate.default_value:.4g}" + (" m" if coordinate.motion_type == "translational" else "")


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
    with atomic_write(path) as tmp, open(tmp, "w", newline="\n") as handle:
        handle.write(head)
        # repr: the shortest text that reads back as the same double (0.03, not %.17g's
        # 0.029999999999999999), so the round trip stays exact
        handle.writelines("\t".join(map(repr, row)) + "\n" for row in table.tolist())
    return path

