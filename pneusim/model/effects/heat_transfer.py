"""Heat transfer: heat exchange between the chamber air and the cylinder walls (not adiabatic)."""

from __future__ import annotations

from .. import chamber
from .base import POSITIVE, Effect, ScreeningStart, number_text

__all__ = ["HeatTransfer", "HEAT_SCAN_S"]

#: s: thermal time constants the screening starts from.  A switched-on heat transfer is never the nominal
#: model (the chamber temperatures become states), so it is screened from two starts
HEAT_SCAN_S = (0.05, 0.5)


class HeatTransfer(Effect):
    """Newton cooling of the chamber air towards the wall temperature:

    ``Q = m c_v (T_w - T) / tau`` into each chamber's gas (W), ``m = p V / (R T)``,
    ``c_v = R / (gamma - 1)``, ``tau = time_constant_s`` the time constant of the air temperature at
    constant volume, ``T_w = wall_temperature_K``.  The chamber temperatures become states
    (``temperature_a_K``, ``temperature_b_K``) of the energy balance with heat exchange
    (:mod:`pneusim.model.chamber`; Carneiro & de Almeida 2006).
    """

    name = "heat_transfer"
    description = "heat exchange between chamber air and walls (not adiabatic)"
    source = ("vocabulary: shared/spec/diagnosis.md (heat_transfer); chamber energy balance with heat "
              "exchange as in Carneiro & de Almeida 2006, Newton cooling with one time constant")
    parameters = {"time_constant_s": 0.1, "wall_temperature_K": 293.15}
    ranges = {"time_constant_s": POSITIVE, "wall_temperature_K": POSITIVE}
    states = ("temperature_a_K", "temperature_b_K")

    #: the wall temperature stays where it is set (the screening sets it to the supply temperature)
    fit_free = ("time_constant_s",)
    fit_scale = {"time_constant_s": (None, 1e-3, 100.0), "wall_temperature_K": (293.15, 200.0, 400.0)}

    family = "slow pneumatic"
    evidence_plot = "relaxation"
    #: the chamber temperatures become states: never the nominal model, not retried from a neutral value
    neutral = None
    #: the screening from the data sheet runs each start to its end: the faster one stands for both
    data_sheet_start = ("time_constant_s", HEAT_SCAN_S[0])
    scanned = True
    #: free chamber temperatures on a window from the data sheet take up any other missing physics: heat transfer
    #: was the partner of every window pair that named a wrong effect on the practice sets, and of none that named a
    #: right one (docs/decisions/0125)
    window_pairs = False

    def heat_rates_W(self, ctx):
        # tau is the time constant of the air temperature at constant volume:
        # m c_v dT/dt = Q = m c_v (T_w - T) / tau
        tau = self.p(ctx, "time_constant_s")
        t_wall = self.p(ctx, "wall_temperature_K")
        cv = chamber.R_AIR_J_PER_KG_K / (chamber.GAMMA - 1.0)
        mass_a = ctx.p_a * ctx.V_a / (chamber.R_AIR_J_PER_KG_K * ctx.T_a)
        mass_b = ctx.p_b * ctx.V_b / (chamber.R_AIR_J_PER_KG_K * ctx.T_b)
        return mass_a * cv * (t_wall - ctx.T_a) / tau, mass_b * cv * (t_wall - ctx.T_b) / tau

    def derivatives(self, ctx):
        return {"temperature_a_K": ctx.dT_a, "temperature_b_K": ctx.dT_b}

    def initial_state(self, params, opening0):
        t0 = params["heat_transfer.wall_temperature_K"]
        return {"temperature_a_K": t0, "temperature_b_K": t0}

    @classmethod
    def screening_starts(cls, rig_values, sample_time_s, delays_s=None):
        """From each time constant of :data:`HEAT_SCAN_S`, the walls at the supply temperature."""
        return [ScreeningStart(f"heat transfer from {tau:g} s",
                               cls(time_constant_s=tau, wall_temperature_K=float(rig_values["supply_temperature_K"])))
                for tau in HEAT_SCAN_S]

    @classmethod
    def evidence(cls, signatures):
        s = signatures
        extra = (f"pressure residual settles {number_text(s['hold_pressure_settling_kPa'], '.2f')} kPa over a hold "
                 "after a move; " if "hold_pressure_settling_kPa" in s else "")
        return f"{extra}creep after stops {number_text(s['creep_mm_s'], '+.3f')} mm/s beyond the model"
