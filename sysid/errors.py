"""Exceptions raised by :mod:`sysid` for invalid user input."""

__all__ = ["SysidError"]


class SysidError(ValueError):
    """Invalid input to a :mod:`sysid` function.

    The message is one sentence naming the argument and what was expected.
    """
