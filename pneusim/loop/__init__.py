"""The sample loop shared by the mixed-reality environment (:mod:`pneusim.mre`) and the scenarios' online
runs (:func:`pneusim.scenario.online.simulate_online`): measure, identify, control, actuate, record.

* :mod:`~pneusim.loop.sample_loop`: :func:`run_loop` and its :class:`LoopResult`;
* :mod:`~pneusim.loop.pacing`: when sample ``k`` may start (as fast as possible, real time with absolute
  deadlines, plain sleep);
* :mod:`~pneusim.loop.status`: the live status line and the timing summary of a run.
"""

from .pacing import PACING_MODES, FastPacing, Pacing, RealtimePacing, SleepPacing, make_pacing
from .sample_loop import LoopResult, row_columns, run_loop
from .status import StatusLine, timing_summary

__all__ = ["run_loop", "LoopResult", "row_columns", "StatusLine", "timing_summary", "Pacing", "FastPacing",
           "RealtimePacing", "SleepPacing", "make_pacing", "PACING_MODES"]
