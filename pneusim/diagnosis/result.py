"""The result of a mismatch diagnosis; its JSON form is the contract of ``shared/spec/diagnosis.md``."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["MismatchWindow", "Finding", "CandidateTrial", "DiagnosisResult"]


def _num(value, digits: int = 6):
    """A JSON number (None for NaN or infinity), rounded to ``digits`` significant digits."""
    if value is None:
        return None
    value = float(value)
    if not math.isfinite(value):
        return None
    return float(f"{value:.{digits}g}")


@dataclass
class MismatchWindow:
    """A stretch of the recording where the nominal model's residual exceeds the sensor noise.

    ``score`` is the window's mean squared residual divided by the noise variance (1 for pure noise); the JSON
    gives its square root, ``residual_rms_noise_units`` (the report's "residual / noise (rms)"), so that a reader
    of the file can rank the windows as the report does.  An episode (windows merged, :func:`.locate.episodes`)
    names its strongest window's signal and condition, and the other signals its windows were in (``also_in``).
    """

    t_start_s: float
    t_end_s: float
    signal: str
    condition: str
    score: float = 1.0
    also_in: tuple = ()

    @property
    def residual_rms_noise_units(self) -> float:
        """The window's root-mean-square residual in units of the sensor noise (1 for pure noise)."""
        return math.sqrt(max(self.score, 0.0))

    def to_dict(self) -> dict:
        out = {"t_start_s": _num(self.t_start_s), "t_end_s": _num(self.t_end_s), "signal": self.signal,
               "condition": self.condition, "residual_rms_noise_units": _num(self.residual_rms_noise_units, 3)}
        if self.also_in:
            out["also_in"] = list(self.also_in)
        return out


@dataclass
class Finding:
    """An effect that the nominal model left out, modelled and kept.

    Attributes
    ----------
    effect : str
        A vocabulary name of ``diagnosis.md``, or ``other``.
    evidence : str
        What points to it, as numbers a user can check.
    parameters : dict
        Fitted effect parameters (SI units, unit in the name).
    standard_errors : dict
        Their standard errors (same units; None where the data do not pin one down).
    fit_percent : float
        Validation fit of the position with this finding (and the ones ranked before it) modelled, %.
    improvement_points : float
        ``fit_percent`` minus the validation fit without this finding, percentage points.
    mismatch : list of MismatchWindow
        ``other`` only: the episodes where the unexplained residual is, with their operating conditions.
    closest : list of dict
        ``other`` only: the vocabulary candidates that came closest, ``{"effect", "why_rejected", "fit_percent"}``.
    signatures : dict
        ``other`` only: the signature numbers of the unexplained residual.
    """

    effect: str
    evidence: str
    parameters: dict
    fit_percent: float
    improvement_points: float
    standard_errors: dict = field(default_factory=dict)
    mismatch: list = field(default_factory=list)
    closest: list = field(default_factory=list)
    signatures: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        out = {"effect": self.effect, "evidence": self.evidence,
               "parameters": {k: (_num(v) if not isinstance(v, str) else v) for k, v in self.parameters.items()},
               "standard_errors": {k: _num(v) for k, v in self.standard_errors.items()},
               "fit_percent": _num(self.fit_percent), "improvement_points": _num(self.improvement_points)}
        if self.effect == "other":
            out["mismatch"] = [w.to_dict() for w in self.mismatch]
            out["closest"] = [{**c, "fit_percent": _num(c.get("fit_percent"))} for c in self.closest]
            out["signatures"] = {k: (_num(v) if isinstance(v, (int, float)) else v)
                                 for k, v in self.signatures.items()}
        return out


@dataclass
class CandidateTrial:
    """One candidate effect: its screening evidence and, when refitted, the outcome of the test."""

    effect: str
    score: float
    evidence: str
    refitted: bool = False
    status: str = "not refitted"
    fit_percent: float | None = None
    improvement_points: float | None = None
    estimation_cost_drop: float | None = None
    threshold: float | None = None
    kept: bool = False
    parameters: dict = field(default_factory=dict)
    seconds: float | None = None

    def to_dict(self) -> dict:
        return {"effect": self.effect, "score": _num(self.score), "evidence": self.evidence,
                "refitted": self.refitted, "status": self.status, "fit_percent": _num(self.fit_percent),
                "improvement_points": _num(self.improvement_points),
                "estimation_cost_drop": _num(self.estimation_cost_drop), "threshold": _num(self.threshold),
                "kept": self.kept,
                "parameters": {k: (_num(v) if not isinstance(v, str) else v) for k, v in self.parameters.items()},
                "seconds": _num(self.seconds, 4)}


@dataclass
class DiagnosisResult:
    """What :func:`pneusim.diagnose` found.

    Attributes
    ----------
    recording : str
        File name of the recording.
    rig : str
    validation : dict
        ``t_start_s``, ``t_end_s`` of the validation part, never used for fitting.
    nominal : dict
        ``fit_percent`` (validation fit of the fitted nominal model, %) and ``parameters`` (fitted values, SI).
    mismatch : list of MismatchWindow
    findings : list of Finding
        Ranked, most important first; empty when nothing is missing, or when the time budget stopped the search
        before anything passed the test (``status`` then says so, and :attr:`no_findings` in words).
    final_fit_percent : float
        Validation fit with every kept finding modelled, %.
    candidates : list of CandidateTrial
        Every candidate screened, with the refits tried and their test outcome (a failed refit is
        reported here with its error, not raised).
    seconds : float
        Wall time of the diagnosis.
    status : str
        ``"complete"``, or ``"stopped by the time budget: ..."`` naming the first step the budget refused (the
        result then holds what was found before it).
    search : str
        How far the search for findings went: ``"one effect first"`` (a second effect among the candidates the
        first round kept or set aside), ``"one effect first, then several"`` (those findings left the model above
        noise and the several-effects search went on from them) or ``"several effects"`` (from the first finding
        on, ``several_effects=True``).
    episodes : list of MismatchWindow
        The nominal fit's mismatch windows merged into a few episodes (:func:`.locate.episodes`).
    final_parameters : dict
        The nominal model's parameters as fitted with every finding (SI), beside ``nominal["parameters"]``
        fitted without them: how far the nominal parameters had bent to make up for the missing physics.
    timing : dict
        ``nominal_fit_s``, ``screening_s``, ``refits_s``: wall time of each stage, the refits split into
        ``first_finding_s`` (confirming the first round and the delay scan), ``on_top_s`` (the search on top of
        the findings) and ``drop_one_s``, and ``window_sets_s`` (within ``first_finding_s``: the pre-fits of the
        sets of effects on the mismatch window, :mod:`.window_sets`), ``rescue_s`` (within the stage that asked
        for each: the fits fitted again with the rescue routes, ``rescues``); ``cpu_s``: the diagnosis's processor time
        (this process, both fit threads); ``budget_s``: the time budget it used (model work at the reference rate,
        :mod:`.budget`).
    window_sets : list of dict
        Where no effect alone explained the screening's window: the sets of effects pre-fitted together there
        (:mod:`.window_sets`), best first, each ``{"effects", "variants", "window_objective_normalised",
        "criterion"}``.
    rescues : list of dict
        The fits fitted again with the fit's rescue routes (:func:`.refits.rescued`), in the order they ran, each
        ``{"where", "effects", "fit_percent_before", "estimation_rms_before", "fit_percent_after",
        "estimation_rms_after", "kept", "outcome", "seconds"}``: the validation fit % and the estimation part's rms
        residual in noise units (continuity defects included) before and after (no ``_after`` where the fit failed
        or the time budget stopped it), whether the new fit was kept (it ends lower) and the wall seconds.
    nominal_fit, final_fit : FitResult
        The fits themselves (for plots; not part of the JSON).
    """

    recording: str
    rig: str
    validation: dict
    nominal: dict
    mismatch: list
    findings: list
    final_fit_percent: float
    candidates: list = field(default_factory=list)
    test: str = ""
    seconds: float = 0.0
    status: str = "complete"
    search: str = "one effect first"
    episodes: list = field(default_factory=list)
    final_parameters: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    window_sets: list = field(default_factory=list)
    rescues: list = field(default_factory=list)
    nominal_fit: object = None
    final_fit: object = None
    signatures: dict = field(default_factory=dict)
    fits: dict = field(default_factory=dict)

    @property
    def effects(self) -> list[str]:
        """Names of the findings, ranked."""
        return [f.effect for f in self.findings]

    @property
    def no_findings(self) -> tuple[str, str]:
        """What an empty ``findings`` means, ``(verdict, because)`` in words: "nothing is missing" only where the
        search ran to its end; where the time budget stopped it first, that nothing is known (the model may still
        be far off)."""
        if self.status == "complete":
            return "nothing is missing", "no vocabulary effect improved the held-out fit by more than noise explains"
        return ("not known whether something is missing", f"the time budget stopped the search before any "
                f"vocabulary effect passed the test (validation fit {self.final_fit_percent:.2f} % without one)")

    def to_dict(self) -> dict:
        """The JSON result of ``diagnosis.md``, plus ``candidates`` (every candidate screened, the refits and
        their test outcome, failures included), ``test`` (the keep rule in words) and ``timing`` (s)."""
        return {
            "recording": self.recording,
            "rig": self.rig,
            "validation": {"t_start_s": _num(self.validation["t_start_s"]),
                           "t_end_s": _num(self.validation["t_end_s"])},
            "nominal": {"fit_percent": _num(self.nominal["fit_percent"]),
                        "parameters": {k: _num(v) for k, v in self.nominal["parameters"].items()}},
            "mismatch": [w.to_dict() for w in self.mismatch],
            "findings": [f.to_dict() for f in self.findings],
            "final_fit_percent": _num(self.final_fit_percent),
            "final_parameters": {k: _num(v) for k, v in self.final_parameters.items()},
            "episodes": [w.to_dict() for w in self.episodes],
            "status": self.status,
            "search": self.search,
            "candidates": [c.to_dict() for c in self.candidates],
            **({"window_sets": list(self.window_sets)} if self.window_sets else {}),
            **({"rescues": [{k: _num(v, 4) if isinstance(v, float) else v for k, v in r.items()}
                            for r in self.rescues]} if self.rescues else {}),
            "test": self.test,
            "timing": {"total_s": _num(self.seconds, 4), **{k: _num(v, 4) for k, v in self.timing.items()}},
        }

    def write_json(self, path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1, allow_nan=False))
        return path

    def summary(self) -> str:
        """A few lines for the terminal."""
        lines = [f"{self.recording} ({self.rig}): nominal validation fit {self.nominal['fit_percent']:.2f} %"]
        if self.mismatch:
            lines.append(f"mismatch beyond noise in {len(self.mismatch)} window(s), e.g. "
                         + "; ".join(f"{w.t_start_s:.2f}-{w.t_end_s:.2f} s {w.signal} ({w.condition})"
                                     for w in self.mismatch[:3]))
        else:
            lines.append("no residual window beyond the sensor noise")
        if not self.findings:
            lines.append("findings: none - {}: {}".format(*self.no_findings))
        for k, f in enumerate(self.findings, 1):
            params = ", ".join(f"{n} = {v:.4g}" if not isinstance(v, str) else f"{n} = {v}"
                               for n, v in f.parameters.items())
            lines.append(f"{k}. {f.effect}: validation fit {f.fit_percent:.2f} % (+{f.improvement_points:.2f} "
                         f"points); {params}")
            lines.append(f"   evidence: {f.evidence}")
        lines.append(f"final validation fit {self.final_fit_percent:.2f} %; {self.seconds:.0f} s")
        if self.status != "complete":
            lines.append(self.status)
        return "\n".join(lines)
