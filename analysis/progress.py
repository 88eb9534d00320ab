"""Progress bars for long work (tqdm on stderr); silent with ``quiet=True`` or when not a TTY."""
from __future__ import annotations

import sys

__all__ = ["progress"]


def progress(iterable=None, *, total=None, desc=None, quiet=False, unit="it"):
    """Wrap ``iterable`` in a tqdm bar on stderr, or return it unchanged when quiet.

    The bar is shown only when stderr is a terminal (so CI logs and pipes stay clean),
    unless ``quiet`` is False and the environment variable ``FIBRES_PROGRESS=1`` forces it.
    """
    import os

    force = os.environ.get("FIBRES_PROGRESS") == "1"
    if quiet or not (force or sys.stderr.isatty()):
        return iterable if iterable is not None else _NullBar()
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
