"""Ctrl-C (SIGINT) honoured at every stage of a command: exit 130, no traceback, nothing half-written.

Python turns SIGINT into a `KeyboardInterrupt` raised wherever the main thread happens to be.
That is not enough on its own:

- a third-party ``except BaseException:`` (seen during a lazy import) can swallow it, and the
  run then finishes with exit status 0 as if nothing had been asked;
- worker threads (``--jobs``) never see it;
- an interrupt in the middle of moving the finished files into the output folder would leave a
  mix of two runs.

So the command line installs `handler` (inside `honoured`): it records the request in a flag
*and* raises `KeyboardInterrupt` as usual. The run calls `check` between stages and between
muscles (threads included), which raises again if the flag is set, whoever swallowed the first
exception; the command returns 130 whenever the flag is set. `deferred` holds an interrupt back
for the few milliseconds in which finished files are moved into place, and raises it afterwards.

Without `honoured` (the Python API) nothing is installed: `check` only looks at the flag, which
stays clear, and Ctrl-C behaves as Python's default.

Before `honoured` there is the time in which Python loads the packages (about 0.2 s: numpy,
pandas ...). When the process *is* the ``fibres`` command (``fibres ...`` or ``python -m
analysis.cli``, `is_the_command`), ``analysis/__init__.py`` calls `install_early` first thing:
a Ctrl-C then ends the process at once with status 130 and one line, as nothing has started
and nothing needs cleaning up (instead of Python's traceback from inside an import). Only the
interpreter's own start-up (tens of milliseconds, before any of our code runs) is left to
Python's default handling.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

__all__ = ["honoured", "deferred", "check", "requested", "clear", "install_early", "is_the_command",
           "exit_now"]

_FLAG = threading.Event()
_DEFERRING = threading.Event()


def handler(signum, frame):  # noqa: ARG001 - signal API
    """SIGINT handler: remember the request; raise KeyboardInterrupt unless inside `deferred`."""
    _FLAG.set()
    if not _DEFERRING.is_set():
        raise KeyboardInterrupt


def is_the_command() -> bool:
    """Whether this process is the ``fibres`` command line (not a library user)."""
    if os.path.basename(sys.argv[0] if sys.argv else "").lower() in ("fibres", "fibres.exe",
                                                                      "fibres-script.py"):
        return True
    orig = list(getattr(sys, "orig_argv", ()))
    return any(a == "-m" and orig[i + 1:i + 2] == ["analysis.cli"] for i, a in enumerate(orig))


def _early(signum, frame):  # noqa: ARG001 - signal API
    try:
        sys.stderr.write("fibres: interrupted while starting; nothing was written.\n")
        sys.stderr.flush()
    finally:
        os._exit(130)


def install_early() -> None:
    """SIGINT -> exit 130 at once, while the command's packages load (module docstring)."""
    if threading.current_thread() is threading.main_thread() and \
            signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _early)


def requested() -> bool:
    """Whether Ctrl-C was pressed since `honoured` was entered."""
    return _FLAG.is_set()


def clear() -> None:
    """Forget an earlier request (a new command starts)."""
    _FLAG.clear()


def check() -> None:
    """Raise `KeyboardInterrupt` if Ctrl-C was pressed (also in worker threads)."""
    if _FLAG.is_set():
        raise KeyboardInterrupt


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _unraisable(previous):
    """``sys.unraisablehook`` that drops a KeyboardInterrupt raised where Python cannot raise it
    (a ``__del__``, a weakref callback): the flag is set, so the next `check` raises it. Python
    would print "Exception ignored in ... Traceback ... KeyboardInterrupt" and go on."""
    def hook(unraisable):
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and _FLAG.is_set():
            return
        previous(unraisable)
    return hook


@contextlib.contextmanager
def honoured():
    """Install `handler` for SIGINT for the duration of a command (main thread only)."""
    clear()
    if not _main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, handler)
    previous_hook = sys.unraisablehook
    sys.unraisablehook = _unraisable(previous_hook)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = previous_hook
        # the command has read the request (`requested`) by now: a stale flag would make the next
        # `check` outside any command (the Python API, a test) raise
        _FLAG.clear()


def exit_now(code: int):
    """End the command process with ``code`` at once (`is_the_command` only): the files are
    written and closed, so the interpreter's finalization (up to a second of freeing arrays and
    tearing down libraries, during which Python resets SIGINT to its default and a Ctrl-C killed
    the process silently) is skipped. SIGINT is ignored from here on: the work is complete."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)


@contextlib.contextmanager
def deferred():
    """Hold Ctrl-C back while the block runs (moving finished files into place); raise it after.

    Only effective under `honoured` in the main thread; elsewhere a plain block."""
    if not _main_thread() or signal.getsignal(signal.SIGINT) is not handler:
        yield
        return
    _DEFERRING.set()
    try:
        yield
    finally:
        _DEFERRING.clear()
    check()
