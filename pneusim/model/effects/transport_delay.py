"""Transport delay: dead time between the command and the valve (tubing, DAQ latency)."""

from __future__ import annotations

from .base import Effect, ScreeningStart, number_text

__all__ = ["TransportDelay", "DELAY_SCAN_S", "SAMPLE_FRACTION"]

#: s: transport delays scanned when the command-residual cross-correlation shows no lag (those of at
#: least one sample are screened)
DELAY_SCAN_S = (0.01, 0.02, 0.04)
#: a scanned delay is screened when it is at least this fraction of the sample time: at least one sample,
#: with room for the rounding of delays computed from the sample time
SAMPLE_FRACTION = 0.99


class TransportDelay(Effect):
    """Dead time: the valve sees the command ``delay_s`` late, ``u_valve(t) = u(t - delay_s)``.

    The solver holds the delayed commands in a buffer (:meth:`command_delay_s`); the equations are
    the nominal ones.  A delay moves the command switch times, so a fit has no gradient for it: it is
    found by a search over a grid (``searched``).
    """

    name = "transport_delay"
    description = "dead time between the command and the valve (tubing, DAQ latency)"
    source = ("vocabulary: shared/spec/diagnosis.md (transport_delay); a pure dead time on the valve "
              "command")
    parameters = {"delay_s": 0.01}
    #: at most 10 s: tubing and DAQ latency are milliseconds, and the sample loop holds the delayed commands
    #: in a buffer of delay / sample time values (a delay of 1e9 s asked for 7 TiB)
    ranges = {"delay_s": (0.0, 10.0, True, True)}

    fit_free = ("delay_s",)
    searched = ("delay_s",)
    fit_scale = {"delay_s": (0.01, 0.0, 0.5)}

    family = "timing"
    evidence_plot = "lag"
    #: every delay moves the response; the screening scans delays rather than starting from none
    neutral = None
    #: a delay has no gradient: every delay of the scan is pre-fitted
    data_sheet_start = None
    scanned = True

    def command_delay_s(self):
        return self.values["delay_s"]

    @classmethod
    def screening_starts(cls, rig_values, sample_time_s, delays_s=None):
        """One start a scanned delay (``delays_s``, default :data:`DELAY_SCAN_S`) of at least a sample."""
        return [ScreeningStart(f"transport delay {d * 1e3:.3g} ms", cls(delay_s=d))
                for d in delays_s or DELAY_SCAN_S if d >= SAMPLE_FRACTION * sample_time_s]

    @classmethod
    def added_parameters(cls, free):
        """One: the delay, searched by a grid instead of freed."""
        return 1

    @classmethod
    def evidence(cls, signatures):
        s = signatures
        return (f"command-residual cross-correlation peaks at a lag of {number_text(s['lag_s'] * 1e3, '.0f')} ms "
                f"(r = {number_text(s['lag_r'], '+.2f')})")
