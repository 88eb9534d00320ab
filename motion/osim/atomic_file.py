"""Writing a file atomically: whole under a temporary name beside it, then renamed into place.

`atomic_write(path)` yields a new, empty temporary file ``.<name>.<8 hex digits>.part`` in
``path``'s folder; when the block succeeds it is renamed to ``path`` (``os.replace``: atomic on
POSIX and Windows within one file system, so a reader sees the old file or the new one, never a
part). When the block raises anything (``KeyboardInterrupt`` too) the temporary file is removed
and ``path`` is left as it was. A process killed in between leaves only a ``.*.part`` file, which
``fibres run`` clears from its output folder (`analysis.out_folder`).

Permissions: the file gets what ``open(path, "w")`` would give a new file, ``0o666`` less the
process umask (``0o644`` under the usual umask 022), not ``tempfile.mkstemp``'s ``0o600``. The
temporary file is created with that mode by ``os.open``, so the kernel applies the umask; reading
the umask instead would mean setting it, which races with other threads creating files.

Used by the model and motion writers here (`motion.osim.builder`, `motion.osim.motion_file`), by
`analysis.output_files` (every output of the command line) and by ``models/make_example.py``.
"""
from __future__ import annotations

import contextlib
import os
import secrets
from pathlib import Path

__all__ = ["atomic_write"]

#: attempts at a free temporary name (each has 32 random bits)
_TRIES = 100


@contextlib.contextmanager
def atomic_write(path):
    """Yield a temporary `Path` beside ``path``; rename it to ``path`` if the block succeeds,
    remove it if the block raises (module docstring).

    Examples
    --------
    >>> with atomic_write("out/model.osim") as tmp:   # doctest: +SKIP
    ...     tmp.write_text(xml)
    """
    path = Path(path)
    tmp = _new_file_beside(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _new_file_beside(path: Path) -> Path:
    """Create an empty file ``.<name>.<hex>.part`` in ``path``'s folder with mode 0o666 less
    the umask, failing rather than reusing an existing name (``O_EXCL``)."""
    for _ in range(_TRIES):
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.part"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return tmp
    raise FileExistsError(f"no free temporary name beside {path} after {_TRIES} tries")
