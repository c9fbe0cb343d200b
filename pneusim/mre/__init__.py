"""Mixed-reality environment (paper 1): controller, online identifiers and a plant in one real-time loop.

The loop itself (measure, identify, control, actuate, record; its pacing) is :mod:`pneusim.loop`, the
online identifiers are :mod:`pneusim.online`; this package adds what a live run needs around them:

* :mod:`~pneusim.mre.rt`: real-time settings of the process while it is paced (SCHED_FIFO, locked memory);
* :mod:`~pneusim.mre.plants`: the ``--plant`` choice and the replayed recording (open loop);
* :mod:`~pneusim.mre.udp`: a rig in another process over UDP (protocol, loop side, server, watchdog);
* :mod:`~pneusim.mre.daq`: a real rig through an NI card (``nidaqmx``, optional extra ``daq``);
* :mod:`~pneusim.mre.recorder`: the recording written row by row while the loop runs;
* :mod:`~pneusim.mre.scenario`: MRE files; :mod:`~pneusim.mre.run`: a whole run; :mod:`~pneusim.mre.report`.
"""

from .run import MreRun, run_mre
from .scenario import load_mre

__all__ = ["run_mre", "MreRun", "load_mre"]
