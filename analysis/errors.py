"""Errors raised by `analysis`: the toolkit's one hierarchy of `fibres.errors` (`InputError`,
a one-line message naming file, element and fix, exit status 2 on the command line;
`MissingDependencyError`, naming the extra to install), re-exported here, and `FibreWarning`
(a UserWarning) for a result to look at, which ``fibres run`` prints on stderr.
"""
from __future__ import annotations

from fibres.errors import InputError, MissingDependencyError

__all__ = ["InputError", "MissingDependencyError", "FibreWarning"]


class FibreWarning(UserWarning):
    """A result the user should look at (fibres far from their action lines, a path shorter than
    its tendon slack length); also written as a ``warning:`` note of the muscle in run.json."""
