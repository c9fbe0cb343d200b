"""Progress of a long run: a bar on a terminal, plain lines anywhere else.

A bar redrawn in place (tqdm) reads well on a terminal but not in a log file or a CI log, where only its
first state (``0%``) shows until the run ends.  :func:`progress_bar` gives the bar when the stream is a
terminal, and otherwise a :class:`LineProgress`: one line when the run starts, one every few seconds
while it advances, one when it ends (``sweep: 12/36 runs (33 %), 14.2 s, about 28 s left``).
"""

from __future__ import annotations

import sys
import time

__all__ = ["progress_bar", "LineProgress", "LINE_INTERVAL_S"]

#: seconds between two progress lines in a log
LINE_INTERVAL_S = 5.0


class LineProgress:
    """Progress as plain lines: the start, at most one line every ``interval_s`` seconds, the end.

    The methods a caller of a tqdm bar uses (``update``, ``close``, a ``with`` block) behave the same.
    """

    def __init__(self, total: int | None, desc: str = "", unit: str = "it", stream=None,
                 interval_s: float = LINE_INTERVAL_S):
        self.total, self.desc, self.unit = total, desc, unit
        self.stream = stream if stream is not None else sys.stderr
        self.interval_s = interval_s
        self.n = 0
        self.started = self._last = time.perf_counter()
        self._closed = False
        self._line()

    def _line(self) -> None:
        elapsed = time.perf_counter() - self.started
        text = f"{self.desc}: {self.n}"
        if self.total:
            text += f"/{self.total} {self.unit}s ({100.0 * self.n / self.total:.0f} %), {elapsed:.1f} s"
            if 0 < self.n < self.total:
                text += f", about {elapsed * (self.total - self.n) / self.n:.0f} s left"
        else:
            text += f" {self.unit}s, {elapsed:.1f} s"
        print(text, file=self.stream, flush=True)
        self._last = time.perf_counter()

    def update(self, n: int = 1) -> None:
        """Advance by ``n``; print a line when ``interval_s`` has passed since the last one."""
        self.n += n
        if time.perf_counter() - self._last >= self.interval_s and (self.total is None or self.n < self.total):
            self._line()

    def close(self) -> None:
        """Print the last line (once)."""
        if not self._closed:
            self._closed = True
            self._line()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def progress_bar(total: int | None, desc: str, unit: str = "it", *, leave: bool = True, mininterval: float = 0.5,
                 stream=None, interval_s: float = LINE_INTERVAL_S):
    """A tqdm bar on a terminal, :class:`LineProgress` otherwise (a log file, a pipe, a notebook).

    Parameters
    ----------
    total : int or None
        Steps to the end (None: unknown).
    desc, unit : str
        What runs (``"sweep"``) and what a step is (``"run"``).
    leave : bool
        Keep the bar on the terminal when it closes (lines always stay).
    mininterval : float
        Seconds between two redraws of the bar.
    stream : file, optional
        Where to write (default: standard error).
    interval_s : float
        Seconds between two lines when not on a terminal.
    """
    stream = stream if stream is not None else sys.stderr
    isatty = getattr(stream, "isatty", None)
    if isatty is not None and isatty():
        from tqdm import tqdm   # ~0.1 s to import; only a run with a bar on a terminal needs it

        return tqdm(total=total, desc=desc, unit=unit, leave=leave, mininterval=mininterval, file=stream)
    return LineProgress(total, desc, unit, stream, interval_s)
