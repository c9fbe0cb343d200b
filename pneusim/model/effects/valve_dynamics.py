"""Valve dynamics: the spool's opening follows the commanded opening through a second-order lag."""

from __future__ import annotations

import math

import casadi as ca

from .base import POSITIVE, Effect, ScreeningStart, number_text

__all__ = ["ValveDynamics", "SPOOL_SCAN_HZ", "SCREENING_DAMPING"]

#: Hz: spool natural frequencies the screening starts from (proportional valves: 5-100 Hz); a lag has no
#: value equal to the nominal model and moves the response non-linearly, so it is screened from several
SPOOL_SCAN_HZ = (30.0, 10.0, 4.0)
#: the damping ratio every screening start uses: a well-damped spool, as valve data sheets show
SCREENING_DAMPING = 0.7


class ValveDynamics(Effect):
    """The spool's own lag between command and opening, a second-order system:

    ``x_v'' = w^2 (x_c - x_v) - 2 zeta w x_v'``, ``w = 2 pi natural_frequency_Hz``,
    ``zeta = damping``, ``x_c`` the opening the command asks for (after null, offset and dead band);
    the opening the flows see is ``x_v`` limited to [-1, 1].  States: ``spool_opening`` and
    ``spool_rate_per_s``.  A proportional valve's data sheet gives its frequency response as such a
    lag (bandwidth and phase).
    """

    name = "valve_dynamics"
    description = "spool opening follows the commanded opening through a second-order lag"
    source = ("vocabulary: shared/spec/diagnosis.md (valve_dynamics); a second-order lag, the form of a "
              "proportional valve's data-sheet frequency response")
    parameters = {"natural_frequency_Hz": 20.0, "damping": 0.7}
    ranges = {"natural_frequency_Hz": POSITIVE, "damping": POSITIVE}
    states = ("spool_opening", "spool_rate_per_s")

    fit_free = ("natural_frequency_Hz", "damping")
    #: proportional valves' spools: a few Hz to a few hundred, well damped.  A fit that wanders to a fast,
    #: barely damped spool makes the model stiff and ringing (each evaluation then costs tens of solver
    #: steps a sample), and no rig's spool rings like that
    fit_scale = {"natural_frequency_Hz": (None, 0.5, 300.0), "damping": (0.7, 0.2, 5.0)}

    family = "timing"
    evidence_plot = "lag"
    #: a spool lag adds two states and is never the nominal model: a refit is not retried from a neutral value
    neutral = None
    #: the screening from the data sheet runs each start to its end: the middle frequency stands for all
    data_sheet_start = ("natural_frequency_Hz", SPOOL_SCAN_HZ[1])
    scanned = True

    def opening(self, ctx, commanded_opening):
        ctx.commanded_opening = commanded_opening
        return ca.fmin(ca.fmax(ctx.x["spool_opening"], -1.0), 1.0)

    def derivatives(self, ctx):
        omega = 2.0 * math.pi * self.p(ctx, "natural_frequency_Hz")
        zeta = self.p(ctx, "damping")
        xv, rate = ctx.x["spool_opening"], ctx.x["spool_rate_per_s"]
        accel = omega**2 * (ctx.commanded_opening - xv) - 2.0 * zeta * omega * rate
        return {"spool_opening": rate, "spool_rate_per_s": accel}

    def initial_state(self, params, opening0):
        return {"spool_opening": opening0, "spool_rate_per_s": 0.0}

    @classmethod
    def screening_starts(cls, rig_values, sample_time_s, delays_s=None):
        return [ScreeningStart(f"valve dynamics from {f:g} Hz",
                               cls(natural_frequency_Hz=f, damping=SCREENING_DAMPING))
                for f in SPOOL_SCAN_HZ]

    @classmethod
    def evidence(cls, signatures):
        s = signatures
        return (f"command-residual cross-correlation peaks at a lag of {number_text(s['lag_s'] * 1e3, '.0f')} ms "
                f"(r = {number_text(s['lag_r'], '+.2f')}): lag after fast command changes")
