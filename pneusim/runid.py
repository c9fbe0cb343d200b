"""Run ids: the name of one run of a sweep, the same for the same parameters and seed on any machine."""

from __future__ import annotations

import hashlib
import json

__all__ = ["run_id"]


def run_id(params: dict, seed: int) -> str:
    """12 hex digits of the SHA-1 of ``params`` and ``seed`` (keys sorted), e.g. ``'3f0c9a1b2d4e'``.

    A sweep stores each run's result as ``runs/RUN_ID.json``, so a restarted sweep finds the runs
    already done.
    """
    text = json.dumps({"params": params, "seed": seed}, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:12]
