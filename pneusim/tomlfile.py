"""Reading the project's TOML files (rigs, scenarios, sweeps) with one kind of error."""

from __future__ import annotations

import tomllib
from pathlib import Path

from .errors import InputFileError

__all__ = ["read_toml"]


def read_toml(path: str | Path, what: str) -> dict:
    """Parse ``path`` as TOML; a missing or malformed file raises :class:`InputFileError`.

    ``what`` names the kind of file in the message ("rig", "scenario", "sweep").
    """
    path = Path(path)
    if not path.exists():
        raise InputFileError(f"{what} file not found", path=path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputFileError(f"not a valid TOML {what} file ({exc})", path=path) from None
