"""The diagnosis's rules: every threshold that decides what is screened, what is fitted, what is kept, in one place.

Each rule is a named constant with its unit in parentheses and its reason in one line (``#:`` above it), so that
the whole policy reads on one screen and a change to one rule is weighed against its siblings; the table of
``docs/diagnosis.md`` ("Rules") is generated from these lines by :func:`table_markdown`.  The keep test
(:func:`passes_test`, :func:`validation_room`, the information criterion and the noise floor ``F``) is written
here too, as the rule it is.  The recordings that decided each rule are in the decision records
(``docs/decisions/0027``-``0033``, and ``0077``-``0086``).

Units: a *normalised* residual is the rms over the sensor noise std (1 at the noise level); a *cost* is a
residual sum of squares in noise units; *points* are percentage points of MATLAB's fit % of the position on the
validation part; ``F`` is the fit that white sensor noise alone takes away there (:func:`noise_floor_points`).
"""

from __future__ import annotations

import ast
import inspect
import math

import numpy as np

from ..errors import PneusimError, SolverError
from ..fit import rules as fit_rules

__all__ = [
    "MIN_SAMPLES", "VALIDATION_FRACTION", "VALIDATION_FRACTION_RANGE", "VALIDATION_MOTION_NOISE",
    "FALSE_ALARM", "LOCATE_WINDOW_S", "LOCATE_WINDOW_SAMPLES", "MAX_WINDOWS", "MAX_EPISODES", "EPISODE_GAP",
    "EPISODE_LENGTH",
    "MODEL_SHORT", "MAX_REFITS", "MAX_LOOKALIKES", "MAX_FINDINGS", "MAX_FINDINGS_SEVERAL",
    "SCREEN_SAMPLES", "SCREEN_EVALUATIONS", "SCANNED_EVALUATIONS", "DEFECT_WEIGHT", "DELAY_LAG_FACTORS",
    "DELAY_LAG_CORRELATION", "RELATIVE_SCORE", "MIN_EXPLAINED",
    "WINDOW_SAMPLES", "PREFIT_EVALUATIONS", "AT_NOISE_ON_WINDOW", "WINDOW_SHOWS_MISMATCH", "MAX_FITS", "EXPLAINED",
    "RIVAL_WINDOW", "RIVAL_ON_TOP", "DEFER_WINDOW", "PREFIT_START", "DATA_SHEET_FIT_STARTS", "DATA_SHEET_FIT_RESCUE", "SET_LEADERS", "WINDOW_DELAY_STEPS", "SET_EXPLAINS_WINDOW", "SET_SHRINK", "SET_FIT_SHARE",
    "MIN_IMPROVEMENT_POINTS", "ERROR_SHRINK", "CLEARLY_SHORT", "AT_NOISE", "PERFECT_ERROR",
    "DELAY_SCAN_ERROR_RATIO", "SCAN_FACTOR", "SCAN_REFITS", "DELAY_GRID_PER_SAMPLE", "MIN_DELAY_SAMPLES",
    "ON_TOP_REFITS", "OTHER_RESIDUAL", "FURTHER_SEARCH_RESIDUAL", "MAX_CLOSEST", "TIME_BUDGET_S", "WORK_UNITS_PER_S", "BUDGET_BACKSTOP", "BUDGET_NOMINAL_FITS", "default_budget_s", "COMMAND_MAP_SPAN", "COMMAND_MAP_BINS", "SETS_SHOWN",
    "MOVING_STROKE", "NEAR_NULL_SPAN", "LARGE_OPENING_HALF_SPAN", "END_STOP_STROKE", "HIGH_PRESSURE_SUPPLY",
    "LOW_PRESSURE_ATMOSPHERES", "FAST_CHANGE_SPAN", "FAST_CHANGE_S", "REVERSAL_S", "CONDITION_SHARE",
    "REVERSAL_SHARE", "OFF_NULL_V", "SMALL_COMMAND_V",
    "SOLVER_FAILURES",
    "bic_penalty", "information_gain", "noise_floor_points", "validation_room", "passes_test", "keep_test_text",
    "screening_route", "is_solver_failure", "rules_table", "table_markdown",
]

