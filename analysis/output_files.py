"""Writing output files atomically: a failed or interrupted run never leaves a half-written file.

Every file is written to a temporary name in the destination folder and renamed into place
(``os.replace`` is atomic on POSIX and Windows within one file system).
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from .errors import InputError

__all__ = ["atomic_path", "write_csv", "write_text", "prepare_out_dir"]


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; rename it to ``path`` only if the block succeeds.

    Examples
    --------
    >>> with atomic_path("out/table.csv") as tmp:   # doctest: +SKIP
    ...     frame.to_csv(tmp, index=False)
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_csv(frame, path, *, float_format="%.12g"):
    """Write a pandas DataFrame as CSV (no index, >= 9 significant digits), atomically."""
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False, float_format=float_format)


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
