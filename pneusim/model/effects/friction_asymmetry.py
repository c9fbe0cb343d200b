"""Friction asymmetry: seal friction that differs between extending and retracting."""

from __future__ import annotations

import casadi as ca

from .base import POSITIVE, Effect, ScreeningStart, number_text

__all__ = ["FrictionAsymmetry", "FRICTION_ASYMMETRY_SCAN", "SCALED_LEVELS"]

#: retract factors the screening starts from (1: the nominal model).  Away from 1 the static and Coulomb
#: levels start at 2/(1 + factor) of the nominal fit's, so that the mean of the two directions stays the
#: level the nominal fit found: from 1 alone a few trust-region steps may not move the factor on a
#: stick-slip recording, and from a factor away from 1 with the levels kept the start lies far above the
#: nominal cost, where the steps do not recover
FRICTION_ASYMMETRY_SCAN = (1.0, 2.0, 0.5)
#: the nominal friction levels the starts away from 1 scale
SCALED_LEVELS = ("friction_static_N", "friction_coulomb_N")


class FrictionAsymmetry(Effect):
    """Static and Coulomb friction multiplied by ``retract_factor`` while retracting (``v < 0``):
    ``F_s, F_c -> r F_s, r F_c`` in the Stribeck law (:func:`pneusim.model.piston.stribeck_friction_N`);
    viscous friction and the Stribeck velocity are the same both ways.  ``r = 1`` is the nominal model.
    """

    name = "friction_asymmetry"
    description = "static and Coulomb friction multiplied by a factor when retracting"
    source = ("vocabulary: shared/spec/diagnosis.md (friction_asymmetry); the Stribeck law of "
              "pneusim.model.piston with one level factor per direction")
    parameters = {"retract_factor": 1.5}
    ranges = {"retract_factor": POSITIVE}

    fit_free = ("retract_factor",)
    fit_scale = {"retract_factor": (1.0, 0.05, 20.0)}

    family = "friction and force"
    evidence_plot = "direction"
    neutral = {"retract_factor": 1.0}
    #: the screening from the data sheet runs each start to its end: from the nominal model
    data_sheet_start = ("retract_factor", 1.0)

    def friction_factor(self, ctx):
        return ca.if_else(ctx.v < 0, self.p(ctx, "retract_factor"), 1.0)

    @classmethod
    def screening_starts(cls, rig_values, sample_time_s, delays_s=None):
        """From each factor of :data:`FRICTION_ASYMMETRY_SCAN`, the levels' mean kept away from 1."""
        out = []
        for factor in FRICTION_ASYMMETRY_SCAN:
            mean_kept = {} if factor == 1.0 else {p: 2.0 / (1.0 + factor) for p in SCALED_LEVELS}
            out.append(ScreeningStart(f"friction asymmetry from {factor:g}", cls(retract_factor=factor), mean_kept))
        return out

    @classmethod
    def evidence(cls, signatures):
        s = signatures
        return (f"velocity residual follows the direction of motion (r = {number_text(s['direction_r'], '+.2f')}); "
                f"mean {number_text(s['extend_mean_mm_s'], '+.2f')} mm/s extending, "
                f"{number_text(s['retract_mean_mm_s'], '+.2f')} mm/s retracting")

    @classmethod
    def derived_parameters(cls, values, fitted):
        """Plus the Coulomb and static levels each way, N, as a data sheet gives them."""
        out = dict(values)
        if "retract_factor" in values:
            fc = fitted("friction_coulomb_N")
            fs = fitted("friction_static_N")
            out.update(coulomb_extend_N=fc, coulomb_retract_N=fc * values["retract_factor"],
                       static_extend_N=fs, static_retract_N=fs * values["retract_factor"])
        return out