# --------------------------------------------------------------------------------------------- the input
#: (samples) a recording shorter than this cannot be split into estimation and validation parts worth fitting
MIN_SAMPLES = 500
#: (fraction of the recording) the final part kept for validation unless told otherwise: the fit's own default
VALIDATION_FRACTION = fit_rules.DEFAULT_VALIDATION_FRACTION
#: (fraction of the recording) the validation fractions accepted: enough to score a model, enough left to fit it
VALIDATION_FRACTION_RANGE = (0.05, 0.5)
#: (position-noise stds) the piston must move over at least this range in the validation part to score a model
VALIDATION_MOTION_NOISE = 20

# ---------------------------------------------------------------------------------- the operating conditions
#: (fraction of the stroke per second) the piston moves (extends, retracts) faster than this, and holds still
#: otherwise: well above the noise of a differentiated position, well below any commanded motion
MOVING_STROKE = 0.01
#: (fraction of the valve's span) the valve is near null this close to it: a leak's creep while holding and the
#: pressures' settling after a move show there
NEAR_NULL_SPAN = 0.02
#: (fraction of the valve's half span) beyond this from null the valve is wide open: a long move's heating and a
#: supply's droop show there
LARGE_OPENING_HALF_SPAN = 0.4
#: (fraction of the stroke) the piston is near an end stop this close to either end
END_STOP_STROKE = 0.05
#: (fraction of supply, absolute) a chamber above this is at high pressure
HIGH_PRESSURE_SUPPLY = 0.8
#: (atmospheres) a chamber below this is at low pressure
LOW_PRESSURE_ATMOSPHERES = 1.3
#: (fraction of the valve's span) a command change larger than this from one sample to the next is fast
FAST_CHANGE_SPAN = 0.1
#: (s) a fast command change marks the samples this long after it, the spool's and the chambers' response
FAST_CHANGE_S = 0.05
#: (s) a velocity reversal marks this long on either side of it, where the friction changes sign
REVERSAL_S = 0.05
#: (fraction of a window's samples) a mismatch window is described by the conditions that hold on more of it
CONDITION_SHARE = 0.5
#: (fraction of a window's samples) a window is described as a velocity reversal where more of it is one: a
#: reversal marks a tenth of a second, a smaller share of most windows than a direction
REVERSAL_SHARE = 0.2
#: (V) the small-command speed deficit reads commands at least this far from null (2 % of the paper rigs' 5 V half
#: span, a fixed voltage on any rig): the smallest quarter of them still opens the valve
OFF_NULL_V = 0.1
#: (V) the signatures read the velocity's zero crossing and the smallest commands that move the piston (a flat
#: spot's edge) on commands this close to null, where a line fits the velocity
SMALL_COMMAND_V = 1.0

# ------------------------------------------------------------------------------------------------ locate
#: (probability) a recording explained up to noise flags a window with at most this probability (Bonferroni
#: over the windows of the recording)
FALSE_ALARM = 1e-3
#: (s) the sliding window's length, unless told otherwise: long enough to average the noise of a few samples
LOCATE_WINDOW_S = 0.1
#: (samples) the sliding window is never shorter: a chi-square quantile of fewer degrees of freedom is too wide
LOCATE_WINDOW_SAMPLES = 20
#: (windows) at most this many mismatch windows are reported, the strongest
MAX_WINDOWS = 50
#: (episodes) the windows are merged into at most this many episodes for a reader, the strongest
MAX_EPISODES = 5
#: (fraction of the recording's duration) windows closer than this join one episode ...
EPISODE_GAP = 0.02
#: (fraction of the recording's duration) ... while it stays shorter than this: a residual above noise all along
#: is said as several episodes a reader can find, not as the whole recording
EPISODE_LENGTH = 0.1

