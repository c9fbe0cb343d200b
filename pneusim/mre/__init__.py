"""Mixed-reality environment (paper 1): controller, online identifiers and a plant in one real-time loop.

* :mod:`~pneusim.mre.clock`: pacing (as fast as possible, real time with absolute deadlines, plain sleep);
* :mod:`~pneusim.mre.rt`: real-time settings of the process while it is paced (SCHED_FIFO, locked memory);
* :mod:`~pneusim.mre.loop`: the sample loop (measure, identify, control, actuate) with per-sample timing;
* :mod:`~pneusim.mre.plants`: the ``--plant`` choice and the replayed recording (open loop);
* :mod:`~pneusim.mre.udp`: a rig in another process over UDP (protocol, loop side, server, watchdog);
* :mod:`~pneusim.mre.daq`: a real rig through an NI card (``nidaqmx``, optional extra ``daq``);
* :mod:`~pneusim.mre.scenario`: MRE files; :mod:`~pneusim.mre.run`: a whole run; :mod:`~pneusim.mre.report`.
"""

from .clock import FastPacing, RealtimePacing, SleepPacing, make_pacing
from .loop import LoopResult, run_loop
from .run import run_mre
from .scenario import load_mre

__all__ = ["run_loop", "LoopResult", "run_mre", "load_mre", "make_pacing", "FastPacing", "RealtimePacing",
           "SleepPacing"]
