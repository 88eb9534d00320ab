"""The output folder (``--out``) is owned by the run writing into it.

Rules (docs/INTERFACE.md, "The output folder"):

- **Refused folders.** The root of a file system, the home folder, and any folder that holds a
  git repository (``.git``), a Python project (``pyproject.toml``, ``setup.py``, ``setup.cfg``),
  is a Python package (``__init__.py``) or holds one (a sub-folder with ``__init__.py``): a run
  there would scatter its files among the user's own (``--out .`` at the project root used to
  drop files into the ``fibres/`` package). ``--force`` writes there anyway.
- **One run at a time.** `OutFolderLock` takes an exclusive, non-blocking ``flock`` on
  ``DIR/.fibres-lock`` before the long computation starts and keeps it until every file is in
  place; a second run into the same folder refuses at once (exit 2) instead of mixing its files
  with the first's. The kernel drops the lock when a process dies, even by SIGKILL, so a killed
  run never blocks the next one.
- **A manifest, and no files of an earlier run left behind.** ``run.json`` lists every file the
  run wrote (``files``, paths relative to DIR). The next run into the folder *removes* the files
  listed by the previous ``run.json`` that it does not write itself (a run with fewer frames or
  muscles leaves no stale ``.vtp``, ``.pvd`` or plot), then publishes its own. Files that no
  ``run.json`` lists -- the user's own -- are never touched. While files are being moved into
  place, ``DIR/.fibres-publish.json`` lists the union of the old and new files, so that a run
  killed in those milliseconds is still cleaned up by the next one.
- **Stale staging cleaned.** Each run writes into a hidden staging folder ``DIR/.fibres-run-*``
  and moves the files into place at the end (`publish`); staging folders and ``.*.part`` files
  left by a killed run are removed by the next run once it holds the lock.
"""
from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
from pathlib import Path, PurePosixPath

from . import interrupts
from .errors import InputError

__all__ = ["refusal", "check_out_folder", "OutFolderLock", "clean_stale", "previous_files",
           "publish", "LOCK_NAME", "JOURNAL_NAME", "STAGING_PREFIX"]

LOCK_NAME = ".fibres-lock"
JOURNAL_NAME = ".fibres-publish.json"
STAGING_PREFIX = ".fibres-run-"
_PART = re.compile(r"\..+\.part\Z")
_PROJECT_MARKERS = ("pyproject.toml", "setup.py", "setup.cfg")
#: sub-folders looked at for a Python package (a huge folder is not scanned to the end)
_SCAN_LIMIT = 2000


def refusal(out) -> str | None:
    """Why ``out`` must not be used as an output folder without ``--force``, or None."""
    folder = Path(out).resolve()
    if folder == Path(folder.anchor):
        return "is the root of the file system"
    with contextlib.suppress(RuntimeError, KeyError):   # no home folder known
        if folder == Path.home().resolve():
            return "is your home folder"
    if not folder.is_dir():
        return None
    if (folder / ".git").exists():
        return "holds a git repository (.git)"
    if (folder / "__init__.py").is_file():
        return "is a Python package (it holds __init__.py)"
    for marker in _PROJECT_MARKERS:
        if (folder / marker).is_file():
            return f"holds a Python project ({marker})"
    with contextlib.suppress(OSError):
        with os.scandir(folder) as entries:
            for k, entry in enumerate(entries):
                if k >= _SCAN_LIMIT:
                    break
                if entry.is_dir(follow_symlinks=False) and os.path.isfile(
                        os.path.join(entry.path, "__init__.py")):
                    return f"holds the Python package {entry.name}/"
    return None


def check_out_folder(out, *, force: bool = False) -> None:
    """Raise InputError if ``out`` is a refused folder (module docstring) and not ``force``."""
    why = None if force else refusal(out)
    if why:
        raise InputError(f"the output folder {why}; a run would mix its files with yours", file=out,
                         where="--out", fix="Choose an empty or new folder with --out, or pass --force.")


class OutFolderLock:
    """An exclusive lock on an output folder (``DIR/.fibres-lock``), held by one run at a time.

    Use as a context manager; `acquire` raises InputError at once if another process holds it.
    The lock file holds the owner's process id (for the message) and is removed on release.
    """

    def __init__(self, out):
        self.out = Path(out)
        self.path = self.out / LOCK_NAME
        self.fd = None

    def acquire(self):
        for _ in range(100):   # retry only while the file is replaced under us
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise InputError(f"the output folder is not writable ({exc.strerror})", file=self.out,
                                 where="--out", fix="Choose a folder you can write to with --out.") from None
            try:
                if not _try_lock(fd):
                    owner = _read_pid(fd)
                    raise InputError(f"another fibres run{f' (process {owner})' if owner else ''} "
                                     "is writing into this folder", file=self.out, where="--out",
                                     fix="Wait for it to finish, or choose another folder with --out.")
                try:
                    same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
                except FileNotFoundError:
                    same = False
                if not same:          # the holder removed it between our open and our lock
                    os.close(fd)
                    continue
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
                self.fd = fd
                return self
            except BaseException:
                if self.fd is None:
                    with contextlib.suppress(OSError):
                        os.close(fd)
                raise
        raise InputError("cannot take the output folder's lock", file=self.path,
                         fix="Remove the file if no fibres run is writing into the folder.")

    def release(self):
        if self.fd is None:
            return
        with contextlib.suppress(OSError):
            if os.name == "posix":        # removed while still held: nobody can lock a stale copy
                os.unlink(self.path)
        with contextlib.suppress(OSError):
            os.close(self.fd)
        self.fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()
        return False


