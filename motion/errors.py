"""Errors raised by `motion`: the toolkit's one hierarchy, defined in `fibres.errors`.

`motion` may use `fibres`' geometry and errors (docs/DESIGN.md, "Layering"); raising the same
classes means ``except InputError`` catches a bad .osim, a bad mesh and a bad TOML alike.
"""
from __future__ import annotations

from fibres.errors import InputError, MissingDependencyError

__all__ = ["InputError", "MissingDependencyError", "read_guarded"]


def read_guarded(load, path, *, what: str, fix: str):
    """``load()``, with anything unexpected that goes wrong while reading ``path`` (a value of
    a type the reader did not foresee, MemoryError, RecursionError) reported as one InputError
    naming the file: bad input must never crash with a traceback."""
    try:
        return load()
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - the point of this function
        raise InputError(f"cannot read the {what} ({type(exc).__name__}: {exc})", file=path, fix=fix) from None
