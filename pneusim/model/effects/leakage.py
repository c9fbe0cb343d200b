"""Leakage: laminar air flow across the piston seal (A<->B) or from a chamber to atmosphere."""

from __future__ import annotations

import casadi as ca

from .base import NON_NEGATIVE, Effect, ScreeningStart, number_text

__all__ = ["Leakage", "SCREENING_CONDUCTANCE_KG_PER_S_PA"]

#: kg/(s Pa): the conductance the screening starts from and the neutral value: small, the effect nearly
#: absent, so the screening starts where the nominal fit ended
SCREENING_CONDUCTANCE_KG_PER_S_PA = 1e-11


class Leakage(Effect):
    """A laminar leak: mass flow proportional to the pressure difference across it.

    Internal (across the piston seal, A to B): ``q_AB = g (p_A - p_B)``, out of A and into B at the
    upstream chamber's temperature.  External (chamber ``c`` to atmosphere):
    ``q_in = g (p_atm - p_c)``, entering at the supply temperature or leaving at the chamber's.
    ``g = conductance_kg_per_s_Pa``.  A narrow seal clearance passes laminar (Hagen-Poiseuille)
    flow, linear in the pressure difference.
    """

    name = "leakage"
    description = "laminar air flow across the piston seal (A<->B) or from a chamber to atmosphere"
    source = ("vocabulary: shared/spec/diagnosis.md (leakage); laminar (Hagen-Poiseuille) flow through a "
              "seal clearance, linear in the pressure difference")
    parameters = {"conductance_kg_per_s_Pa": 1.0e-9}
    ranges = {"conductance_kg_per_s_Pa": NON_NEGATIVE}
    options = {"kind": ("internal", "external"), "chamber": ("a", "b")}

    fit_free = ("conductance_kg_per_s_Pa",)
    fit_scale = {"conductance_kg_per_s_Pa": (1e-9, 0.0, None)}

    family = "slow pneumatic"
    evidence_plot = "holding"
    neutral = {"conductance_kg_per_s_Pa": SCREENING_CONDUCTANCE_KG_PER_S_PA}
    #: a screening step may reach the bound zero, where the leak is absent: its refit starts at the neutral value
    refit_start_floor = {"conductance_kg_per_s_Pa": SCREENING_CONDUCTANCE_KG_PER_S_PA}
    #: every leak path is different physics: the screening from the data sheet keeps all three
    data_sheet_start = None

    def extra_flows(self, ctx):
        g = self.p(ctx, "conductance_kg_per_s_Pa")
        if self.option_values["kind"] == "internal":
            q_ab = g * (ctx.p_a - ctx.p_b)
            t_up = ca.if_else(q_ab >= 0, ctx.T_a, ctx.T_b)
            return [("a", -q_ab, t_up), ("b", q_ab, t_up)]
        which = self.option_values["chamber"]
        p_ch, t_ch = (ctx.p_a, ctx.T_a) if which == "a" else (ctx.p_b, ctx.T_b)
        q_in = g * (ctx.param("atmosphere_Pa") - p_ch)
        t_in = ca.if_else(q_in >= 0, ctx.param("supply_temperature_K"), t_ch)
        return [(which, q_in, t_in)]

    @classmethod
    def screening_starts(cls, rig_values, sample_time_s, delays_s=None):
        """Each leak path from a leak too small to show."""
        return [ScreeningStart(label, cls(conductance_kg_per_s_Pa=SCREENING_CONDUCTANCE_KG_PER_S_PA, **opts))
                for label, opts in (("leakage (internal, A<->B)", {"kind": "internal"}),
                                    ("leakage (chamber A to atmosphere)", {"kind": "external", "chamber": "a"}),
                                    ("leakage (chamber B to atmosphere)", {"kind": "external", "chamber": "b"}))]

    @classmethod
    def evidence(cls, signatures):
        s = signatures
        extra = (f"; pressure residual settles {number_text(s['hold_pressure_settling_kPa'], '.2f')} kPa over a hold "
                 "after a move" if "hold_pressure_settling_kPa" in s else "")
        return f"creep near null {number_text(s['creep_mm_s'], '+.3f')} mm/s beyond the model{extra}"

    @classmethod
    def reported_options(cls, option_values):
        """The path; the chamber only for a leak to atmosphere (an internal leak joins both)."""
        return {k: v for k, v in option_values.items()
                if not (k == "chamber" and option_values.get("kind") == "internal")}
