"""Valve dead band: spool overlap, no flow while the command is within +-d of null."""

from __future__ import annotations

from .base import NON_NEGATIVE, Effect, ScreeningStart, number_text

__all__ = ["ValveDeadband", "SCREENING_DEADBAND_V"]

#: V: the dead band the screening starts from and the neutral value: small, the effect nearly absent, so
#: the screening starts where the nominal fit ended
SCREENING_DEADBAND_V = 0.02


class ValveDeadband(Effect):
    """Spool overlap: no opening while ``|u - u_null| <= d``; beyond it the opening is rescaled so that
    full command is still full opening, ``x_v = sign(e) max(|e| - d, 0) / (5 V - d)`` with
    ``e = u - u_null`` and ``d = deadband_V`` (:func:`pneusim.model.valve.opening_from_command`).
    """

    name = "valve_deadband"
    description = "spool overlap: no flow while the command is within +-d of null"
    source = ("vocabulary: shared/spec/diagnosis.md (valve_deadband); an overlapped (closed-centre) spool, "
              "its opening rescaled to full opening at full command")
    parameters = {"deadband_V": 0.2}
    ranges = {"deadband_V": NON_NEGATIVE}

    fit_free = ("deadband_V",)
    #: from none to half the valve's 5 V command span
    fit_scale = {"deadband_V": (0.2, 0.0, 2.5)}

    family = "valve null"
    evidence_plot = "command map"
    neutral = {"deadband_V": SCREENING_DEADBAND_V}
    data_sheet_start = None   # one start only

    def deadband_V(self, ctx):
        return self.p(ctx, "deadband_V")

    @classmethod
    def screening_starts(cls, rig_values, sample_time_s, delays_s=None):
        return [ScreeningStart(cls.name, cls(deadband_V=SCREENING_DEADBAND_V))]

    @classmethod
    def evidence(cls, signatures):
        s = signatures
        return (f"flat spot of the command-velocity map around null wider than the model's by "
                f"{number_text(s['flat_spot_V'], '+.3f')} V; "
                f"small commands move the piston {number_text(100 * s['small_command_speed_deficit'], '.0f')} % "
                "less than large ones relative to the model")
