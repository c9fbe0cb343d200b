"""What a loop run shows while it runs and sums up afterwards: the live status line and the timing summary."""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from ..progress import LINE_INTERVAL_S

__all__ = ["StatusLine", "timing_summary"]


class StatusLine:
    """A live status (samples, overruns, lateness, one-step error): one line redrawn in place on a terminal;
    in a log (any other stream) a line every ``line_interval_s`` and the last state when the run ends, so
    that a log does not stop at its first ``0 %``.

    Parameters
    ----------
    stream : file
        Where to write (``sys.stderr`` by default).
    interval_s : float
        Wall time between two updates.
    label : str
        First word of the line.
    line_interval_s : float
        Wall time between two lines in a log.
    """

    def __init__(self, stream=None, interval_s: float = 0.5, label: str = "mre",
                 line_interval_s: float = LINE_INTERVAL_S):
        self.stream = stream if stream is not None else sys.stderr
        self.label = label
        self.interval_s = float(interval_s)
        self.line_interval_s = float(line_interval_s)
        self.terminal = bool(getattr(self.stream, "isatty", lambda: False)())
        self.last_text = ""
        self.n = 0
        self._written, self._written_at = "", -math.inf

    def show(self, k: int, n: int, overruns: int, late_half: int, lateness_s: np.ndarray,
             err: float, err_name: str) -> None:
        lat = lateness_s[np.isfinite(lateness_s)]
        timing = (f", lateness p50 {np.percentile(lat, 50) * 1e3:.3f} ms p99 {np.percentile(lat, 99) * 1e3:.3f} ms "
                  f"max {lat.max() * 1e3:.3f} ms" if lat.size else "")
        e = f", 1-step error ({err_name}) {err:+.4g}" if err_name else ""
        paced = f", overruns {overruns}, late > Ts/2 {late_half}{timing}" if lat.size else ""   # none when fast
        self.last_text = f"{self.label}: {k}/{n} samples ({100.0 * k / max(n, 1):.0f} %){paced}{e}"
        self.n = n
        if self.terminal:
            self.stream.write("\r" + self.last_text + "   ")
        elif time.perf_counter() - self._written_at >= self.line_interval_s:
            self._line(self.last_text)
        self.stream.flush()

    def _line(self, text: str) -> None:
        self.stream.write(text + "\n")
        self._written, self._written_at = text, time.perf_counter()

    def close(self, done: int | None = None) -> None:
        """End the status: on a terminal a new line, in a log the last state not written yet; with ``done``
        (samples run) the count the run ended at."""
        if not self.last_text:
            return
        final = (f"{self.label}: {done}/{self.n} samples ({100.0 * done / max(self.n, 1):.0f} %), ended"
                 if done is not None and not self.last_text.startswith(f"{self.label}: {done}/") else None)
        if self.terminal:
            self.stream.write(("\r" + final + " " * max(0, len(self.last_text) - len(final)) if final else "") + "\n")
        else:
            if self.last_text != self._written:
                self._line(self.last_text)
            if final:
                self._line(final)
        self.stream.flush()


def timing_summary(result) -> dict:
    """Lateness p50/p99/max, overruns and computation per sample of a run (a :class:`LoopResult`), in s and
    counts."""
    ts, n = result.sample_time_s, result.n_samples
    out = {"samples": n, "pacing": result.pacing, "sample_time_s": ts, "overruns": result.overruns,
           "late_half_sample": result.late_half,
           "late_half_sample_percent": 100.0 * result.late_half / n if n else math.nan}
    for name, arr in (("lateness_s", result.lateness_s), ("latency_s", result.latency_s),
                      ("compute_s", result.compute_s)):
        a = arr[np.isfinite(arr)] if arr is not None else np.empty(0)
        out[name] = ({"p50": float(np.percentile(a, 50)), "p99": float(np.percentile(a, 99)),
                      "max": float(a.max()), "mean": float(a.mean())} if a.size else None)
    return out
