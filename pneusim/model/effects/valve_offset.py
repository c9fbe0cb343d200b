"""Valve offset: the valve's true null is the nominal null plus an offset."""

from __future__ import annotations

from .base import Effect, ScreeningStart, number_text

__all__ = ["ValveOffset"]


class ValveOffset(Effect):
    """The valve's true null voltage is ``u_null + offset_V``: the opening is computed from
    ``u - (u_null + offset_V)`` (:func:`pneusim.model.valve.opening_from_command`).  An offset of 0 is
    the nominal model exactly.
    """

    name = "valve_offset"
    description = "the valve's true null is the nominal null plus an offset"
    source = ("vocabulary: shared/spec/diagnosis.md (valve_offset); a shift of the null voltage of the "
              "nominal valve law")
    parameters = {"offset_V": 0.1}

    fit_free = ("offset_V",)
    #: within 2 V of the nominal null either way
    fit_scale = {"offset_V": (0.1, -2.0, 2.0)}

    family = "valve null"
    evidence_plot = "command map"
    neutral = {"offset_V": 0.0}
    data_sheet_start = None   # one start only

    def valve_null_V(self, ctx, null_V):
        return null_V + self.p(ctx, "offset_V")

    @classmethod
    def screening_starts(cls, rig_values, sample_time_s, delays_s=None):
        """From no offset: the nominal model itself."""
        return [ScreeningStart(cls.name, cls(offset_V=0.0))]

    @classmethod
    def evidence(cls, signatures):
        s = signatures
        return (f"measured velocity crosses zero {number_text(s['null_shift_V'], '+.3f')} V from the model's null; "
                f"creep near null {number_text(s['creep_mm_s'], '+.3f')} mm/s beyond the model")