def _try_lock(fd) -> bool:
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        import msvcrt

        try:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
            return True
        except OSError:
            return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except (BlockingIOError, PermissionError):
        return False


def _read_pid(fd):
    with contextlib.suppress(OSError, ValueError):
        return int(os.pread(fd, 32, 0).decode().strip() or 0) or None
    return None


def clean_stale(out) -> list:
    """Remove staging folders and ``.*.part`` files that killed runs left in ``out`` (and in its
    ``plots/`` and ``fibres/``); call only while holding the lock. Returns what was removed."""
    out = Path(out)
    removed = []
    for folder in (out, out / "plots", out / "fibres"):
        if not folder.is_dir() or folder.is_symlink():
            continue
        for entry in list(folder.iterdir()):
            if entry.name.startswith(STAGING_PREFIX) and entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
                removed.append(entry)
            elif _PART.match(entry.name) and entry.is_file():
                with contextlib.suppress(OSError):
                    entry.unlink()
                    removed.append(entry)
    return removed


def _relative(name) -> str | None:
    """A manifest entry as a safe relative POSIX path, or None if it is not one."""
    if not isinstance(name, str) or not name or "\x00" in name or "\\" in name:
        return None
    p = PurePosixPath(name)
    if p.is_absolute() or any(part in ("", ".", "..") for part in p.parts):
        return None
    return p.as_posix()


def _listed(path: Path) -> set:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return set()
    if not isinstance(data, dict) or not isinstance(data.get("files"), list):
        return set()
    return {r for r in map(_relative, data["files"]) if r}


def previous_files(out) -> set:
    """Relative paths an earlier run wrote into ``out``: its ``run.json`` manifest (only a
    musclefibres run.json) and the publishing journal of a run killed while publishing."""
    out = Path(out)
    run_json = out / "run.json"
    owned = set()
    with contextlib.suppress(OSError, ValueError):
        if json.loads(run_json.read_text(encoding="utf-8")).get("tool") == "musclefibres":
            owned |= _listed(run_json)
    return owned | _listed(out / JOURNAL_NAME)


def staged_files(staging) -> list:
    """Relative POSIX paths of every file in the staging folder, ``run.json`` last."""
    staging = Path(staging)
    rel = [p.relative_to(staging).as_posix() for p in staging.rglob("*") if p.is_file()]
    return sorted(rel, key=lambda r: (r == "run.json", r))


def _remove_stale(out: Path, rel: str):
    path = out / rel
    parent = path.parent.resolve()
    if not (parent == out.resolve() or parent.is_relative_to(out.resolve())):
        return                               # a symlinked folder pointing elsewhere: not ours
    if path.is_symlink() or path.is_file():
        with contextlib.suppress(OSError):
            path.unlink()
    folder = path.parent
    while folder != out:                      # drop folders that became empty (plots/, fibres/)
        try:
            folder.rmdir()
        except OSError:
            break
        folder = folder.parent


def publish(staging, out) -> list:
    """Move every staged file to its place in ``out`` (``run.json`` last), remove the files of
    the previous run that this run did not write, and return the final paths.

    Ctrl-C is held back (`interrupts.deferred`) until the folder holds exactly this run's files.
    """
    from .output_files import write_text

    staging, out = Path(staging), Path(out)
    new = staged_files(staging)
    old = previous_files(out)
    written = []
    with interrupts.deferred():
        write_text(json.dumps({"files": sorted(old | set(new))}) + "\n", out / JOURNAL_NAME)
        # a staged folder with no counterpart in DIR yet (fibres/, scene/ of a first run) moves
        # in one rename: no file of the previous run can be inside it
        moved = {top for top in {PurePosixPath(rel).parts[0] for rel in new if "/" in rel}
                 if not os.path.lexists(out / top)}
        for top in sorted(moved):
            os.replace(staging / top, out / top)
        for rel in new:
            if rel == "run.json":
                continue
            dst = out / rel
            if PurePosixPath(rel).parts[0] not in moved:
                dst.parent.mkdir(parents=True, exist_ok=True)
                os.replace(staging / rel, dst)
            written.append(dst)
        for rel in sorted(old - set(new)):
            _remove_stale(out, rel)
        if "run.json" in new:
            os.replace(staging / "run.json", out / "run.json")
            written.append(out / "run.json")
        with contextlib.suppress(FileNotFoundError):
            (out / JOURNAL_NAME).unlink()
    return written