# ------------------------------------------------------------------------------ which screening, how many fits
#: (normalised residual) the fit's own threshold (pneusim.fit.rules, one definition): a nominal fit ending more
#: than this above noise has bent its parameters to make up for missing physics, so candidates are screened
#: from the data sheet, not around it
MODEL_SHORT = fit_rules.MODEL_SHORT
#: (refits) leading candidates confirmed by a whole fit, one per look-alike family, unless told otherwise
MAX_REFITS = 3
#: (refits) look-alikes of each kept candidate (or of the leader) fitted in a second round, unless told otherwise
MAX_LOOKALIKES = 2
#: (effects) at most this many findings modelled together, unless told otherwise: the first and one on top of it
MAX_FINDINGS = 2
#: (effects) ... with several effects searched for (``several_effects``): a worn rig shows up to three at once, and
#: each one more is screened and tested on top of all the others
MAX_FINDINGS_SEVERAL = 3

# ---------------------------------------------------------------------------- near noise: around the nominal fit
#: (samples) the screening's window: at most this many of the estimation part's first samples
SCREEN_SAMPLES = 2500
#: (trust-region evaluations) per screened candidate: a rank needs a few steps downhill, not an optimum
SCREEN_EVALUATIONS = 6
#: (trust-region evaluations) per candidate screened away from the nominal model (an effect's ``scanned``, or a
#: start that moves nominal parameters): the nominal parameters need more steps to follow a moved response
SCANNED_EVALUATIONS = 12
#: (1) continuity weight of the screening problem and of every cost compared: the fit's penalty weight
DEFECT_WEIGHT = fit_rules.PENALTY_WEIGHT
#: (times the lag) transport delays screened around the lag of the command-residual cross-correlation
DELAY_LAG_FACTORS = (0.6, 1.0, 1.6)
#: (correlation) the lag points to a delay only where the cross-correlation's peak exceeds this in magnitude
DELAY_LAG_CORRELATION = 0.1
#: (fraction of the best score) a candidate is refitted only when its screening score is at least this ...
RELATIVE_SCORE = 0.05
#: (fraction of the cost) ... and it explains at least this fraction of the nominal cost on the screening window
#: (also the least share a second effect must explain on top of the first finding to be refitted there)
MIN_EXPLAINED = 0.01

