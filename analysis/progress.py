"""Progress for long work on stderr: a tqdm bar on a terminal; elsewhere (a log file, a pipe, a batch
job) one plain line per muscle done (``unit="muscle"``), so long runs are never silent; nothing with
``quiet=True``."""
from __future__ import annotations

import sys

__all__ = ["progress", "start_notice", "compile_notice", "kernels_cached", "stage_notice"]

#: What a first run in a new environment prints: numba compiles the package's kernels once per
#: environment and caches them on disk (timings: bench/README.md, "Cold start").
COMPILE_NOTICE = ("first run with this installation: compiling the numerical kernels "
                  "(about half a minute, once; later runs reuse them)")


def start_notice(what: str, quiet=False, *, compiling=None) -> bool:
    """Print ``fibres: <what>`` on stderr at once (unless quiet), so that a run is never silent
    before its first muscle is done (issue 13: progress within 5 s of starting). When the
    compiled kernels are not cached yet a second line says so (`compile_notice`): the first run
    in a new environment compiles before its first muscle is done. Returns whether anything was
    printed."""
    if quiet:
        return False
    print(f"fibres: {what}", file=sys.stderr, flush=True)
    compile_notice("fibres", compiling=compiling)
    return True


def compile_notice(prefix: str, quiet=False, *, compiling=None) -> None:
    """Print ``<prefix>: `COMPILE_NOTICE``` on stderr when the compiled kernels are not cached
    yet (``compiling`` true, default: ``kernels_cached() is False``) and not quiet."""
    if compiling is None:
        compiling = kernels_cached() is False
    if compiling and not quiet:
        print(f"{prefix}: {COMPILE_NOTICE}", file=sys.stderr, flush=True)


def kernels_cached(index_paths=None):
    """Whether numba's on-disk cache holds the action lines' kernel (`motion.wrapping.path_points`,
    compiled by every run): True or False, None when that cannot be told (numba's cache layout is
    internal; the question is only asked to word a progress line). ``index_paths``: the cache
    index files to look for (default: that kernel's)."""
    import os

    if index_paths is None:
        try:
            from motion.wrapping import path_points

            index_paths = [path_points._polyline_loop._cache._cache_file._index_path]
        except Exception:      # another numba version lays its cache out differently
            return None
    return all(os.path.exists(p) for p in index_paths)


def stage_notice(what: str, seconds: float, quiet=False) -> None:
    """One line ``fibres: <what> (<seconds> s)`` on stderr when a stage before the per-muscle
    lines is done (unless quiet)."""
    if not quiet:
        print(f"fibres: {what} ({seconds:.1f} s)", file=sys.stderr, flush=True)


def progress(iterable=None, *, total=None, desc=None, quiet=False, unit="it"):
    """Wrap ``iterable`` in a tqdm bar on stderr, or return it unchanged when quiet.

    The bar is shown only when stderr is a terminal (so CI logs and pipes stay clean),
    unless ``quiet`` is False and the environment variable ``FIBRES_PROGRESS=1`` forces it.
    """
    import os

    force = os.environ.get("FIBRES_PROGRESS") == "1"
    if quiet:
        return iterable if iterable is not None else _NullBar()
    if not (force or sys.stderr.isatty()):
        if unit != "muscle":       # per-frame counters would flood a log: muscles only
            return iterable if iterable is not None else _NullBar()
        bar = _LineBar(total, desc, unit)
        return bar.wrap(iterable) if iterable is not None else bar
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr, leave=False)


class _NullBar:
    """Stand-in for a manual tqdm bar when progress is off."""

    def update(self, n=1):
        pass

    def set_description(self, desc):
        pass

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


class _LineBar(_NullBar):
    """One line per step on stderr: ``fibres: <desc>: 2/3 muscles (12.4 s)``."""

    def __init__(self, total, desc, unit):
        import time

        self.total, self.desc, self.unit, self.n = total, desc or "working", unit, 0
        self._clock = time.perf_counter
        self.t0 = self._clock()

    def update(self, n=1):
        self.n += n
        total = f"/{self.total}" if self.total else ""
        print(f"fibres: {self.desc}: {self.n}{total} {self.unit}s ({self._clock() - self.t0:.1f} s)",
              file=sys.stderr, flush=True)

    def wrap(self, iterable):
        if self.total is None and hasattr(iterable, "__len__"):
            self.total = len(iterable)
        for item in iterable:
            yield item
            self.update(1)

    def set_description(self, desc):
        self.desc = desc
