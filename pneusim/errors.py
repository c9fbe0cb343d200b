"""User-facing errors.

Every mistake a user can make (a bad file, an unknown parameter, a rig that does
not match a recording) raises a subclass of :class:`PneusimError`.  The command
line prints its message as one sentence and exits non-zero; tracebacks are kept
for bugs.
"""

from __future__ import annotations

__all__ = ["PneusimError", "InputFileError", "SolverError", "FitError"]


class PneusimError(Exception):
    """Base class of errors caused by user input or by a failed computation."""


class InputFileError(PneusimError, ValueError):
    """A file that does not follow its documented format.

    Parameters
    ----------
    message:
        What is wrong and what was expected.
    path:
        The file (or ``None`` for in-memory data).
    line:
        1-based line number in a text file, or ``None``.
    field:
        Column, key or variable name, or ``None``.
    """

    def __init__(self, message: str, *, path=None, line: int | None = None, field: str | None = None):
        self.path = None if path is None else str(path)
        self.line = line
        self.field = field
        self.reason = message
        where = []
        if self.path is not None:
            where.append(self.path)
        if line is not None:
            where.append(f"line {line}")
        if field is not None:
            where.append(f"field '{field}'")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class SolverError(PneusimError, RuntimeError):
    """The ODE solver failed; the message gives the time and the state."""


class FitError(PneusimError, RuntimeError):
    """A parameter fit that could not give a trustworthy answer."""
