"""Cylinder chambers: volumes and the pressure (and temperature) balance.

Energy balance of an ideal gas in a variable volume, inflow at its upstream
temperature, outflow at the chamber's (Richer & Hurmuzlu 2000, eq. 17 without
heat loss; with heat exchange as in Carneiro & de Almeida 2006):

``dp/dt = gamma R / V * (sum_in m_dot T_in - sum_out m_dot T) - gamma p dV/dt / V
+ (gamma - 1) / V * Q_dot``.

In the nominal (adiabatic) model the chamber temperature is not a state and
every ``T`` is the supply temperature, which gives
``dp/dt = gamma R T / V (m_in - m_out) - gamma p V_dot / V``.
"""

from __future__ import annotations

import math



__all__ = ["GAMMA", "R_AIR_J_PER_KG_K", "areas_m2", "chamber_volumes_m3", "pressure_rate", "temperature_rate"]

GAMMA = 1.4
R_AIR_J_PER_KG_K = 287.05


def areas_m2(bore_m, rod_m):
    """Piston areas: (cap side A, annulus side B, rod cross-section), m^2."""
    area_a = math.pi / 4.0 * bore_m**2
    area_rod = math.pi / 4.0 * rod_m**2
    return area_a, area_a - area_rod, area_rod


def chamber_volumes_m3(position_m, velocity_m_per_s, stroke_m, area_a, area_b, dead_a, dead_b):
    """Volumes of A and B and their rates: (V_a, V_b, dV_a/dt, dV_b/dt)."""
    volume_a = dead_a + area_a * position_m
    volume_b = dead_b + area_b * (stroke_m - position_m)
    return volume_a, volume_b, area_a * velocity_m_per_s, -area_b * velocity_m_per_s


def pressure_rate(pressure, volume, volume_rate, enthalpy_in, heat_rate=0.0):
    """dp/dt of a chamber, Pa/s.

    Parameters
    ----------
    enthalpy_in : SX
        ``sum(m_dot_i * T_i)`` over all ports, kg K/s, signed positive into the
        chamber, each flow at its upstream temperature.
    heat_rate : SX
        Heat flow from the walls into the gas, W.
    """
    return (GAMMA * R_AIR_J_PER_KG_K / volume * enthalpy_in
            - GAMMA * pressure * volume_rate / volume
            + (GAMMA - 1.0) / volume * heat_rate)


def temperature_rate(temperature, pressure, pressure_rate_, volume, volume_rate, mass_rate):
    """dT/dt from the ideal gas law ``T = p V / (m R)``, K/s."""
    mass = pressure * volume / (R_AIR_J_PER_KG_K * temperature)
    return temperature * (pressure_rate_ / pressure + volume_rate / volume - mass_rate / mass)
