"""``diagnose(recording)``: locate the mismatch, name the physics left out, model it, show the fit improve.

The one call the command line, the batch runs and the notebooks use: it runs :class:`.estimator.Diagnosis`
with these options (the method, step by step, is in :mod:`.estimator`'s docstring; its thresholds in
:mod:`.rules`).
"""

from __future__ import annotations

from .estimator import Diagnosis
from .result import DiagnosisResult
from .rules import MAX_LOOKALIKES, MAX_REFITS, MIN_SAMPLES, VALIDATION_FRACTION

__all__ = ["diagnose", "MIN_SAMPLES"]


def diagnose(recording, rig=None, *, effects=None, validation_fraction: float = VALIDATION_FRACTION,
             max_refits: int = MAX_REFITS, max_lookalikes: int = MAX_LOOKALIKES, max_findings: int | None = None,
             screen_samples: int | None = None, progress: bool = False,
             several_effects: bool | None = None, time_budget_s: float | None = None) -> DiagnosisResult:
    """Diagnose what physics the nominal model leaves out of ``recording``.

    Parameters
    ----------
    recording : Recording or path
        A ``pneusim-recording/1`` file (CSV or .mat) or a loaded recording.
    rig : Rig, str or None
        The rig's data sheet (default: the recording's ``rig`` metadata).
    effects : sequence of str, optional
        Vocabulary effects to consider (default: all of ``diagnosis.md``).
    validation_fraction : float
        Final fraction of the recording kept for validation (never fitted).
    max_refits : int
        Leading candidates confirmed by a whole refit, one per look-alike family
        (:data:`.candidates.FAMILIES`).
    max_lookalikes : int
        Look-alikes of the winning candidate (same family) refitted in a second round.
    max_findings : int, optional
        At most this many findings (effects modelled together); default :data:`.rules.MAX_FINDINGS` (2), with
        ``several_effects`` :data:`.rules.MAX_FINDINGS_SEVERAL` (3).
    screen_samples : int, optional
        Estimation samples the screening uses (default :data:`.rules.SCREEN_SAMPLES`).
    progress : bool
        Print one line per stage to standard error.
    several_effects : bool or None
        The several-effects search (every vocabulary variant screened on top of the findings, one more at a
        time, each finding tested with the others present (drop-one), ``other`` after the findings where they
        leave physics unexplained, under a time budget; see :mod:`.estimator`).  None (default): where the
        one-effect-first search's findings leave the recording unexplained, it goes on from them; True: from
        the first finding on; False: never.
    time_budget_s : float, optional
        Seconds the diagnosis may take, counted in model work at the reference machine's rate (the same search
        and answer on every machine; :mod:`.budget`): no fit that would end past it is started, one that runs
        past it is stopped, and the result (``status``) says which step; default :func:`.rules.default_budget_s`
        (ten nominal fits, at least :data:`.rules.TIME_BUDGET_S`), :data:`.rules.TIME_BUDGET_S` with
        ``several_effects=True``, no limit with ``several_effects=False``.

    Returns
    -------
    DiagnosisResult
        Its ``to_dict()`` is the JSON of ``shared/spec/diagnosis.md``.

    Raises
    ------
    PneusimError
        Unknown rig or effect, a recording too short, a validation window without motion, or a
        recording the nominal fit cannot start on (one sentence each).
    """
    return Diagnosis(effects=effects, validation_fraction=validation_fraction, max_refits=max_refits,
                     max_lookalikes=max_lookalikes, max_findings=max_findings, screen_samples=screen_samples,
                     progress=progress, several_effects=several_effects,
                     time_budget_s=time_budget_s).fit(recording, rig)
