"""The study file (TOML) of ``fibres study``: subjects, their fibre models and trials, and the
``fibres run`` options of every trial.

Layout (paths relative to the study file)::

    [options]                       # any `fibres run` option, for every trial
    fibres = 50
    frames = "0:40"
    no-plots = true                 # flags: the option's name (`no-plots`, `no_plots`) = true,
                                    # or its positive form `plots = false`
    [subjects.S01]
    model = "S01/fibres.toml"       # the subject's fibre model
    trials = ["S01/walk*.mot", "S01/stairs.mot"]   # motion files or glob patterns
    options = { fibres = 80 }       # optional: this subject's own options over [options]
    [subjects.S02]
    model = "S02/fibres.toml"
    trials = ["S02/*.mot",          # a trial's own options: a table, over the subject's
              { motion = "S02/run.mot", options = { frames = "12:140" } }]

A trial is one motion file; its name is the file name without its extension (``walk1`` for
``walk1.mot``) and its outputs go to ``DIR/<subject>/<trial>/``. Options apply in the order
``[options]``, the subject's ``options``, the trial entry's ``options`` (each over the one
before); a file named by two entries (a glob, then a table for one of its files) keeps its first
place and takes the later entry's options. Subject and trial names become
folder names only through `analysis.file_names.file_stems` (the name itself when it is safe).

Method: the option names and types are those of the ``fibres run`` parser itself
(`analysis.cli_run.add_arguments`), so a new ``fibres run`` option is a study option at once.
Options that name the trial's own inputs or outputs (``spec``, ``motion``, ``setup``, ``out``)
and ``force``/``quiet`` are not study options (the study sets them). Every value is type-checked
here, before any work, and a wrong one is one `InputError` naming the file, the key and the fix.
A literal trial path that does not exist and a glob that matches no file are errors too; a
motion that exists but cannot be read is the trial's own failure, reported when it runs.
"""
from __future__ import annotations

import argparse
import dataclasses
import glob
import sys
from pathlib import Path

from .errors import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["Study", "StudyTrial", "load_study", "run_arguments", "run_parser", "RESERVED_NAMES"]

#: `fibres run` arguments the study sets itself (module docstring)
_NOT_OPTIONS = {"spec", "motion", "setup", "out", "force", "quiet", "help", "debug"}
_SUBJECT_KEYS = ("model", "trials", "options")
#: names a subject may not have: the study's own files in DIR
RESERVED_NAMES = ("study.json", "study.parquet")


@dataclasses.dataclass(frozen=True)
class StudyTrial:
    """One (subject, trial): the fibre model, the motion, the options and the output folder.

    ``folder`` is relative to the study's output folder: ``<subject stem>/<trial stem>``;
    ``options`` maps `fibres run` argument names (argparse ``dest``) to checked TOML values.
    """
    subject: str
    trial: str
    spec: Path
    motion: Path
    options: dict
    folder: str

    @property
    def label(self) -> str:
        return f"{self.subject}/{self.trial}"


@dataclasses.dataclass(frozen=True)
class Study:
    """A parsed study file: its path, its subjects (in file order) and every trial."""
    file: Path
    subjects: tuple
    trials: tuple

    def subject_trials(self, subject: str) -> tuple:
        return tuple(t for t in self.trials if t.subject == subject)


def run_parser() -> argparse.ArgumentParser:
    """The ``fibres run`` argument parser (its options are the study's options)."""
    from .cli_run import add_arguments

    parser = argparse.ArgumentParser(prog="fibres run", add_help=False)
    add_arguments(parser)
    return parser


def _option_table(parser) -> dict:
    """TOML key -> (action, negated): every ``--long-option`` of ``fibres run`` by its name with
    ``-`` or ``_``, plus ``plots``/``scene`` ... for the flags named ``no-...``."""
    table = {}
    for action in parser._actions:   # the parser's own option list (argparse has no public one)
        if action.dest in _NOT_OPTIONS:
            continue
        for flag in action.option_strings:
            if flag.startswith("--"):
                table[flag[2:].replace("-", "_")] = (action, False)
    for key, (action, _) in list(table.items()):
        if key.startswith("no_") and key[3:] not in table and action.nargs == 0:
            table[key[3:]] = (action, True)
    return table


