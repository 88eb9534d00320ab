"""Errors raised by `analysis`: `fibres.errors`' classes (the toolkit's one hierarchy) and
`FibreWarning`.

One hierarchy for the whole package:

- `InputError(ValueError)`: the user's input is wrong (a file, an element, an argument).
  The message is one line that names the file, the element (XML path, line, muscle, key)
  and what to do about it. The command line turns it into exit status 2 with no traceback.
- `MissingDependencyError(ImportError)`: an optional dependency is not installed; the
  message names the extra to install.

Anything else escaping the package is an internal failure (exit status 1). `FibreWarning`
(a UserWarning) flags a result to look at; ``fibres run`` prints it on stderr.
"""
from __future__ import annotations

from fibres.errors import InputError, MissingDependencyError

__all__ = ["InputError", "MissingDependencyError", "FibreWarning"]


class FibreWarning(UserWarning):
    """A result the user should look at (fibres far from their action lines, a path shorter than
    its tendon slack length); also written as a ``warning:`` note of the muscle in run.json."""
