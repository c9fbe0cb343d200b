"""The effect contract: everything the model, the fit and the diagnosis need to know about one effect.

An optional effect is physics the nominal model leaves out (``shared/spec/diagnosis.md``).  Each one
is a subclass of :class:`Effect` in its own module of this package, and declares there:

* **the law** -- ``description`` (one line, for ``pneusim effects``), ``source`` (where the law comes
  from) and the class docstring with the equation;
* **its parameters** -- ``parameters`` (name -> default, SI unit in the name), ``ranges`` (the
  physical range of each), ``options`` (name -> allowed values, the first the default) and
  ``states`` (its own state variables);
* **its hooks** -- the methods the actuator assembly calls at fixed places (a hook an effect does not
  override leaves the nominal physics unchanged, so any set of effects composes), and
  :meth:`Effect.static_force_N` for the state at rest;
* **what a fit frees** -- ``fit_free`` (parameter names), ``searched`` (those found by a search over a
  grid instead of by gradient) and ``fit_scale`` (the optimiser's scale and bounds of each);
* **how diagnosis screens it** -- ``neutral`` (the values at which it is nearly absent, or ``None``),
  :meth:`Effect.screening_starts`, ``data_sheet_start``, ``scanned``,
  :meth:`Effect.added_parameters`, ``refit_start_floor``, ``family`` (one of :data:`LOOK_ALIKE_FAMILIES`),
  :meth:`Effect.evidence`, :meth:`Effect.reported_options` and :meth:`Effect.derived_parameters`.

A fact every effect must declare starts as :data:`REQUIRED`; :func:`missing_facts` lists those an
effect class left so (``tests/pneusim/model/test_effect_contract.py`` fails on any).  The registry
(:mod:`.registry`) lists the effect classes; the fit and the diagnosis read these facts only through it.

Parameters enter the CasADi graph as symbols named ``EFFECT.PARAM`` (for example
``valve_deadband.deadband_V``), so a fit changes them without a rebuild.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

from ...errors import PneusimError

__all__ = ["Effect", "ScreeningStart", "REQUIRED", "LOOK_ALIKE_FAMILIES", "EVIDENCE_PLOTS", "POSITIVE", "NON_NEGATIVE",
           "POSITIVE_NEAR_START", "in_range", "range_words", "missing_facts", "number_text"]


class _Required:
    """Marks a fact an effect class must declare (see :func:`missing_facts`)."""

    def __repr__(self):
        return "REQUIRED"


#: the value of a fact an effect has not declared yet
REQUIRED = _Required()

#: look-alike families: effects whose signatures a recording can confuse.  When one of a family leads
#: the diagnosis's screening, the others are refitted too.
LOOK_ALIKE_FAMILIES = {
    "timing": "the response comes late after command changes (dead time, spool lag)",
    "friction and force": "a force in the piston's balance that depends on direction, position or pressure",
    "valve null": "the valve's behaviour around its null (where it opens, how far from nominal)",
    "slow pneumatic": "chamber pressures that drift or sag slowly (leaks, heat exchange, the supply line)",
}

#: the evidence plots a diagnosis report draws (:mod:`pneusim.diagnosis.evidence`), each a signature before and after
#: the findings: an effect names the one that identifies it (``evidence_plot``)
EVIDENCE_PLOTS = {
    "direction": "the velocity residual against the direction of motion (friction that differs each way)",
    "position": "the velocity residual against position (a force that depends on where the piston is)",
    "pressure difference": "the velocity residual's magnitude against the pressure difference across the seal",
    "lag": "the cross-correlation of command and residual increments against lag (the response comes late)",
    "command map": "the velocity against the command near null (a flat spot, or a shifted crossing)",
    "holding": "the velocity with the valve near null against position (creep while holding)",
    "relaxation": "the pressure residual's change against the time since the valve came back near null after a "
                  "move (a slow relaxation); the position residual's where no pressures were recorded",
    "over time": "the residuals against time",
}


@dataclass
class ScreeningStart:
    """One start of the diagnosis's screening of an effect.

    Attributes
    ----------
    label : str
        What the user reads in the progress and the report (``"valve dynamics from 10 Hz"``).
    effect : Effect
        The effect switched on, at its starting values and options.
    start_scale : dict
        Nominal parameters multiplied by these factors at the start (empty: the nominal fit's values).
    """

    label: str
    effect: "Effect"
    start_scale: dict = field(default_factory=dict)


class Effect:
    """Base class: an optional part of the actuator model, off unless listed.

    Subclasses declare the class attributes below (those set to :data:`REQUIRED` must be declared)
    and override :meth:`screening_starts` and :meth:`evidence`; see the module docstring and
    ``docs/adding-an-effect.md``.
    """

    # --- the law ---------------------------------------------------------
    name = ""
    description = ""
    #: where the law comes from: the vocabulary entry and the reference of the equation
    source: str = REQUIRED
    parameters: Mapping[str, float] = {}
    options: Mapping[str, tuple[str, ...]] = {}
    states: tuple[str, ...] = ()
    #: physical range of a parameter, ``name: (low, high, low_included, high_included)``; any
    #: parameter not listed must only be finite
    ranges: Mapping[str, tuple[float, float, bool, bool]] = {}

    # --- the fit -----------------------------------------------------------
    #: parameters (names without the ``EFFECT.`` prefix) a fit frees when the effect is switched on
    fit_free: tuple[str, ...] = REQUIRED
    #: of ``fit_free``: those found by a search over a grid instead of by gradient
    searched: tuple[str, ...] = ()
    #: the optimiser's ``(typical magnitude, lower, upper)`` of a parameter, SI units: the typical
    #: magnitude is the scale of ``theta = value / scale`` (``None``: the starting value's); a ``None``
    #: bound is 50 times the magnitude on that side; :data:`POSITIVE_NEAR_START` keeps the parameter
    #: within a factor 50 of its start.  Bounds are then narrowed to ``ranges``.  Every parameter in
    #: ``fit_free`` needs a row (see :func:`pneusim.fit.parameters.parameter_bounds`)
    fit_scale: Mapping[str, tuple] = {}

    # --- the diagnosis -------------------------------------------------------
    #: one of :data:`LOOK_ALIKE_FAMILIES`
    family: str = REQUIRED
    #: the values at which the effect is (nearly) absent, as its screening starts it: a refit nests the
    #: nominal model, so one that ends above the nominal residual is fitted once more from here.
    #: ``None``: the effect has no such value (it is never the nominal model) and is not retried
    neutral: Mapping[str, float] | None = REQUIRED
    #: the one screening start the screening from the data sheet keeps: ``(parameter, value)``, the start
    #: whose parameter has that value; ``None``: every start (they are different physics or a scan)
    data_sheet_start: tuple[str, float] | None = REQUIRED
    #: True when the screening starts away from the nominal model: it gets more trust-region evaluations
    scanned: bool = False
    #: the report's evidence plot of a finding of this effect, one of :data:`EVIDENCE_PLOTS`: the signature that
    #: identifies it, before and after the findings
    evidence_plot: str = "over time"
    #: the least value a refit starts a parameter at, ``name: value`` (none by default): a screening step may end a
    #: parameter on a bound where the effect is absent (a leak's conductance at zero), and its refit starts at least
    #: here instead
    refit_start_floor: Mapping[str, float] = {}
    #: False when the effect is left out of the pairs pre-fitted together on the mismatch window (it is pre-fitted
    #: there alone as every effect is): its own states, fitted freely on a window, absorb whatever else is missing
    window_pairs: bool = True

    def __init__(self, **values):
        self.values = dict(self.parameters)
        self.option_values = {k: v[0] for k, v in self.options.items()}
        for key, value in values.items():
            if key in self.options:
                if value not in self.options[key]:
                    raise PneusimError(f"effect {self.name}: option {key} must be one of "
                                       f"{', '.join(self.options[key])}, got {value!r}")
                self.option_values[key] = value
            elif key in self.parameters:
                try:
                    self.values[key] = float(value)
                except (TypeError, ValueError):
                    raise PneusimError(f"effect {self.name}: parameter {key} must be a number, "
                                       f"got {value!r}") from None
            else:
                known = ", ".join(list(self.parameters) + list(self.options))
                raise PneusimError(f"effect {self.name} has no parameter {key!r}; expected one of: {known}")
        for key, value in self.values.items():
            if not in_range(value, self.ranges.get(key)):
                raise PneusimError(f"effect {self.name}: parameter {key} must be "
                                   f"{range_words(self.ranges.get(key))}, got {value!r}")

    # --- identification ---------------------------------------------------
    def qualified(self) -> dict[str, float]:
        """``{EFFECT.PARAM: value}`` of the numeric parameters."""
        return {f"{self.name}.{k}": v for k, v in self.values.items()}

    def to_text(self) -> str:
        """The command-line form ``NAME:PARAM=VALUE,...`` that :func:`parse_effect_text` reads back."""
        items = {**self.option_values, **self.values}
        return self.name + ":" + ",".join(f"{k}={v!r}" if not isinstance(v, str) else f"{k}={v}"
                                          for k, v in items.items())

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in {**self.option_values, **self.values}.items())
        return f"{type(self).__name__}({args})"

    # --- hooks (ctx is the assembly context of actuator.py) -----------------
    def valve_null_V(self, ctx, null_V):
        return null_V

    def deadband_V(self, ctx):
        return 0.0

    def opening(self, ctx, commanded_opening):
        return commanded_opening

    def supply_Pa(self, ctx):
        return None

    def extra_flows(self, ctx):
        """List of ``(chamber 'a'|'b', signed mass flow into it kg/s, inflow temperature K)``."""
        return []

    def friction_factor(self, ctx):
        return 1.0

    def external_force_N(self, ctx):
        return 0.0

    def heat_rates_W(self, ctx):
        """``(Q_a, Q_b)`` into the chamber gas, or ``None`` for adiabatic chambers."""
        return None

    def derivatives(self, ctx) -> dict:
        """Rates of this effect's own states."""
        return {}

    def initial_state(self, params: Mapping[str, float], opening0: float) -> dict:
        return {}

    def static_force_N(self, params: Mapping[str, float], position_m: float) -> float:
        """Force this effect puts on the piston at rest at ``position_m``, N (positive pushes out),
        from the numeric parameter values ``params`` (``EFFECT.PARAM`` names): the initial state's
        pressures balance it (:meth:`~pneusim.model.ActuatorModel.initial_state`)."""
        return 0.0

    #: seconds by which the valve sees the command late (handled by the solver)
    def command_delay_s(self) -> float:
        return 0.0

    def p(self, ctx, key):
        return ctx.param(f"{self.name}.{key}")

    # --- diagnosis ------------------------------------------------------------
    @classmethod
    def screening_starts(cls, rig_values: Mapping[str, float], sample_time_s: float,
                         delays_s: Sequence[float] | None = None) -> list[ScreeningStart]:
        """The starts the diagnosis screens this effect from, in order.

        Parameters
        ----------
        rig_values : mapping
            The rig's data-sheet parameters (rig file names, SI units).
        sample_time_s : float
            The recording's sample time, s.
        delays_s : sequence of float, optional
            Transport delays to scan, s (read by the transport delay only).
        """
        raise NotImplementedError(f"effect {cls.name} declares no screening starts")

    @classmethod
    def evidence(cls, signatures: Mapping[str, float]) -> str:
        """The signature numbers that bear on this effect, in words (``signatures``: the dict of
        :func:`pneusim.diagnosis.signatures.compute_signatures`)."""
        raise NotImplementedError(f"effect {cls.name} declares no evidence text")

    @classmethod
    def added_parameters(cls, free: Sequence[str]) -> int:
        """Parameters the effect adds for the information criterion, given the ``free`` ones."""
        return max(1, len(free))

    @classmethod
    def reported_options(cls, option_values: Mapping[str, str]) -> dict:
        """The options a finding reports (those that say something about the fitted effect)."""
        return dict(option_values)

    @classmethod
    def derived_parameters(cls, values: Mapping[str, float], fitted) -> dict:
        """``values`` (the fitted effect parameters, no prefix) plus the parameters a user compares with
        a data sheet, derived from them; ``fitted(name)`` gives a fitted rig parameter's value."""
        return dict(values)


_INF = math.inf
POSITIVE = (0.0, _INF, False, False)
NON_NEGATIVE = (0.0, _INF, True, False)
#: the fit's row (see :attr:`Effect.fit_scale`) of a positive parameter kept within a factor 50 of its
#: start (a real rig differs from its data sheet by tens of percent, not by orders of magnitude)
POSITIVE_NEAR_START = (None, "pos", "pos")


def in_range(value: float, bounds) -> bool:
    """True when ``value`` is finite and inside ``bounds`` (``(low, high, low_included, high_included)``)."""
    if not math.isfinite(value):
        return False
    if bounds is None:
        return True
    lo, hi, lo_in, hi_in = bounds
    return (value >= lo if lo_in else value > lo) and (value <= hi if hi_in else value < hi)


def range_words(bounds) -> str:
    """``bounds`` in words: ``'a finite number'``, ``'>= 0'``, ``'in (0, 1]'``."""
    if bounds is None:
        return "a finite number"
    lo, hi, lo_in, hi_in = bounds
    if hi == _INF:
        return f"{'>=' if lo_in else '>'} {lo:g}"
    return f"in {'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"


def number_text(value, fmt: str) -> str:
    """``value`` formatted with ``fmt`` for an evidence text, ``'n/a'`` when it is None or not finite."""
    return "n/a" if value is None or not math.isfinite(value) else format(value, fmt)


def missing_facts(cls: type[Effect]) -> list[str]:
    """The facts ``cls`` has not declared: attributes still :data:`REQUIRED`, and the methods
    :meth:`Effect.screening_starts` and :meth:`Effect.evidence` when not overridden."""
    missing = [key for key in ("source", "fit_free", "family", "neutral", "data_sheet_start")
               if getattr(cls, key) is REQUIRED]
    for method in ("screening_starts", "evidence"):
        if getattr(cls, method).__func__ is getattr(Effect, method).__func__:
            missing.append(method)
    return missing
