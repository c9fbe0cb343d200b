"""External load: a force not in the nominal model, constant (gravity, a process load) plus a spring."""

from __future__ import annotations

from ..chamber import areas_m2
from .base import NON_NEGATIVE, Effect, ScreeningStart, number_text

__all__ = ["ExternalLoad", "LOAD_SCAN_FRACTIONS"]

#: constant loads the screening starts from, as fractions of the full supply force on the bore (0: the
#: nominal model; the vocabulary's loads are tenths of it).  Also from loads of either sign: far from the
#: optimum a stuck model piston makes the response to a small load nearly flat, and a few steps from 0 N
#: then move the force by a fraction of what is there
LOAD_SCAN_FRACTIONS = (0.0, 0.15, -0.15)


class ExternalLoad(Effect):
    """A force on the piston (positive pushes out): ``F_ext = force_N - stiffness_N_per_m x``, ``x`` the
    position, added to the piston's force balance (:mod:`pneusim.model.piston`).  Gravity on a
    vertically mounted cylinder or a process load is the constant, a return spring the stiffness
    (its force at ``x = 0`` in the constant).  ``kind`` says which the user means; the law is the same.
    """

    name = "external_load"
    description = "a force not in the nominal model: constant (gravity, process load) plus a spring"
    source = ("vocabulary: shared/spec/diagnosis.md (external_load); a constant force plus a linear "
              "spring in the piston's force balance")
    parameters = {"force_N": 0.0, "stiffness_N_per_m": 0.0}
    ranges = {"stiffness_N_per_m": NON_NEGATIVE}
    options = {"kind": ("constant", "spring")}

    fit_free = ("force_N", "stiffness_N_per_m")
    #: typical magnitudes: tens of newtons, hundreds of newtons per metre (bounds 50 times either way,
    #: the stiffness then narrowed to >= 0)
    fit_scale = {"force_N": (50.0, None, None), "stiffness_N_per_m": (500.0, None, None)}

    family = "friction and force"
    evidence_plot = "position"
    neutral = {"force_N": 0.0, "stiffness_N_per_m": 0.0}
    #: the screening from the data sheet runs each start to its end: from no load
    data_sheet_start = ("force_N", 0.0)
    scanned = True

    def external_force_N(self, ctx):
        return self.p(ctx, "force_N") - self.p(ctx, "stiffness_N_per_m") * ctx.x_pos

    def static_force_N(self, params, position_m):
        return params["external_load.force_N"] - params["external_load.stiffness_N_per_m"] * position_m

    @classmethod
    def screening_starts(cls, rig_values, sample_time_s, delays_s=None):
        """From each fraction of :data:`LOAD_SCAN_FRACTIONS` of the supply's gauge force on the bore, no spring."""
        supply = float(rig_values["supply_Pa"])
        area_a, _, _ = areas_m2(float(rig_values["bore_m"]), float(rig_values["rod_m"]))
        full_force = (supply - float(rig_values["atmosphere_Pa"])) * area_a
        out = []
        for fraction in LOAD_SCAN_FRACTIONS:
            force = fraction * full_force
            out.append(ScreeningStart(f"external load from {force:.0f} N", cls(force_N=force, stiffness_N_per_m=0.0)))
        return out

    @classmethod
    def evidence(cls, signatures):
        s = signatures
        return (f"velocity residual against position r = {number_text(s['position_r'], '+.2f')}; mean "
                f"{number_text(s['extend_mean_mm_s'], '+.2f')} mm/s extending, "
                f"{number_text(s['retract_mean_mm_s'], '+.2f')} mm/s retracting")

    @classmethod
    def reported_options(cls, option_values):
        """None: ``kind`` does not change the law, the fitted force and stiffness say what the load is."""
        return {}
