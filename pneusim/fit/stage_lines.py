"""The fit's stage lines: one line per stage to the ``pneusim.fit`` logger and, unless quiet, to standard error."""

from __future__ import annotations

import logging
import sys
import time

__all__ = ["StageLines", "routes_text", "rounds_text"]

_LOG = logging.getLogger("pneusim.fit")


class StageLines:
    """One line per fit stage, with the seconds since ``started``: to the ``pneusim.fit`` logger at INFO level,
    and to standard error unless ``quiet``."""

    def __init__(self, quiet: bool, started: float):
        self.quiet, self.started = quiet, started

    def __call__(self, message: str) -> None:
        line = f"fit [{time.perf_counter() - self.started:6.1f} s] {message}"
        _LOG.info(line)
        if not self.quiet:
            print(line, file=sys.stderr, flush=True)


def rounds_text(info: dict) -> str:
    """A tracked route's rounds and its finished residual, for the stage line."""
    finished = info.get("finished_rms_normalised")
    return (", ".join(f"{r['rms_normalised']:.3g}" for r in info["rounds"])
            + (f", finished {finished:.3g}" if finished is not None else ""))


def routes_text(info: dict) -> str:
    """The routes a :func:`.stages.two_routes` stage tried and the one it kept, for the stage line."""
    if len(info["routes"]) < 2 and "finished_rms_normalised" not in info["routes"][0]:
        return ""
    routes = ", ".join(f"{r['route']} {r['rms_normalised']:.3g}"
                       + (f" (IPOPT from it {r['finished_rms_normalised']:.3g})" if "finished_rms_normalised" in r else "")
                       for r in info["routes"])
    skipped = info["routes"][0].get("second_route_skipped")
    return f" (routes: {routes}; kept {info['route']}" + (f"; continuation not tried: {skipped})" if skipped else ")")
