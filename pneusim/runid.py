"""Run ids: the name of one run of a sweep, the same for the same run on any machine, different for any
change that changes the run.

A sweep stores each run's result as ``runs/RUN_ID.json`` and a restarted sweep reuses what is stored,
so the id must hash everything that determines the run: the varied parameters and the seed, and the
*context* -- the scenario, the sweep's ``[base]``, its options (:func:`run_context`) -- and the contents
of every rig file any of them names (a path ending in ``.toml`` that exists).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

__all__ = ["run_id", "run_context"]


def _canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, default=str, separators=(",", ":"))


def _file_digests(obj, out: dict | None = None) -> dict:
    """``{path: sha1 of its bytes}`` of every string in ``obj`` (nested lists and dicts) that names an
    existing ``.toml`` file: the rig files a scenario, a [base] or a point names."""
    out = {} if out is None else out
    if isinstance(obj, str):
        if obj.lower().endswith(".toml") and obj not in out:
            try:
                out[obj] = hashlib.sha1(Path(obj).read_bytes()).hexdigest()
            except OSError:
                pass
    elif isinstance(obj, dict):
        for value in obj.values():
            _file_digests(value, out)
    elif isinstance(obj, (list, tuple)):
        for value in obj:
            _file_digests(value, out)
    return out


def run_context(*parts) -> str:
    """A digest (hex) of what every run of a sweep shares: ``parts`` (the scenario, the ``[base]``
    overrides, options) and the contents of the rig files they name."""
    return hashlib.sha1(_canonical({"parts": parts, "files": _file_digests(parts)}).encode()).hexdigest()


def run_id(params: dict, seed: int, context: str = "") -> str:
    """12 hex digits of the SHA-1 of ``params``, ``seed``, ``context`` (:func:`run_context`) and the
    contents of the rig files ``params`` names, e.g. ``'3f0c9a1b2d4e'``."""
    text = _canonical({"params": params, "seed": seed, "context": context, "files": _file_digests(params)})
    return hashlib.sha1(text.encode()).hexdigest()[:12]
