"""Piston: force balance, Stribeck friction and end stops.

``m a = p_a A_a - p_b A_b - p_atm A_rod - F_friction + F_stops + F_external``

Friction (Stribeck curve, smoothed through zero velocity with ``tanh``; Armstrong-
Helouvry 1994):
``F = (F_c + (F_s - F_c) exp(-(v / v_s)^2)) tanh(v / v_eps) + b v``.

End stops are stiff spring-dampers that act only while the piston penetrates
them and only push (never pull the piston back into contact).
"""

from __future__ import annotations

import casadi as ca

__all__ = ["stribeck_friction_N", "end_stop_force_N"]


def stribeck_friction_N(velocity, static_N, coulomb_N, stribeck_velocity, viscous, smoothing_velocity):
    """Friction force opposing motion, N (positive for positive velocity)."""
    stribeck = coulomb_N + (static_N - coulomb_N) * ca.exp(-(velocity / stribeck_velocity) ** 2)
    return stribeck * ca.tanh(velocity / smoothing_velocity) + viscous * velocity


def end_stop_force_N(position, velocity, stroke_m, stiffness, damping):
    """Contact force of the two end stops on the piston, N (positive pushes out)."""
    below = position < 0.0
    above = position > stroke_m
    push_out = ca.fmax(stiffness * (-position) - damping * velocity, 0.0)
    push_in = ca.fmax(stiffness * (position - stroke_m) + damping * velocity, 0.0)
    return ca.if_else(below, push_out, 0.0) - ca.if_else(above, push_in, 0.0)