def _checked_value(key, value, action, negated, *, file, where):
    """The TOML ``value`` of option ``key`` checked against its argparse ``action``; returns the
    (dest, value) to set on the parsed `fibres run` arguments."""
    def bad(expected, fix):
        return InputError(f"{expected}, got {value!r}", file=file, where=where, fix=fix)

    if action.nargs == 0:                          # a flag: store_true / store_false
        if not isinstance(value, bool):
            raise bad("a flag takes true or false", f"Write {key} = true or {key} = false.")
        stored = action.const if value else not action.const
        return action.dest, (not stored) if negated else stored
    if isinstance(action, argparse._AppendAction):   # --muscle NAME (repeatable)
        items = [value] if isinstance(value, str) else value
        if not isinstance(items, list) or not items or not all(isinstance(v, str) and v for v in items):
            raise bad("expected a name or a list of names", f'Write {key} = ["name", ...].')
        return action.dest, list(items)
    if action.type is int:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise bad("expected a whole number >= 1", f"Write {key} = 10, for example.")
        if key in ("fibres", "resolution"):        # the limits of the fibre model
            from .spec import check_count

            check_count(key, value, where=where, file=file)
        return action.dest, value
    if key == "max_memory" and isinstance(value, int) and not isinstance(value, bool):
        value = str(value)
    if not isinstance(value, str) or not value or "\x00" in value:
        raise bad("expected a text value", f'Write {key} = "..." (see fibres run --help).')
    if action.choices is not None and value not in action.choices:
        raise bad("unknown value", f"Use one of: {', '.join(map(str, action.choices))}.")
    if action.type is not None:                    # --frames: parsed as the command line does
        try:
            action.type(value)
        except (argparse.ArgumentTypeError, ValueError, TypeError) as exc:
            raise InputError(f"bad value {value!r} ({exc})", file=file, where=where,
                             fix="Write it as on the fibres run command line.") from None
    return action.dest, value


def _options(table, *, file, where, option_table) -> dict:
    if not isinstance(table, dict):
        raise InputError("expected a table of fibres run options", file=file, where=where,
                         fix=f"Write [{where}] with keys such as fibres = 50.")
    out = {}
    for key, value in table.items():
        name = key.replace("-", "_")
        if name not in option_table:
            hint = ("the study sets it" if name in _NOT_OPTIONS else
                    f"use one of: {', '.join(sorted(k for k in option_table if not k.startswith('no_')))}")
            raise InputError(f"not a study option ({hint})", file=file, where=f"{where}.{key}",
                             fix="Remove it, or use a fibres run option name.")
        action, negated = option_table[name]
        dest, val = _checked_value(name, value, action, negated, file=file, where=f"{where}.{key}")
        out[dest] = val
    return out


def _trial_paths(pattern, base: Path, *, file, where) -> list:
    """The motion files of one trial entry's path or glob ``pattern`` (module docstring)."""
    if not isinstance(pattern, str) or not pattern:
        raise InputError("expected a motion file or glob pattern", file=file, where=where,
                         fix='Write trials = ["walk*.mot", "stairs.mot"] (relative to the study file).')
    if "\x00" in pattern:
        raise InputError("a path holds a NUL character", file=file, where=where, fix="Remove it.")
    full = Path(pattern) if Path(pattern).is_absolute() else base / pattern
    if glob.has_magic(pattern):
        found = sorted(Path(p) for p in glob.glob(str(full)) if Path(p).is_file())
        if not found:
            raise InputError(f"the pattern {pattern!r} matches no file", file=file, where=where,
                             fix="Fix the pattern (it is relative to the study file).")
        return [p.resolve() for p in found]
    if not full.is_file():
        raise InputError(f"no motion file {pattern!r} ({full})", file=file, where=where,
                         fix="Fix the path (it is relative to the study file).")
    return [full.resolve()]


def _trial_entries(entries, base: Path, *, file, where, option_table) -> dict:
    """Motion file -> that trial's own options, from a subject's ``trials`` list: each entry a
    path or glob, or a table ``{ motion = PATH_OR_GLOB, options = {...} }``. A file named again
    by a later entry keeps its place and takes that entry's options over the earlier ones."""
    items = [entries] if isinstance(entries, (str, dict)) else entries
    if not isinstance(items, list) or not items:
        raise InputError("expected a list of motion files or glob patterns", file=file, where=where,
                         fix='Write trials = ["walk*.mot", "stairs.mot"] (relative to the study file).')
    found = {}
    for k, entry in enumerate(items):
        at = f"{where}[{k}]"
        own = {}
        if isinstance(entry, dict):
            extra = sorted(set(entry) - {"motion", "options"})
            if extra or "motion" not in entry:
                raise InputError(f"unknown key {extra[0]!r}" if extra else "missing motion", file=file,
                                 where=f"{at}.{extra[0]}" if extra else f"{at}.motion",
                                 fix='Write { motion = "run.mot", options = { frames = "10:120" } }.')
            own = _options(entry.get("options", {}), file=file, where=f"{at}.options",
                           option_table=option_table)
            entry = entry["motion"]
        for path in _trial_paths(entry, base, file=file, where=at):
            found[path] = {**found.get(path, {}), **own}
    return found


