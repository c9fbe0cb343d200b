"""Shared pieces of the MRE and rig-server tests (``mre/test_mre*.py``, ``mre/test_rig_server_fuzz.py``,
``commands/test_outputs_and_inputs.py``): a short MRE file of paper 1's loop, a rig server serving in a thread
of the test's process, and ``pneusim serve-rig`` in another process.

Imported by name (``from mre_cases import ...``), as ``recording_cases``: this folder is on ``sys.path``
because of its ``conftest.py``.
"""

from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
import threading

from pneusim.mre.rig_server import RigServer
from pneusim.plant import SimulatedPlant
from pneusim.rig import load_rig

__all__ = ["mre_text", "rig_server_thread", "free_udp_port", "serve_rig_process"]

#: every server here is paper 1's rig, on this machine only, with its valve's null at 5 V
RIG = "paper1-mre"
HOST = "127.0.0.1"
NULL_V = 5.0


def mre_text(duration_s: float = 0.2, seed: int | None = 2) -> str:
    """An MRE file: paper 1's rig under proportional control (40 V/m) following steps between 2 and 5 cm,
    one RLS identifier of order 3, ``duration_s`` long, no warm-up; ``seed`` None leaves the seed out (the
    file's default)."""
    seed_line = "" if seed is None else f"seed = {seed}\n"
    return f"""
[mre]
name = "t"
{seed_line}duration_s = {duration_s!r}
warmup_s = 0.0
[rig]
name = "{RIG}"
[controller]
kind = "proportional"
kp_V_per_m = 40.0
[reference]
kind = "steps"
unit = "m"
low = 0.02
high = 0.05
hold_s = [0.05, 0.1]
[[identifiers]]
name = "o3"
kind = "rls"
order = 3
"""


@contextlib.contextmanager
def rig_server_thread(seed: int, watchdog_s: float, **serve_options):
    """A :class:`~pneusim.mre.rig_server.RigServer` of paper 1's simulated rig (sensor noise ``seed``) on a
    free port of 127.0.0.1, serving in a daemon thread (``serve_options``: more keywords of its ``serve``).

    Yields ``(server, thread)``; on leaving, the server is told to stop, joined (at most 5 s) and closed.
    """
    server = RigServer(SimulatedPlant(load_rig(RIG), seed=seed), HOST, 0, watchdog_s=watchdog_s, null_V=NULL_V)
    stop = threading.Event()
    thread = threading.Thread(target=server.serve, kwargs={"stop": stop, **serve_options}, daemon=True)
    thread.start()
    try:
        yield server, thread
    finally:
        stop.set()
        thread.join(5)
        server.close()


def free_udp_port() -> int:
    """A UDP port of 127.0.0.1 free a moment ago (bound, read and released)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind((HOST, 0))
    port = s.getsockname()[1]
    s.close()
    return port


@contextlib.contextmanager
def serve_rig_process(*options: str, stderr=None):
    """``pneusim serve-rig --rig paper1-mre --port PORT OPTIONS...`` in another process, its output read as
    text through a pipe (``stderr``: ``subprocess.PIPE`` to read that too; None leaves it to the test's).

    Yields ``(process, port)`` once the server has said it listens (its first line names ``udp 127.0.0.1``);
    on leaving, a process still running is killed.
    """
    port = free_udp_port()
    proc = subprocess.Popen([sys.executable, "-m", "pneusim.cli", "serve-rig", "--rig", RIG, "--port", str(port),
                             *options], stdout=subprocess.PIPE, stderr=stderr, text=True)
    try:
        assert f"on udp {HOST}" in proc.stdout.readline()
        yield proc, port
    finally:
        if proc.poll() is None:
            proc.kill()
