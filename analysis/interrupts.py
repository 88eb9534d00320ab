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
"""
from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["honoured", "deferred", "check", "requested", "clear"]

_FLAG = threading.Event()
_DEFERRING = threading.Event()


def handler(signum, frame):  # noqa: ARG001 - signal API
    """SIGINT handler: remember the request; raise KeyboardInterrupt unless inside `deferred`."""
    _FLAG.set()
    if not _DEFERRING.is_set():
        raise KeyboardInterrupt


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


@contextlib.contextmanager
def honoured():
    """Install `handler` for SIGINT for the duration of a command (main thread only)."""
    clear()
    if not _main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


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
