"""The diagnosis's time: a budget that no recording runs past, and where the time went, stage by stage.

A diagnosis is a sequence of fits, each from seconds to minutes; none can be stopped half-way and give a fit.
:class:`Budget` is asked before each costly step whether it fits in what is left (:meth:`Budget.allows`, the
step's expected cost measured on this recording: the nominal fit's own time); a step that does not fit is not
started, the budget records why (:attr:`Budget.stopped`), and the diagnosis returns what it has with that
status.  The budget counts the process's CPU time (every thread of it), not the wall clock: on an idle
machine a diagnosis then ends within its budget in wall time too (CPU time is at least the wall time of a
busy process), and on a loaded one the answer does not depend on what else runs.

:class:`StageClock` adds up the wall and CPU time of each named stage (``with clock.stage("screening"):``);
the result's ``timing`` reports them.
"""

from __future__ import annotations

import contextlib
import math
import time

__all__ = ["Budget", "StageClock"]


class Budget:
    """At most ``seconds`` of CPU time for one diagnosis (``math.inf``: no limit), counted from construction."""

    def __init__(self, seconds: float = math.inf):
        self.seconds = float(seconds)
        self.started = time.process_time()
        #: the first step that did not fit in what was left, and why (None: none was refused)
        self.stopped: str | None = None

    def used(self) -> float:
        """CPU seconds used so far."""
        return time.process_time() - self.started

    def left(self) -> float:
        """CPU seconds left (may be negative)."""
        return self.seconds - self.used()

    def allows(self, step: str, cost_s: float) -> bool:
        """Whether ``step``, expected to cost ``cost_s`` CPU seconds, fits in what is left; the first step
        refused is recorded in :attr:`stopped` (later ones are refused too, and not recorded)."""
        if self.stopped is not None:
            return False
        if self.used() + max(0.0, cost_s) <= self.seconds:
            return True
        self.stopped = (f"{step} (expected {cost_s:.0f} s of CPU time) did not fit in the {max(self.left(), 0.0):.0f} s "
                        f"left of the {self.seconds:.0f} s budget")
        return False

    @property
    def status(self) -> str:
        """``"complete"``, or ``"stopped by the time budget: ..."`` with the step refused."""
        return "complete" if self.stopped is None else f"stopped by the time budget: {self.stopped}"


class StageClock:
    """Wall and CPU seconds per named stage, added up over every time the stage runs."""

    def __init__(self):
        self.wall: dict[str, float] = {}
        self.cpu: dict[str, float] = {}

    @contextlib.contextmanager
    def stage(self, name: str):
        """Time the block as stage ``name``."""
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            yield
        finally:
            self.wall[name] = self.wall.get(name, 0.0) + time.perf_counter() - wall
            self.cpu[name] = self.cpu.get(name, 0.0) + time.process_time() - cpu

    def timing(self) -> dict:
        """``{"<stage>_s": wall seconds, ..., "cpu": {"<stage>_s": CPU seconds}}``."""
        out = {f"{k}_s": v for k, v in self.wall.items()}
        out["cpu_by_stage"] = {f"{k}_s": v for k, v in self.cpu.items()}
        return out