# ------------------------------------------------------------------------- far above noise: from the data sheet
#: (samples) the window every candidate is pre-fitted on, where the nominal residual is largest: the fit's own
#: pre-fit window
WINDOW_SAMPLES = 2000
#: (trust-region evaluations) of each pre-fit, direct route only: a rank needs no polish, and a wrong candidate
#: may wander into stiff corners of its parameters
PREFIT_EVALUATIONS = 40
#: (normalised residual) a candidate whose pre-fit ends within this explains the window: only its look-alikes
#: are pre-fitted after it
AT_NOISE_ON_WINDOW = 1.2
#: (times AT_NOISE_ON_WINDOW) the window shows the mismatch only where the nominal model's pre-fit ends above
#: this: a window the nominal model explains says nothing
WINDOW_SHOWS_MISMATCH = 2.0
#: (whole fits) at most this many whole fits from the data sheet: each costs as much as a nominal fit
MAX_FITS = 6
#: (normalised residual) a kept candidate whose whole fit ends within this has explained the recording: the
#: other families are not fitted
EXPLAINED = 1.5
#: (ratio of window rms) a candidate whose pre-fit ends more than this above the best kept one's is no rival for
#: the first finding: not fitted whole, screened as a second effect on top of it; and a subset of a set fitted
#: jointly whose pre-fit ends more than this above the set's is no rival for the set: drop-one does not fit it
#: from the data sheet; where the window's best set, fitted whole, ends more than MODEL_SHORT times above noise, the
#: same effects through another variant (a leak's other path) whose pre-fit ends within this of the set's are
#: fitted whole too
RIVAL_WINDOW = 3.0
#: (ratio of shares explained) a look-alike whose screening on top of the findings explains less than this
#: fraction of what the candidate kept there explained is no rival for it: not refitted in its place
RIVAL_ON_TOP = 0.33
#: (ratio of window rms) the first round fits effects without states first, except one whose pre-fit ends more
#: than this above the round's best: it waits for the others
DEFER_WINDOW = 5.0
#: (ratio of window rms) a whole fit starts from its pre-fit's nominal values only where that pre-fit ended
#: within this fraction of the nominal pre-fit's residual: else they are where its evaluations left them
PREFIT_START = 0.5
#: (starts) of a whole fit from the data sheet: the pre-fit on the window chose its start
DATA_SHEET_FIT_STARTS = 1
#: (yes/no) a whole fit from the data sheet runs the fit's rescue routes where it ends above noise: no. They find the
#: optimum of a model that is right on a chaotic recording; a candidate on a recording that lacks more physics than
#: it ends above noise by any route, and the routes took over a third of a three-effect recording's diagnosis.  The
#: fit the search goes on from (the first finding's, or a pair's found jointly) gets them where it ends above noise,
#: and the findings' fit before ``other`` is said (:func:`~.refits.rescued`)
DATA_SHEET_FIT_RESCUE = False
#: (effects) where no effect alone explains the window, the effects whose pre-fits alone lead there are pre-fitted
#: together, in pairs (each variant of each), as the several effects a recording may lack at once
SET_LEADERS = 4
#: (pre-fits) before the pairs, the best screened transport delay is followed downhill on the window by at most
#: this many pre-fits, a factor SCAN_FACTOR apart: the screened delays sit where other missing physics moved the lag
WINDOW_DELAY_STEPS = 4
#: (normalised objective) the best set of the window is fitted whole only where its pre-fit ends within this: a set
#: that leaves the window an order of magnitude above noise explains too little of it to choose the physics (more
#: is missing than the set, or something outside the vocabulary), and the one-effect-first search decides
SET_EXPLAINS_WINDOW = 10.0
#: (ratio of window objective rms) ... and only where it ends at most this fraction of the best single effect's, as
#: the keep test asks a refit to shrink the validation error (ERROR_SHRINK): the window's information criterion
#: counts its residuals as independent, which they are not, and lets a second effect in for a hair
SET_SHRINK = 0.9
#: (fraction) the best set's whole fit may use at most this share of the time budget left when it starts: where it
#: cannot finish there, the one-effect-first confirmation that follows still has the rest (a whole fit of a pair
#: from the data sheet can take several times a single effect's, and one that ran to the budget's end left nothing)
SET_FIT_SHARE = 0.5

# -------------------------------------------------------------------------------------------- the keep test
#: (points) a refit must raise the validation fit by more than max(this, F): less is within what a short
#: validation window gives by chance
MIN_IMPROVEMENT_POINTS = 0.5
#: (fraction of the nominal validation error) a kept refit's validation error is at most this: at least 10 %
#: smaller
ERROR_SHRINK = 0.9
#: (times F) a nominal validation error at least this is clearly short of the noise floor ...
CLEARLY_SHORT = 2.0
#: (times F) ... and a refit's at most this explains the held-out data down to noise: it passes by more than F
AT_NOISE = 1.25
#: (times F) below any validation error a model explaining everything but the noise reaches (the rms of
#: N >= 1000 noise samples scatters by 1 / sqrt(2 N)): where no refit can pass, nothing is screened
PERFECT_ERROR = 0.9

# ---------------------------------------------------------------------------------- the transport delay's scan
#: (ratio of validation errors) a kept delay is scanned with refits where it leads, or where its validation
#: error is at most this many times the leader's: the scan moves a delay along its valley, not a look-alike's
DELAY_SCAN_ERROR_RATIO = 3.0
#: (ratio of delays) neighbouring delays of the refit scan
SCAN_FACTOR = 1.5
#: (refits) at most this many in the scan
SCAN_REFITS = 8
#: (grid steps per sample) delays are tried on a grid of a tenth of a sample: finer is below what a refit resolves
DELAY_GRID_PER_SAMPLE = 10
#: (samples) the least delay tried
MIN_DELAY_SAMPLES = 0.5

