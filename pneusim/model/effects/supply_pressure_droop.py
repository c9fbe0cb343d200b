"""Supply pressure droop: the valve fed from a volume refilled from a regulator through a restriction."""

from __future__ import annotations

from .. import chamber, valve
from .base import POSITIVE, POSITIVE_NEAR_START, Effect, ScreeningStart, number_text

__all__ = ["SupplyPressureDroop", "SUPPLY_DROOP_SCAN"]

#: supply lines the screening starts from: (conductance over the valve's, supply volume m^3).  Four
#: times the valve's conductance barely sags; a sag the data can show needs a supply line of the order
#: of the valve's or narrower, and a start from the wide line alone can make the residual worse in a few
#: steps
SUPPLY_DROOP_SCAN = ((4.0, 5e-4), (0.5, 2e-4))


class SupplyPressureDroop(Effect):
    """The valve draws from a supply volume ``V_s`` refilled from the regulator through a restriction:

    ``dp_s/dt = R T_s / V_s (q_refill - q_draw)``, isothermal at the supply temperature ``T_s`` (the line
    and receiver walls hold the air there), ``q_refill`` the ISO 6358 flow
    (:func:`pneusim.model.valve.iso6358_mass_flow`) of conductance ``supply_conductance_m3_per_s_Pa``
    from ``regulator_Pa`` to ``p_s``, with the valve's critical pressure ratio, and ``q_draw`` what the
    valve takes to both chambers.  State: ``supply_pressure_Pa``, the valve's supply pressure.
    """

    name = "supply_pressure_droop"
    description = "valve fed from a volume refilled from a regulator through a restriction"
    source = ("vocabulary: shared/spec/diagnosis.md (supply_pressure_droop); an isothermal receiver "
              "filled through an ISO 6358 restriction (ISO 6358-1:1989)")
    parameters = {"supply_volume_m3": 2.0e-4, "supply_conductance_m3_per_s_Pa": 5.0e-9,
                  "regulator_Pa": 701325.0}
    ranges = {"supply_volume_m3": POSITIVE, "supply_conductance_m3_per_s_Pa": POSITIVE, "regulator_Pa": POSITIVE}
    states = ("supply_pressure_Pa",)

    #: the regulator's pressure is the rig's supply pressure (the screening sets it so)
    fit_free = ("supply_volume_m3", "supply_conductance_m3_per_s_Pa")
    fit_scale = {"supply_volume_m3": POSITIVE_NEAR_START, "supply_conductance_m3_per_s_Pa": POSITIVE_NEAR_START}

    family = "slow pneumatic"
    evidence_plot = "pressure difference"
    #: a supply line of any size adds a state and is never the nominal model: not retried from a neutral value
    neutral = None
    #: the screening from the data sheet runs each start to its end: the narrow line, the one that sags
    data_sheet_start = ("supply_volume_m3", SUPPLY_DROOP_SCAN[1][1])
    scanned = True

    def supply_Pa(self, ctx):
        return ctx.x["supply_pressure_Pa"]

    def derivatives(self, ctx):
        # isothermal supply volume: the line and receiver walls hold the air at supply temperature
        t_s = ctx.param("supply_temperature_K")
        refill = valve.iso6358_mass_flow(self.p(ctx, "supply_conductance_m3_per_s_Pa"),
                                         ctx.param("valve_critical_pressure_ratio"),
                                         self.p(ctx, "regulator_Pa"), ctx.supply, t_s, t_s)
        rate = chamber.R_AIR_J_PER_KG_K * t_s / self.p(ctx, "supply_volume_m3") * (refill - ctx.supply_draw)
        return {"supply_pressure_Pa": rate}

    def initial_state(self, params, opening0):
        return {"supply_pressure_Pa": params["supply_pressure_droop.regulator_Pa"]}

    @classmethod
    def screening_starts(cls, rig_values, sample_time_s, delays_s=None):
        """From each line of :data:`SUPPLY_DROOP_SCAN`, the regulator at the rig's supply pressure."""
        supply = float(rig_values["supply_Pa"])
        conductance = float(rig_values["valve_sonic_conductance_m3_per_s_Pa"])
        return [ScreeningStart(f"supply pressure droop from {ratio:g} x the valve's conductance",
                               cls(supply_volume_m3=volume, supply_conductance_m3_per_s_Pa=ratio * conductance,
                                   regulator_Pa=supply))
                for ratio, volume in SUPPLY_DROOP_SCAN]

    @classmethod
    def evidence(cls, signatures):
        s = signatures
        return (f"velocity residual grows with time at large opening (r = {number_text(s['long_move_r'], '+.2f')}) "
                f"and with |p_A - p_B| (r = {number_text(s['pressure_r'], '+.2f')})")
