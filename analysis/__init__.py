"""Per-motion fibre studies: the run, tables, plots, 3D files and the ``fibres`` command line.

May import ``motion`` and ``fibres``.
"""
from .errors import InputError, MissingDependencyError
from .result import MuscleResult, RunResult
from .run import run
from .spec import AttachmentSpec, FibreModelSpec, MuscleSpec, load_spec

__all__ = ["InputError", "MissingDependencyError", "run", "RunResult", "MuscleResult", "load_spec",
           "FibreModelSpec", "MuscleSpec", "AttachmentSpec"]
