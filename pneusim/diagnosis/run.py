"""One recording's diagnosis as it goes: what every step reads and writes.

A step of :class:`~.estimator.Diagnosis` takes a :class:`DiagnosisRun`: the recording and the rig, the nominal
baseline every refit is compared with (:class:`NominalBaseline`), the options, the stages it calls
(:class:`~.estimator.DiagnosisStages`: the fits, the screenings, the keep test) and the progress line; and it
records its outcome there: a :class:`~.result.CandidateTrial` per effect (``trials``), the kept and rejected
refits (``refits``, ``{effect: (fit, candidate)}``), the candidates left to the screening on top of the
first finding (``second_only``, ``{effect: candidate}``), and every candidate a search on top of the findings
screens (``on_top``, ``{label: candidate}``) and the labels already refitted on top (``refitted_on_top``).  A test builds one with stand-in stages and runs one
step alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, NamedTuple

from .rules import MAX_FINDINGS, MAX_LOOKALIKES, MAX_REFITS

__all__ = ["NominalBaseline", "WindowScreening", "DiagnosisRun"]


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

    def rms(self, cost: float) -> float:
        """The rms, in noise units, of an estimation cost (sum of squared residuals over the noise) spread over the
        nominal fit's residual count: how far above the noise a fit of that cost ends."""
        return math.sqrt(cost / max(self.n_residuals, 1))


class WindowScreening(NamedTuple):
    """The screening from the data sheet's window (:mod:`.from_data_sheet`): the pre-fit options that describe it
    (its first sample, length, evaluations), the nominal model's pre-fit there (``base``), whether it shows the
    mismatch, and every candidate's pre-fit alone (``singles``: ``{label: (candidate, pre-fit or None)}``)."""

    options: dict
    base: object
    shows_mismatch: bool
    singles: dict


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
    max_refits, max_lookalikes, max_findings, several_effects
        The options of :class:`~.estimator.Diagnosis`.
    screen_samples : int or None
        Estimation samples the screening uses (None: :data:`~.rules.SCREEN_SAMPLES`).
    n_screen : int
        Residuals of the screening window (the ``ln N`` of a screening score).
    say : callable
        ``say(message)``: one progress line.
    trials, refits, second_only, on_top : dict
        What the steps found (see the module docstring).
    refitted_on_top : set
        Labels of the candidates refitted on top of findings (none is refitted twice on top of the same ones).
    window : WindowScreening or None
        The screening from the data sheet's window: its pre-fit options, the nominal model's pre-fit there and
        every candidate's pre-fit alone (None where the screening ran around the nominal fit).
    window_sets : list
        The sets of effects pre-fitted together on that window (:mod:`.window_sets`), best first.
    window_sets_s : float
        Wall seconds the pre-fits of those sets took (0 where none were pre-fitted).
    contributions : dict
        ``{effect: points}``: the validation fit each finding adds with all the others present, from the last
        drop-one test (:func:`.findings.drop_one`).
    joint : WindowSet or None
        The set of ``window_sets`` fitted whole together (None where none was): drop-one fits its subsets as it was
        fitted (:func:`.window_sets.subset_from_prefit`).
    rescues : list of dict
        Every fit fitted again with the fit's rescue routes (:func:`.refits.rescued`), in the order they ran.
    """

    recording: object
    rig: object
    baseline: NominalBaseline
    stages: object
    max_refits: int = MAX_REFITS
    max_lookalikes: int = MAX_LOOKALIKES
    max_findings: int = MAX_FINDINGS
    several_effects: bool = False
    screen_samples: int | None = None
    n_screen: int = 0
    say: Callable = _silent
    trials: dict = field(default_factory=dict)
    refits: dict = field(default_factory=dict)
    second_only: dict = field(default_factory=dict)
    on_top: dict = field(default_factory=dict)
    refitted_on_top: set = field(default_factory=set)
    window: object = None
    window_sets: list = field(default_factory=list)
    window_sets_s: float = 0.0
    contributions: dict = field(default_factory=dict)
    joint: object = None
    rescues: list = field(default_factory=list)

    @property
    def noise(self) -> dict:
        """Sensor noise std per measured signal (the baseline's)."""
        return self.baseline.noise

    def kept_by_fit(self) -> list[str]:
        """The kept effects, best validation fit first."""
        return sorted((k for k in self.refits if self.trials[k].kept), key=lambda k: -self.refits[k][0].fit_percent)
