"""Checks of the tables read from the project's TOML files (scenarios, MRE files, signals).

Every fault raises :class:`~pneusim.errors.InputFileError` naming the file (``where``), the dotted
key and what was expected, in one line.
"""

from __future__ import annotations

from .errors import InputFileError

__all__ = ["NUMBER", "fail", "type_name", "check_type", "check_numbers", "check_keys", "check_choice"]

#: the types TOML gives a number
NUMBER = (int, float)


def fail(where, key: str, message: str):
    """Raise the one-line error: ``WHERE, field 'KEY': MESSAGE``."""
    raise InputFileError(message, path=where, field=key)


def type_name(types) -> str:
    """``int`` -> ``'an integer'``, :data:`NUMBER` -> ``'a number'`` ..."""
    names = {int: "an integer", float: "a number", str: "a string", list: "a list", dict: "a table",
             bool: "true or false"}
    if types == NUMBER:
        return "a number"
    return names.get(types, str(types))


def check_type(where, key: str, value, types) -> None:
    """``value`` must be of ``types`` (a bool is not a number)."""
    allowed = types if isinstance(types, tuple) else (types,)
    if (isinstance(value, bool) and bool not in allowed) or not isinstance(value, allowed):
        fail(where, key, f"expected {type_name(types)}, got {value!r}")


def check_numbers(where, key: str, value, n: int | None = None, what: str = "numbers") -> None:
    """``value`` must be a non-empty list of numbers (of length ``n`` if given)."""
    ok = isinstance(value, list) and all(isinstance(x, NUMBER) and not isinstance(x, bool) for x in value)
    if not ok or (n is not None and len(value) != n) or not value:
        size = f"{n} " if n is not None else ""
        fail(where, key, f"expected a non-empty list of {size}{what}, got {value!r}")


def check_keys(where, prefix: str, given, allowed, context: str = "") -> None:
    """Every key of the table ``given`` must be one of ``allowed``."""
    for key in sorted(set(given) - set(allowed)):
        fail(where, f"{prefix}.{key}", f"unknown key{context}; expected one of {', '.join(allowed)}")


def check_choice(where, key: str, value, choices) -> None:
    """``value`` must be one of ``choices``."""
    if value not in choices:
        fail(where, key, f"expected one of {', '.join(map(str, choices))}, got {value!r}")