# --------------------------------------------------------------------------------------- findings and other
#: (refits) at most this many candidates are refitted on top of each set of findings, those whose screening explains
#: most there first, unless the findings leave physics unexplained (then every one explaining MIN_EXPLAINED there,
#: before ``other`` is said): near noise a further effect is a detail
ON_TOP_REFITS = 2
#: (normalised residual) with nothing kept, a nominal residual above this (the residuals alone, not the
#: continuity defects a penalty fit left open) in mismatch windows is reported as ``other``
OTHER_RESIDUAL = 3.0
#: (normalised residual) where the one-effect-first search's findings leave the estimation residuals (without the
#: defects) above this, the fit's own "above noise" level, and room on the validation part for a refit to pass the
#: keep test, the several-effects search goes on from them: the model is still above noise
FURTHER_SEARCH_RESIDUAL = fit_rules.ABOVE_NOISE_WARNING
#: (candidates) the ``other`` finding names at most this many closest vocabulary candidates, with why each failed
MAX_CLOSEST = 3
#: (s, counted in model work at WORK_UNITS_PER_S) with several effects searched for from the first finding on
#: (``several_effects=True``), a diagnosis starts no fit that would end past this and stops one that runs past it,
#: unless told otherwise: it returns what it has, its status naming the step refused (five minutes of wall time on
#: a busy two-core machine)
TIME_BUDGET_S = 240.0
#: (units of model work a second) the rate at which the budget's seconds are counted in model work (the
#: integrator's steps, weighted by the states and columns each integrates, :mod:`pneusim.solver.work`): the
#: diagnoses' work over their processor time on the reference machine (a 2-core Xeon VM, two diagnoses at a time,
#: one BLAS thread each: 29.9e6 to 38.8e6 on four several-effects diagnoses the budget stopped, single fits 29.8e6
#: to 34.4e6), so that a budget there lasts about its seconds of processor time and, counted in work, buys the
#: same search on every machine (decision record 0116)
WORK_UNITS_PER_S = 35e6
#: (times the budget, s of processor time) the backstop that ends a search whose work the count misses (the
#: optimisers' own linear algebra, a machine far slower than the reference): far above what a budget's work costs
#: on any machine in use
BUDGET_BACKSTOP = 4.0
#: (nominal fits) by default a diagnosis may cost this many times its nominal fit's share of the budget, and at least
#: TIME_BUDGET_S: a recording whose every fit is slow gets the same number of fits as one whose fits are quick, and
#: none runs unbounded (the default search took a median 4.8 nominal fits on practice2, where it had no budget)
BUDGET_NOMINAL_FITS = 10.0

# ------------------------------------------------------------------------------------------------ the report
#: (fraction of the valve's span) the command-velocity map shows commands this close to null, where a dead band's
#: flat spot or an offset's shifted zero crossing is
COMMAND_MAP_SPAN = 0.15
#: (bins) the map's resolution near null: a bin per command level where there are fewer
COMMAND_MAP_BINS = 40
#: (sets) the report lists at most this many of the sets fitted together on the window, the best (the JSON has all)
SETS_SHOWN = 8


# ---------------------------------------------------------------------------------- the keep test, as a rule
def bic_penalty(k: int, n: int) -> float:
    """The information criterion's price of ``k`` added parameters on ``n`` residuals: ``k ln n`` (BIC)."""
    return k * math.log(n)


def information_gain(cost0: float, cost1: float, n: int, k: int) -> float:
    """The BIC's drop from cost ``cost0`` to ``cost1`` (``n`` residuals, ``k`` added parameters):
    ``n ln(C0 / C1) - k ln n``; positive when the added parameters pay for themselves."""
    return n * math.log(max(cost0, 1e-300) / max(cost1, 1e-300)) - bic_penalty(k, n)


