"""One recording's diagnosis as it goes: what every step reads and writes.

A step of :class:`~.estimator.Diagnosis` takes a :class:`DiagnosisRun`: the recording and the rig, the nominal
baseline every refit is compared with (:class:`NominalBaseline`), the options, the stages it calls
(:class:`~.estimator.DiagnosisStages`: the fits, the screenings, the keep test) and the progress line; and it
records its outcome there: a :class:`~.result.CandidateTrial` per effect (``trials``), the kept and rejected
refits (``refits``, ``{effect: (fit, candidate)}``), and the candidates left to the screening on top of the
first finding (``second_only``, ``{effect: candidate}``).  It also holds the time budget and the stage clock
(:mod:`.budget`) and the expected cost of a whole fit on this recording.  A test builds one with stand-in stages
and runs one step alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, NamedTuple

from .budget import Budget, StageClock
from .rules import MAX_FINDINGS, MAX_LOOKALIKES, MAX_REFITS, STATE_COST

__all__ = ["NominalBaseline", "DiagnosisRun"]


class NominalBaseline(NamedTuple):
    """What the keep test compares a refit with: the sensor noise, the nominal fit's estimation
    residual sum of squares and residual count, its validation fit %, the noise floor in points; and
    the nominal fit itself (a refit ending above it is retried from there)."""

    noise: dict
    cost0: float
    n_residuals: int
    fit0: float
    floor: float
    validation_fraction: float
    fit: object = None


def _silent(message: str) -> None:
    """No progress line."""


@dataclass
class DiagnosisRun:
    """One recording's diagnosis as it goes (see the module docstring).

    Attributes
    ----------
    recording, rig
        The recording and the rig the nominal fit used.
    baseline : NominalBaseline
    stages : DiagnosisStages
        The callables the steps use (:class:`~.estimator.DiagnosisStages`).
    max_refits, max_lookalikes, max_findings : int
        The options of :class:`~.estimator.Diagnosis`.
    screen_samples : int or None
        Estimation samples the screening uses (None: :data:`~.rules.SCREEN_SAMPLES`).
    n_screen : int
        Residuals of the screening window (the ``ln N`` of a screening score).
    say : callable
        ``say(message)``: one progress line.
    trials, refits, second_only : dict
        What the steps found (see the module docstring).
    budget : Budget
        The CPU time the diagnosis may still use (:class:`~.budget.Budget`; no limit by default).
    clock : StageClock
        Wall and CPU seconds by stage.
    fit_cost_s : float
        The expected CPU cost of a whole fit on this recording: the nominal fit's own (0: unknown).
    candidates : list of Candidate
        Every variant of every vocabulary effect the diagnosis considers (:func:`.candidates.candidate_list`).
    ranked : list of str
        The effects in the order of the first screening.
    final : FitResult or None
        The fit with every finding, once the findings are settled.
    window_items : list
        Far above noise, every candidate's pre-fit alone on the window, ``[(score, candidate, pre-fit)]``.
    fits_without : dict
        ``{effect: the fit of the other findings without it}`` (drop-one's).
    set_fits : dict
        ``{frozenset of effect names: the lowest fit of that set met so far}`` (:meth:`remember`).
    """

    recording: object
    rig: object
    baseline: NominalBaseline
    stages: object
    max_refits: int = MAX_REFITS
    max_lookalikes: int = MAX_LOOKALIKES
    max_findings: int = MAX_FINDINGS
    screen_samples: int | None = None
    n_screen: int = 0
    say: Callable = _silent
    trials: dict = field(default_factory=dict)
    refits: dict = field(default_factory=dict)
    second_only: dict = field(default_factory=dict)
    budget: Budget = field(default_factory=Budget)
    clock: StageClock = field(default_factory=StageClock)
    fit_cost_s: float = 0.0
    candidates: list = field(default_factory=list)
    ranked: list = field(default_factory=list)
    final: object = None
    window_items: list = field(default_factory=list)
    fits_without: dict = field(default_factory=dict)
    set_fits: dict = field(default_factory=dict)

    def remember(self, fit) -> None:
        """Keep ``fit`` as the fit of its set of effects (``set_fits``) unless one of the same set is lower on the
        estimation part."""
        from .refits import estimation_cost

        key = frozenset(e.name for e in fit.effects_)
        known = self.set_fits.get(key)
        if known is None or estimation_cost(fit, self.noise)[0] < estimation_cost(known, self.noise)[0]:
            self.set_fits[key] = fit

    def can_fit(self, step: str, fits: float = 1.0, effects=()) -> bool:
        """Whether ``step``, ``fits`` whole fits' worth of CPU time with ``effects`` switched on, fits in the budget
        (:meth:`.Budget.allows`): a whole fit costs the nominal fit's time, times ``1 +``
        :data:`~.rules.STATE_COST` per state the effects add."""
        states = sum(len(e.states) for e in effects)
        return self.budget.allows(step, fits * self.fit_cost_s * (1.0 + STATE_COST * states))

    @property
    def noise(self) -> dict:
        """Sensor noise std per measured signal (the baseline's)."""
        return self.baseline.noise

    def kept_by_fit(self) -> list[str]:
        """The kept effects, best validation fit first."""
        return sorted((k for k in self.refits if self.trials[k].kept), key=lambda k: -self.refits[k][0].fit_percent)
