"""Closed-centre 5/3 proportional valve: command to opening, ISO 6358 flow.

Opening
    ``x_v = sat((u - u_null) / 5 V, -1, 1)``: positive openings connect the
    supply P to chamber A and chamber B to exhaust; negative ones P to B and A to
    exhaust.  At ``x_v = 0`` every port is closed (closed centre).

Flow (ISO 6358-1:1989, with a laminar blend near pressure ratio 1)
    ``m_dot = C * rho_0 * p_up * sqrt(T_0 / T_up) * phi(p_dn / p_up)`` with
    ``phi = 1`` for choked flow (``r <= b``) and
    ``phi = sqrt(1 - ((r - b) / (1 - b))**2)`` for subsonic flow.  The subsonic
    branch has an infinite slope at ``r = 1``; below ``1 - r = 1e-3`` it is
    replaced by the straight line through zero that meets it (laminar flow,
    ISO 6358-3 uses the same 0.999 bound), so the right-hand side stays
    Lipschitz and Newton's method in CVODE keeps converging.
"""

from __future__ import annotations

import casadi as ca

__all__ = ["RHO0_KG_PER_M3", "T0_K", "LAMINAR_RATIO", "opening_from_command", "iso6358_mass_flow"]

#: ISO 6358 reference density and temperature (ANR: 293.15 K, 100 kPa, 65 % RH)
RHO0_KG_PER_M3 = 1.185
T0_K = 293.15
#: pressure ratio above which flow is laminar (linear in the pressure difference)
LAMINAR_RATIO = 0.999
#: command span for full opening, V (0-10 V valve, null at 5 V)
FULL_OPENING_V = 5.0


def opening_from_command(command_V, null_V, deadband_V=0.0):
    """Spool opening in [-1, 1] from the valve command.

    Parameters
    ----------
    command_V, null_V : SX
        Valve command and the valve's true null, V.
    deadband_V : SX or float
        Spool overlap: no opening while ``|u - null| <= deadband_V``; outside,
        the opening is rescaled so that full command is still full opening.
    """
    error = command_V - null_V
    if isinstance(deadband_V, (int, float)) and deadband_V == 0.0:
        return ca.fmin(ca.fmax(error / FULL_OPENING_V, -1.0), 1.0)
    beyond = ca.fmax(ca.fabs(error) - deadband_V, 0.0)
    scaled = ca.sign(error) * beyond / (FULL_OPENING_V - deadband_V)
    return ca.fmin(ca.fmax(scaled, -1.0), 1.0)


def iso6358_mass_flow(conductance, critical_ratio, p_1, p_2, T_1, T_2):
    """Signed mass flow from node 1 to node 2 through one ISO 6358 restriction, kg/s.

    Parameters
    ----------
    conductance : SX
        Sonic conductance C of the restriction as opened, m^3/(s Pa).
    critical_ratio : SX
        Critical pressure ratio b, dimensionless, in (0, 1).
    p_1, p_2 : SX
        Absolute pressures of the two nodes, Pa.
    T_1, T_2 : SX
        Gas temperatures of the two nodes, K (the upstream one is used).
    """
    forward = p_1 >= p_2
    p_up = ca.fmax(p_1, p_2)
    p_dn = ca.fmin(p_1, p_2)
    T_up = ca.if_else(forward, T_1, T_2)
    ratio = p_dn / p_up
    b = critical_ratio

    def subsonic(r):
        z = (ca.fmax(r, b) - b) / (1.0 - b)
        return ca.sqrt(ca.fmax(1.0 - z * z, 0.0))

    laminar = subsonic(LAMINAR_RATIO) * (1.0 - ratio) / (1.0 - LAMINAR_RATIO)
    phi = ca.if_else(ratio <= b, 1.0, ca.if_else(ratio < LAMINAR_RATIO, subsonic(ratio), laminar))
    magnitude = conductance * RHO0_KG_PER_M3 * p_up * ca.sqrt(T0_K / T_up) * phi
    return ca.if_else(forward, magnitude, -magnitude)
