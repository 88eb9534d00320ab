"""Errors raised by `analysis`.

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

__all__ = ["InputError", "MissingDependencyError", "FibreWarning"]


class InputError(ValueError):
    """Bad user input. str(err) is one line: file: where: problem. fix.

    Parameters
    ----------
    problem : str
        What is wrong.
    file : str or os.PathLike, optional
        The file in which it is wrong.
    where : str, optional
        The element: an XML path, line 12, muscle 'biceps', a TOML key ...
    fix : str, optional
        What the user should do.
    """

    def __init__(self, problem: str, *, file=None, where: str | None = None, fix: str | None = None):
        self.problem = str(problem)
        self.file = None if file is None else str(file)
        self.where = where
        self.fix = fix
        super().__init__(self._format())

    def _format(self) -> str:
        parts = [p for p in (self.file, self.where) if p]
        text = ": ".join(parts + [self.problem]) if parts else self.problem
        if self.fix:
            text = text.rstrip(".") + ". " + self.fix
        return " ".join(text.split())


class MissingDependencyError(ImportError):
    """An optional dependency is missing; the message names the extra to install."""


class FibreWarning(UserWarning):
    """A result the user should look at (fibres far from their action lines, a path shorter than
    its tendon slack length); also written as a ``warning:`` note of the muscle in run.json."""