def load_study(path) -> Study:
    """Read and check a study file (module docstring); every problem is one `InputError`.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Study
    """
    from .file_names import file_stems

    file = Path(path)
    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("no such study file", file=file, fix="Check the path of STUDY.toml.") from None
    except (UnicodeDecodeError, IsADirectoryError, PermissionError):
        raise InputError("cannot read it as a text file", file=file, fix="Pass a study .toml file.") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML ({exc})", file=file, fix="Fix the TOML syntax (https://toml.io).") from None
    base = file.resolve().parent
    unknown = sorted(set(data) - {"options", "subjects"})
    if unknown:
        raise InputError(f"unknown top-level key {unknown[0]!r}", file=file, where=unknown[0],
                         fix="Use [options] and [subjects.<name>] tables.")
    option_table = _option_table(run_parser())
    common = _options(data.get("options", {}), file=file, where="options", option_table=option_table)
    subjects = data.get("subjects")
    if not isinstance(subjects, dict) or not subjects:
        raise InputError("no subjects", file=file, where="subjects",
                         fix='Add [subjects.S01] with model = "S01/fibres.toml" and trials = ["S01/*.mot"].')
    stems = file_stems(subjects)
    trials = []
    for name, table in subjects.items():
        where = f"subjects.{name}"
        if not name.strip() or any(ord(c) < 32 for c in name) or name in RESERVED_NAMES:
            raise InputError("not a usable subject name", file=file, where=where,
                             fix="Name subjects with letters, digits, '_' or '-' (not study.json/study.parquet).")
        if not isinstance(table, dict):
            raise InputError("expected a table", file=file, where=where,
                             fix=f'Write [{where}] with model = "..." and trials = [...].')
        extra = sorted(set(table) - set(_SUBJECT_KEYS))
        if extra:
            raise InputError(f"unknown key {extra[0]!r}", file=file, where=f"{where}.{extra[0]}",
                             fix=f"Use only: {', '.join(_SUBJECT_KEYS)}.")
        model = table.get("model")
        if not isinstance(model, str) or not model or "\x00" in model:
            raise InputError("missing or not a path", file=file, where=f"{where}.model",
                             fix='Write model = "<subject fibre model>.toml" (relative to the study file).')
        spec = (Path(model) if Path(model).is_absolute() else base / model).resolve()
        if not spec.is_file():
            raise InputError(f"no fibre model {model!r} ({spec})", file=file, where=f"{where}.model",
                             fix="Fix the path (it is relative to the study file).")
        if "trials" not in table:
            raise InputError("missing", file=file, where=f"{where}.trials",
                             fix='Write trials = ["walk*.mot"] (motion files or globs).')
        motions = _trial_entries(table["trials"], base, file=file, where=f"{where}.trials",
                                 option_table=option_table)
        options = {**common, **_options(table.get("options", {}), file=file, where=f"{where}.options",
                                        option_table=option_table)}
        seen = {}
        for mot in motions:
            if mot.stem in seen:
                raise InputError(f"two trials are named {mot.stem!r} ({seen[mot.stem]} and {mot})", file=file,
                                 where=f"{where}.trials", fix="Give the motion files different names.")
            seen[mot.stem] = mot
        trial_stems = file_stems(seen)
        for trial, mot in seen.items():
            trials.append(StudyTrial(subject=name, trial=trial, spec=spec, motion=mot,
                                     options={**options, **motions[mot]},
                                     folder=f"{stems[name]}/{trial_stems[trial]}"))
    return Study(file=file.resolve(), subjects=tuple(subjects), trials=tuple(trials))


def run_arguments(trial: StudyTrial, out_dir) -> argparse.Namespace:
    """The parsed ``fibres run`` arguments of a trial: its fibre model, ``--motion``, ``--out
    DIR/<subject>/<trial>``, ``--quiet``, and the study's options."""
    args = run_parser().parse_args([str(trial.spec), "--motion", str(trial.motion),
                                    "--out", str(Path(out_dir) / trial.folder), "--quiet"])
    table = _option_table(run_parser())
    for dest, value in trial.options.items():
        action = next(a for a, _ in table.values() if a.dest == dest)
        if action.type is not None and action.nargs != 0 and isinstance(value, str):
            value = action.type(value)
        setattr(args, dest, value)
    return args
