"""SIGTERM stops a command as Ctrl-C does: the same safe stop, a different exit status.

A service manager, ``timeout`` or ``kill`` ends a process with SIGTERM, whose default action ends
Python at once: no ``finally``, so a loop would leave the valve at its last command and a rig server
would not print what it counted.  Inside :func:`sigterm_raises` a SIGTERM raises :class:`Terminated`,
a :class:`KeyboardInterrupt`, so every path that stops safely on Ctrl-C (the sample loop's valve to
null and closed recording, the rig server's statistics) runs for it too; the command tells the two
apart by the class and exits with 128 + 15 = :data:`EXIT_TERMINATED`.

Only the first SIGTERM raises: the ones that follow while the stop is under way are ignored, so that
a second signal cannot cut the valve-to-null step short (SIGKILL still ends the process).
"""

from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["Terminated", "sigterm_raises", "EXIT_TERMINATED"]

#: exit status of a command stopped by SIGTERM (the shell's 128 + signal number)
EXIT_TERMINATED = 128 + signal.SIGTERM


class Terminated(KeyboardInterrupt):
    """SIGTERM was received (raised in the main thread by :func:`sigterm_raises`)."""


@contextlib.contextmanager
def sigterm_raises():
    """While the block runs, SIGTERM raises :class:`Terminated` in the main thread (once).

    Outside the main thread (where Python cannot install a handler) the block runs unchanged.  The
    previous handler is restored when the block ends.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []

    def handler(signum, frame):
        if received:
            return                 # the stop is under way: let it finish
        received.append(signum)
        raise Terminated("terminated (SIGTERM)")

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
