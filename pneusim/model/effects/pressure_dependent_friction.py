"""Pressure-dependent friction: seal friction that grows with the pressure difference across the seal."""

from __future__ import annotations

import casadi as ca

from .base import NON_NEGATIVE, Effect, ScreeningStart, number_text

__all__ = ["PressureDependentFriction", "PRESSURE_SMOOTHING_PA", "SCREENING_COEFFICIENT", "seal_pressure_factor"]

#: Pa: |p_A - p_B| is smoothed as d tanh(d / this): within 0.1 Pa of |d| above 6 kPa, at most 0.28 of this below
PRESSURE_SMOOTHING_PA = 1000.0
#: the pressure coefficient the screening starts from and the neutral value: small, the effect nearly
#: absent, so the screening starts where the nominal fit ended
SCREENING_COEFFICIENT = 0.05


def seal_pressure_factor(difference_Pa, pressure_coefficient, reference_difference_Pa, supply_gauge_Pa,
                         tanh=ca.tanh):
    """Factor on the static and Coulomb levels of :class:`PressureDependentFriction`, dimensionless.

    ``(1 + k |d| / S) / (1 + k d_ref / S)`` with ``d = p_A - p_B`` (Pa), ``|d|`` smoothed as
    ``d tanh(d / PRESSURE_SMOOTHING_PA)``, ``S`` the supply gauge pressure (Pa).  Works on CasADi
    symbols, and on NumPy arrays with ``tanh=numpy.tanh``.
    """
    magnitude = difference_Pa * tanh(difference_Pa / PRESSURE_SMOOTHING_PA)
    return ((1.0 + pressure_coefficient * magnitude / supply_gauge_Pa)
            / (1.0 + pressure_coefficient * reference_difference_Pa / supply_gauge_Pa))


class PressureDependentFriction(Effect):
    """Seal friction that grows with the pressure difference across the piston seal.

    The law of the vocabulary (``shared/spec/diagnosis.md``): static and Coulomb
    levels are ``F_0 (1 + k |p_A - p_B| / S)``, with ``F_0`` the level at zero
    difference, ``k = pressure_coefficient`` (dimensionless) and ``S`` the supply
    gauge pressure ``supply_Pa - atmosphere_Pa`` of the rig (Pa).  Viscous
    friction and the Stribeck velocity are unchanged.

    Parameterisation: the rig's ``friction_static_N`` and ``friction_coulomb_N``
    stay the levels *at* ``reference_difference_Pa`` (``d_ref``), so the effect
    multiplies them by ``(1 + k |d| / S) / (1 + k d_ref / S)``.  A constant-friction
    (nominal) fit finds about the level at the pressure differences the recording
    runs at; with ``d_ref`` there (default 50 kPa: a rig at rest near mid-stroke
    holds 30-45 kPa across its seal, and moves start from there), the nominal
    estimates are the right starting values when the effect is switched on, the
    levels keep their meaning, and ``k`` is nearly uncorrelated with them.  With
    the levels at zero difference instead, switching the effect on would move
    the levels by a factor ``1 + k d_ref / S`` and tie them to ``k``.  ``d_ref``
    is a choice of reference, not a property of the seal: do not free it in a fit
    (it is degenerate with the levels); set it, e.g., to the typical ``|p_A - p_B|``
    of the recording.  ``k = 0`` is the nominal model exactly.

    ``|p_A - p_B|`` is smoothed (:data:`PRESSURE_SMOOTHING_PA`) so that the
    right-hand side stays differentiable for CVODE's Newton iteration and the
    fit's sensitivities, like the ``tanh`` of the friction through zero velocity.
    """

    name = "pressure_dependent_friction"
    description = ("static and Coulomb friction that grow with |p_A - p_B|: "
                   "level(d) = level(d_ref) (1 + k|d|/S) / (1 + k d_ref/S), S the supply gauge pressure")
    source = ("vocabulary: shared/spec/diagnosis.md (pressure_dependent_friction): levels F_0 (1 + k |p_A - p_B| / S), "
              "here referred to the levels at d_ref")
    parameters = {"pressure_coefficient": 2.0, "reference_difference_Pa": 5.0e4}
    ranges = {"pressure_coefficient": NON_NEGATIVE, "reference_difference_Pa": NON_NEGATIVE}

    #: the reference difference is a choice of reference, degenerate with the friction levels: never freed
    fit_free = ("pressure_coefficient",)
    #: friction grows with the pressure across the seal: k >= 0 (the effect's own range)
    fit_scale = {"pressure_coefficient": (1.0, 0.0, 20.0)}

    family = "friction and force"
    evidence_plot = "pressure difference"
    neutral = {"pressure_coefficient": SCREENING_COEFFICIENT}
    data_sheet_start = None   # one start only

    def friction_factor(self, ctx):
        return seal_pressure_factor(ctx.p_a - ctx.p_b, self.p(ctx, "pressure_coefficient"),
                                    self.p(ctx, "reference_difference_Pa"),
                                    ctx.param("supply_Pa") - ctx.param("atmosphere_Pa"))

    @classmethod
    def screening_starts(cls, rig_values, sample_time_s, delays_s=None):
        return [ScreeningStart(cls.name, cls(pressure_coefficient=SCREENING_COEFFICIENT))]

    @classmethod
    def evidence(cls, signatures):
        return (f"squared velocity residual grows with |p_A - p_B| "
                f"(r = {number_text(signatures['pressure_r'], '+.2f')})")
