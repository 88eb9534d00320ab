"""Per-motion fibre studies: the run, tables, plots, 3D files and the ``fibres`` command line.

May import ``motion`` and ``fibres``.
"""
from . import interrupts as _interrupts

if _interrupts.is_the_command():   # Ctrl-C while the packages load: exit 130, no traceback
    _interrupts.install_early()

from .errors import InputError, MissingDependencyError  # noqa: E402
from .result import MuscleResult, RunResult  # noqa: E402
from .run import run  # noqa: E402
from .spec import AttachmentSpec, FibreModelSpec, MuscleSpec, load_spec  # noqa: E402
from .study import study  # noqa: E402  (the function; the module stays importable as analysis.study)

__all__ = ["InputError", "MissingDependencyError", "run", "RunResult", "MuscleResult", "load_spec",
           "FibreModelSpec", "MuscleSpec", "AttachmentSpec", "study"]
