"""Exceptions and warnings raised by :mod:`sysid`."""

__all__ = ["SysidError", "SysidWarning"]


class SysidError(ValueError):
    """Invalid input to a :mod:`sysid` function.

    The message is one sentence naming the argument and what was expected.
    """


class SysidWarning(UserWarning):
    """An estimate that is returned but should not be trusted as it is.

    Raised (as a Python warning) when an estimator ends with an unstable model,
    an input-output part that is numerically zero, or non-finite parameters;
    the same sentences are kept in the model's ``warnings`` list.  Silence it
    with ``warnings.simplefilter("ignore", sysid.SysidWarning)``.
    """
