"""Errors raised by `motion`: the toolkit's one hierarchy, defined in `fibres.errors`.

`motion` may use `fibres`' geometry and errors (docs/DESIGN.md, "Layering"); raising the same
classes means ``except InputError`` catches a bad .osim, a bad mesh and a bad TOML alike.
"""
from __future__ import annotations

from fibres.errors import InputError, MissingDependencyError

__all__ = ["InputError", "MissingDependencyError"]