def noise_floor_points(recording, n_est: int, noise: dict) -> float:
    """``F``: the fit percentage points that white sensor noise alone takes from a perfect model on the
    validation part (samples ``n_est:``), ``100 sigma sqrt(N_val) / ||y - mean(y)||``."""
    y = recording.position_m[n_est:]
    den = float(np.linalg.norm(y - y.mean()))
    return 100.0 * noise["position_m"] * math.sqrt(y.size) / den if den > 0 else float("inf")


def default_budget_s(nominal_s: float) -> float:
    """The default diagnosis's time budget, seconds (counted in work, :mod:`.budget`): :data:`BUDGET_NOMINAL_FITS`
    times the nominal fit's share ``nominal_s``, at least :data:`TIME_BUDGET_S`."""
    return max(TIME_BUDGET_S, BUDGET_NOMINAL_FITS * nominal_s)


def validation_room(fit0: float, floor_points: float) -> float:
    """How far the nominal validation error ``100 - fit0`` lies above the least error any refit could
    reach and still pass :func:`passes_test`, in points (<= 0: no refit can pass).

    A refit passes on the validation part only by more than ``max(0.5, F)`` points with an error of at
    least :data:`PERFECT_ERROR` ``F`` (what white noise leaves a perfect model), or from an error of at
    least :data:`CLEARLY_SHORT` ``F``; a nominal error below both says that nothing can be found, whatever
    the estimation part shows."""
    err0 = 100.0 - fit0
    return err0 - min(max(MIN_IMPROVEMENT_POINTS, floor_points) + PERFECT_ERROR * floor_points,
                      CLEARLY_SHORT * floor_points)


def passes_test(cost0: float, cost1: float, n: int, k: int, fit0: float, fit1: float,
                floor_points: float) -> tuple[bool, float, str]:
    """The keep test: a refit (estimation cost ``cost1``, validation fit ``fit1`` %) is kept against the model
    before it (``cost0``, ``fit0``) when both hold:

    1. *estimation part*: the information criterion drops, ``n ln(C0 / C1) > k ln n``
       (:func:`information_gain`; ``n`` residuals, ``k`` added parameters);
    2. *validation part* (never fitted): the fit rises by more than ``max(0.5, F)`` points
       (:data:`MIN_IMPROVEMENT_POINTS`, ``F`` = ``floor_points``) and the validation error shrinks to at most
       :data:`ERROR_SHRINK` of its value; or, near the noise floor, it falls from at least :data:`CLEARLY_SHORT`
       ``F`` to at most :data:`AT_NOISE` ``F``, by more than ``F`` (the model was clearly short on the held-out
       data and the effect explains it down to noise).

    Returns ``(kept, threshold_points, reason)``."""
    bic_gain = information_gain(cost0, cost1, n, k)
    threshold = max(MIN_IMPROVEMENT_POINTS, floor_points)
    err0, err1 = 100.0 - fit0, 100.0 - fit1
    if not (math.isfinite(fit1) and math.isfinite(cost1)):
        return False, threshold, "refit failed to give a finite fit"
    if bic_gain <= 0:
        return False, threshold, f"estimation: BIC does not drop (N ln(C0/C1) - k ln N = {bic_gain:.1f})"
    below_threshold = fit1 - fit0 <= threshold
    to_noise = (err0 >= CLEARLY_SHORT * floor_points and err1 <= AT_NOISE * floor_points
                and fit1 - fit0 > floor_points)
    if below_threshold and not to_noise:
        return False, threshold, (f"validation: +{fit1 - fit0:.2f} points, not above the noise threshold "
                                  f"{threshold:.2f}")
    if err1 > ERROR_SHRINK * err0:
        return False, threshold, f"validation: error shrinks by less than {100 * (1 - ERROR_SHRINK):.0f} %"
    if below_threshold:
        return True, floor_points, (
            f"BIC gain {bic_gain:.0f} on the estimation part; validation +{fit1 - fit0:.2f} points > F = "
            f"{floor_points:.2f}, its error from {err0 / floor_points:.2f} F to {err1 / floor_points:.2f} F (down to "
            "the noise floor)")
    return True, threshold, (f"BIC gain {bic_gain:.0f} on the estimation part; validation +{fit1 - fit0:.2f} points "
                             f"> {threshold:.2f}")


