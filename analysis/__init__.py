"""Per-motion fibre studies: the run, tables, plots, 3D files and the ``fibres`` command line.

May import ``motion`` and ``fibres``.
"""
from .errors import InputError, MissingDependencyError

__all__ = ["InputError", "MissingDependencyError"]
