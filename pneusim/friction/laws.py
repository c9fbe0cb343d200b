"""Friction laws fitted to measured seal friction, as functions of velocity and chamber pressure.

Both laws are the model's Stribeck curve (:func:`pneusim.model.piston.stribeck_friction_N`),
with one level per direction (extend, retract) because a measured seal is rarely
symmetric:

``F(v, p) = g(p) F_c,d [1 + (r - 1) exp(-(v / v_s)^2)] tanh(v / v_eps) + b v``,

``d`` the direction of ``v``, ``r = F_s / F_c`` the static-to-Coulomb ratio (static level
``F_s,d = r F_c,d``).  The nominal law has ``g = 1`` (the same level at every
pressure).  The pressure law is that of the effect ``pressure_dependent_friction``
(:func:`pneusim.model.effects.seal_pressure_factor`): ``g(p) = (1 + k |p| / S) /
(1 + k p_ref / S)``, ``p`` the pressure difference across the seal (here the chamber
gauge pressure: the other side is open to atmosphere), ``S`` the supply gauge pressure
that normalises ``k`` (6 bar by default, the shipped rigs'), ``p_ref`` the reference
pressure at which the levels ``F_c,d``, ``F_s,d`` are stated.  With the same
reference, the two laws' levels mean the same thing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.effects import PRESSURE_SMOOTHING_PA, seal_pressure_factor

__all__ = ["FrictionLaw", "NOMINAL_LAW", "PRESSURE_LAW"]

_LEVELS = ("coulomb_extend_N", "coulomb_retract_N")
_SHAPE = ("static_over_coulomb", "stribeck_velocity_m_per_s", "viscous_N_s_per_m", "smoothing_velocity_m_per_s")

#: (typical magnitude, lower bound, upper bound) of each parameter, SI.  A friction test runs at
#: about one speed per direction, so the bounds keep the shape physical: levels and viscous friction
#: not negative, static friction 1 to 3 times the Coulomb level (one ratio for both directions).
#: The pressure coefficient may go slightly negative (the factor stays positive up to |p| = S) so
#: that friction without pressure dependence gives an estimate scattered about zero, not pinned at 0.
_TABLE = {
    "coulomb_extend_N": (5.0, 0.0, 1e3),
    "coulomb_retract_N": (5.0, 0.0, 1e3),
    "static_over_coulomb": (1.0, 1.0, 3.0),
    "stribeck_velocity_m_per_s": (3e-3, 5e-4, 0.02),
    "viscous_N_s_per_m": (100.0, 0.0, 1e4),
    "smoothing_velocity_m_per_s": (1e-3, 5e-5, 5e-3),
    "pressure_coefficient": (1.0, -0.5, 20.0),
}


@dataclass(frozen=True)
class FrictionLaw:
    """A friction law: its parameter names, its force and the force's Jacobian.

    Static levels are ``static_over_coulomb`` times the Coulomb level of each direction.

    Attributes
    ----------
    name : str
        ``"nominal"`` or ``"pressure_dependent_friction"``.
    parameter_names : tuple of str
    """

    name: str
    parameter_names: tuple

    @property
    def scales(self) -> np.ndarray:
        return np.array([_TABLE[n][0] for n in self.parameter_names])

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([_TABLE[n][1] for n in self.parameter_names], float),
                np.array([_TABLE[n][2] for n in self.parameter_names], float))

    def start(self, velocity_m_per_s: np.ndarray, friction_N: np.ndarray) -> np.ndarray:
        """Starting values from the data: the median friction while sliding in each direction."""
        ext = friction_N[velocity_m_per_s > 2e-3]
        ret = friction_N[velocity_m_per_s < -2e-3]
        f_ext = float(np.median(ext)) if ext.size else 1.0
        f_ret = float(-np.median(ret)) if ret.size else 1.0
        values = {"coulomb_extend_N": f_ext, "coulomb_retract_N": f_ret, "static_over_coulomb": 1.2,
                  "stribeck_velocity_m_per_s": 3e-3, "viscous_N_s_per_m": 0.0,
                  "smoothing_velocity_m_per_s": 1e-3, "pressure_coefficient": 0.5}
        lo, hi = self.bounds
        return np.clip([values[n] for n in self.parameter_names], lo, hi)

    def force_N(self, theta, velocity_m_per_s, pressure_Pa, reference_Pa: float, supply_gauge_Pa: float,
                jacobian: bool = False):
        """Friction force, N, shape of ``velocity_m_per_s`` (and its Jacobian, shape (N, n_parameters)).

        Parameters
        ----------
        theta : array, shape (len(parameter_names),)
            Parameter values in SI units, in :attr:`parameter_names` order.
        velocity_m_per_s, pressure_Pa : ndarray, shape (N,)
            Piston velocity and pressure difference across the seal.
        reference_Pa : float
            The pressure at which the levels are stated.
        supply_gauge_Pa : float
            Normalising pressure ``S`` of the pressure coefficient.
        """
        p = dict(zip(self.parameter_names, theta))
        v = np.asarray(velocity_m_per_s, float)
        extend = v >= 0.0
        coulomb = np.where(extend, p["coulomb_extend_N"], p["coulomb_retract_N"])
        ratio, v_s = p["static_over_coulomb"], p["stribeck_velocity_m_per_s"]
        v_eps, b = p["smoothing_velocity_m_per_s"], p["viscous_N_s_per_m"]
        bump = np.exp(-(v / v_s) ** 2)
        shape = 1.0 + (ratio - 1.0) * bump
        smooth = np.tanh(v / v_eps)
        gain = np.ones_like(v)
        if "pressure_coefficient" in p:
            gain = seal_pressure_factor(np.asarray(pressure_Pa, float), p["pressure_coefficient"],
                                        reference_Pa, supply_gauge_Pa, tanh=np.tanh)
        level = gain * coulomb * shape
        force = level * smooth + b * v
        if not jacobian:
            return force
        columns = {"coulomb_extend_N": gain * shape * smooth * extend,
                   "coulomb_retract_N": gain * shape * smooth * ~extend,
                   "static_over_coulomb": gain * coulomb * bump * smooth,
                   "stribeck_velocity_m_per_s": gain * coulomb * (ratio - 1.0) * bump * 2.0 * v ** 2 / v_s ** 3 * smooth,
                   "viscous_N_s_per_m": v,
                   "smoothing_velocity_m_per_s": level * (1.0 - smooth ** 2) * (-v / v_eps ** 2)}
        if "pressure_coefficient" in p:
            k = p["pressure_coefficient"]
            magnitude = np.asarray(pressure_Pa, float) * np.tanh(np.asarray(pressure_Pa, float) / PRESSURE_SMOOTHING_PA)
            d_gain = (magnitude - reference_Pa) / supply_gauge_Pa / (1.0 + k * reference_Pa / supply_gauge_Pa) ** 2
            columns["pressure_coefficient"] = d_gain * coulomb * shape * smooth
        return force, np.column_stack([columns[n] for n in self.parameter_names])


NOMINAL_LAW = FrictionLaw("nominal", _LEVELS + _SHAPE)
PRESSURE_LAW = FrictionLaw("pressure_dependent_friction", _LEVELS + _SHAPE + ("pressure_coefficient",))