def keep_test_text(floor_points: float, fit0: float, room: float) -> str:
    """The keep test in words, with this recording's ``F`` (the result's ``test``)."""
    text = ("keep a candidate when its refit lowers the BIC on the estimation part (N ln(C0/C1) > k ln N, C the "
            "residual sum of squares in sensor-noise units) and raises the validation fit by more than "
            f"max({MIN_IMPROVEMENT_POINTS:g}, F) = {max(MIN_IMPROVEMENT_POINTS, floor_points):.2f} points, "
            f"F = {floor_points:.2f} the fit white sensor noise alone takes away (or by more than F where it takes a "
            f"validation error of at least {CLEARLY_SHORT:g} F down to at most {AT_NOISE:g} F), with the validation "
            f"error at least {100 * (1 - ERROR_SHRINK):.0f} % smaller")
    if room <= 0:
        text += (f"; the nominal validation error, {100 - fit0:.3g} points, is already within reach of the noise "
                 f"floor (no refit can end below {PERFECT_ERROR:g} F), so no candidate was screened")
    return text


def screening_route(room_points: float, nominal_rms: float) -> str:
    """Which screening a recording gets: ``"none"`` where no refit could pass the keep test on the validation
    part (:func:`validation_room` <= 0); ``"from the data sheet"`` where the nominal fit's normalised residual on
    its estimation part is above :data:`MODEL_SHORT`; else ``"around the nominal fit"``."""
    if room_points <= 0:
        return "none"
    if nominal_rms > MODEL_SHORT:
        return "from the data sheet"
    return "around the nominal fit"


#: (exceptions) a fit or a screening that raises one of these failed on the recording: it is reported in the
#: result with its error and the diagnosis goes on; any other exception is a bug and is raised
SOLVER_FAILURES = (PneusimError, SolverError, FloatingPointError, np.linalg.LinAlgError, ValueError, RuntimeError,
                   ArithmeticError)


def is_solver_failure(exc: Exception) -> bool:
    """Whether ``exc`` is a fit's failure on the recording (:data:`SOLVER_FAILURES`), reported and not raised."""
    return isinstance(exc, SOLVER_FAILURES)


# ------------------------------------------------------------------------------------------- the rules table
def rules_table() -> list[tuple[str, str, str, str]]:
    """``[(name, value, unit, reason)]`` of every rule, in the order of this module, read from its ``#:`` lines."""
    source = inspect.getsource(inspect.getmodule(rules_table))
    lines = source.splitlines()
    rows = []
    for node in ast.parse(source).body:
        if not (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)):
            continue
        name = node.targets[0].id
        if name not in __all__:
            continue
        comment, k = [], node.lineno - 2
        while k >= 0 and lines[k].startswith("#: "):
            comment.insert(0, lines[k][3:].strip())
            k -= 1
        text = " ".join(comment)
        unit, _, reason = text[1:].partition(") ") if text.startswith("(") else ("", "", text)
        rows.append((name, _value_text(globals()[name]), unit, reason))
    return rows


def _value_text(value) -> str:
    if isinstance(value, tuple) and value and all(isinstance(v, type) for v in value):
        return ", ".join(v.__name__ for v in value)
    return repr(value)


def table_markdown() -> str:
    """The rules as the Markdown table of ``docs/diagnosis.md``'s section "Rules"."""
    lines = ["| rule | value | unit | why |", "|---|---|---|---|"]
    for name, value, unit, reason in rules_table():
        lines.append(f"| `{name}` | {value} | {unit} | {reason.replace('|', '/')} |")
    return "\n".join(lines)
