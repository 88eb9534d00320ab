"""Writing output files atomically: a failed or interrupted run never leaves a half-written file.

Every file is written to a temporary name in the destination folder and renamed into place
(`motion.osim.atomic_file`: ``os.replace`` is atomic on POSIX and Windows within one file system;
the file gets the usual permissions, 0o666 less the umask). Inside `confined_to`
(the staging folder of ``fibres run``) files are written in place: the staging folder is itself
the unit of atomicity (its files are published only after every one was written, and it is
removed on any failure), so a temporary name and a rename per file would add nothing.

Inside `confined_to(folder)` (the staging folder of `fibres run`) every path handed to
`atomic_path` is checked first: it must lie inside that folder once resolved (no ``..``, no
symlink out), and no two outputs of the run may land on the same file. A violation is an
InputError, raised before anything is written. File names built from names in the input files
are made safe beforehand (`analysis.file_names`); this check is the second line of defence.
"""
from __future__ import annotations

import contextlib
import contextvars
import os
from pathlib import Path

from motion.osim.atomic_file import atomic_write

from .errors import InputError

__all__ = ["atomic_path", "write_csv", "write_text", "prepare_out_dir", "confined_to", "checked_path"]

#: (resolved root folder, paths written, resolved folders by name), strings, inside `confined_to`
_CONFINED = contextvars.ContextVar("analysis_output_root", default=None)


@contextlib.contextmanager
def confined_to(folder):
    """Within the block, `atomic_path` refuses any path outside ``folder`` (module docstring)."""
    token = _CONFINED.set((os.fspath(Path(folder).resolve()), set(), {}))
    try:
        yield
    finally:
        _CONFINED.reset(token)


def checked_path(path) -> Path:
    """``path``, after checking it against the `confined_to` folder (if any); InputError if it
    would leave that folder or was already written by this run."""
    path = Path(path)
    state = _CONFINED.get()
    if state is None:
        return path
    root, seen, folders = state
    head, name = os.path.split(os.fspath(path))
    # each folder is resolved once per run (thousands of frame files share one); the checks are
    # on the strings of resolved, normalised paths (what `Path.is_relative_to` compares)
    parent = folders.get(head)
    if parent is None:
        parent = folders[head] = os.fspath(Path(head or ".").resolve())
    full = os.path.join(parent, name)
    if name in ("", ".", "..") or full == root or not full.startswith(root.rstrip(os.sep) + os.sep):
        raise InputError("refused to write a file outside the output folder", file=path,
                         fix="Report this: a name in the input files was not made safe.")
    key = os.path.normcase(full)           # the same file for the file system's path equality
    if key in seen:
        raise InputError("two outputs of this run would be written to the same file", file=path,
                         fix="Give the muscles (and coordinates) names that differ in more than "
                             "upper/lower case.")
    seen.add(key)
    return path


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; rename it to ``path`` only if the block succeeds
    (inside `confined_to`: ``path`` itself, after `checked_path`; module docstring).

    Examples
    --------
    >>> with atomic_path("out/table.csv") as tmp:   # doctest: +SKIP
    ...     frame.to_csv(tmp, index=False)
    """
    path = checked_path(path)
    if _CONFINED.get() is not None:   # the staging folder: written whole or removed (module docstring)
        yield path
        return
    with atomic_write(path) as tmp:
        yield tmp


def write_csv(frame, path):
    """Write a pandas DataFrame as CSV (no index, 12 significant digits: `analysis.csv_text`),
    atomically."""
    from .csv_text import csv_bytes

    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(csv_bytes(frame))


def write_text(text: str, path):
    """Write text atomically."""
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text)


def prepare_out_dir(out_dir) -> Path:
    """Create ``out_dir`` if needed and check it is a writable folder, or raise InputError."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError("the output folder is a file", file=out,
                         fix="Pass --out a folder name (or remove the file).")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder ({exc.strerror})", file=out,
                         fix="Choose a folder you can write to with --out.") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError("the output folder is not writable", file=out,
                         fix="Choose a folder you can write to with --out.")
    return out
