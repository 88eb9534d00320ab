"""The library's thread policy: its own numerical calls run with ONE BLAS thread.

Contract: `one_blas_thread` is a context manager (and `blas_single` a decorator) under which the
BLAS libraries loaded in the process (OpenBLAS, MKL, BLIS: whatever numpy and scipy use) run
single-threaded; on leaving, their earlier limits come back. Nested and concurrent uses (several
threads decomposing at once) are counted: the limit is set by the first to enter and restored
by the last to leave, under a lock, so no thread restores the limits while another still works.

Why: the decomposition's BLAS calls are small (3 x 3 frames against a few thousand vertices,
small least squares); a BLAS thread pool gains nothing on them and, on a busy machine or beside
other processes, its spinning threads oversubscribe the cores (measurements: bench/README.md,
``bench/threads.py``). Parallelism comes from our own level instead: muscles, frames, processes
(``fibres run --jobs``), Dask workers. Method: threadpoolctl's `ThreadpoolController.limit`
(one controller, made once: listing the loaded libraries costs more than the limit itself).
No compiled (numba) code of the package runs in parallel, so numba's threads need no limit.
"""
from __future__ import annotations

import functools
import threading
from contextlib import contextmanager

__all__ = ["one_blas_thread", "blas_single"]

_LOCK = threading.Lock()
_STATE = {"depth": 0, "saved": None, "controller": None}


def _controller():
    if _STATE["controller"] is None:
        import scipy.linalg  # noqa: F401  (loads scipy's BLAS, so that the controller sees it)
        from threadpoolctl import ThreadpoolController

        _STATE["controller"] = ThreadpoolController()
    return _STATE["controller"]


@contextmanager
def one_blas_thread():
    """Run the block with one BLAS thread (module docstring); nestable and thread-safe."""
    with _LOCK:
        if _STATE["depth"] == 0:
            _STATE["saved"] = _controller().limit(limits=1, user_api="blas")
        _STATE["depth"] += 1
    try:
        yield
    finally:
        with _LOCK:
            _STATE["depth"] -= 1
            if _STATE["depth"] == 0:
                _STATE["saved"].restore_original_limits()
                _STATE["saved"] = None


def blas_single(fn):
    """Decorator: ``fn`` runs under `one_blas_thread`."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with one_blas_thread():
            return fn(*args, **kwargs)
    return wrapper
