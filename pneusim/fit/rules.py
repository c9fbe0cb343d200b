"""The fit's rules: every threshold and fixed choice that decides a fit's path or its verdict, in one place.

Each is a named constant with its unit and the reason in one line, so that the whole policy reads on one
screen and a change to one rule is weighed against its siblings.  The measurements behind them are in the
decision records ``docs/decisions/NNNN-*.md``, numbered in parentheses beside a rule or a group.
Normalised residuals are rms over the sensor noise std (1 at the noise level); continuity defects are in
the integrator's state scales (stroke, 1 m/s, 1 bar); ``theta`` is a free parameter over its scale
(:mod:`.parameters`).

The stages import their rules from here; the names the rest of pneusim imports from a stage's module
(``pneusim.fit.stages.MODEL_SHORT``, ``pneusim.fit.result.ABOVE_NOISE_WARNING``, ...) stay importable there.
"""

from __future__ import annotations

__all__ = [
    "ABOVE_NOISE_WARNING", "FAR_ABOVE_NOISE", "MODEL_SHORT", "OPEN_DEFECT_WARNING", "RELATIVE_STD_WARNING",
    "CORRELATION_WARNING",
    "DEFAULT_VALIDATION_FRACTION", "MAX_VALIDATION_FRACTION", "MIN_ESTIMATION_SAMPLES", "MIN_VALIDATION_SAMPLES",
    "EXCITATION_NOISE_MULTIPLE", "POSITION_NOISE_FLOOR", "PRESSURE_NOISE_FLOOR_PA",
    "SEGMENT_SAMPLES", "MIN_SEGMENT_SAMPLES", "PREFIT_SAMPLES", "PREFIT_STARTS", "IPOPT_MAX_ITER",
    "INFORMATIVE_WINDOW", "START_FACTORS", "SAME_PREFIT", "START_VELOCITY_SMOOTHING_S", "FIRST_STATE_GRID_POINTS",
    "FIRST_STATE_LOCAL_STARTS", "FIRST_STATE_EVALUATIONS", "FIRST_STATE_PRIOR_WIDTH",
    "TRUST_REGION_EVALUATIONS", "TRUST_REGION_TOLERANCE", "PREFIT_DEFECT_WEIGHTS", "PENALTY_WEIGHT",
    "FIT_DEFECT_WEIGHTS", "CLEARLY_BETTER", "WELL_ABOVE_MARGIN", "PREFIT_RESTARTS", "SHORT_SEGMENTS",
    "WARM_TOLERANCE", "WARM_CONTINUE_BELOW",
    "DEFECT_TOL_PER_RTOL", "ACCEPTABLE_DEFECT_FACTOR", "IPOPT_OBJECTIVE_CHANGE", "GN_DAMPING", "KEEP_CONSTRAINED",
    "GIVE_UP_CLIMB", "GIVE_UP_STALL", "SETTLED_STEP", "SETTLED_STEPS", "SETTLED_SCATTER_STEPS", "OPENED_DEFECTS",
    "CONTRACTION",
    "TRACKED_ROUNDS", "TRACKED_STARTS", "PLAUSIBLE_INNOVATIONS", "PROCESS_STD", "FIRST_STATE_STD", "PROCESS_SCHEDULE",
    "UNMEASURED_FACTOR", "HELD_BROAD", "HELD_UNTIL", "PREDICTION_ERROR_EVALUATIONS", "PREDICTION_ERROR_TOLERANCE",
    "NEARBY_START", "PREDICTION_ERROR_ATTEMPTS", "SETTLED_NOISE",
]

# ----------------------------------------------------------------------------------------- the verdict
#: normalised residual (any measured signal) above which a fit has not reached the noise: the rms of
#: N >= 1000 white residuals scatters by 1/sqrt(2N) < 2.3 % and the noise std is known to a few percent,
#: while a misfit with a fifth of the noise's power already crosses 1.1 (0002)
ABOVE_NOISE_WARNING = 1.1
#: normalised residual far above noise: the model misses what the recording shows (``pneusim fit`` exits 3)
FAR_ABOVE_NOISE = 1.5
#: normalised residual (a pre-fit's, or IPOPT's from the whole fit's trust region) above which the model
#: lacks physics on the recording: no other start, continuity weighting or rescue route supplies it (0009)
MODEL_SHORT = 5.0
#: largest continuity defect left open (state-scaled) above which the fitted trajectory jumps between
#: segments (IPOPT's penalty form ended there): warned, the residual is then lower than a continuous one
OPEN_DEFECT_WARNING = 1e-3
#: standard error over the estimate above which a parameter is warned as poorly determined
RELATIVE_STD_WARNING = 0.5
#: |correlation| above which two parameters are warned as indistinguishable by the recording
CORRELATION_WARNING = 0.99

# ------------------------------------------------------------------------------------- checks and split
#: final fraction of a recording kept for validation unless told otherwise (never seen by the optimiser)
DEFAULT_VALIDATION_FRACTION = 0.3
#: largest validation fraction accepted: the rest must still estimate
MAX_VALIDATION_FRACTION = 0.9
#: samples, at least, to estimate on: refuses a recording too short to fit (a floor, not tuned)
MIN_ESTIMATION_SAMPLES = 100
#: samples, at least, to validate on: refuses a split that leaves nothing to validate on (a floor, not tuned)
MIN_VALIDATION_SAMPLES = 20
#: the piston must move over this many position-noise stds in the estimation part to excite friction and mass
EXCITATION_NOISE_MULTIPLE = 50
#: floor of the position noise std a residual is divided by, as a fraction of the stroke: a noise-free
#: recording's converter steps must not weigh a residual infinitely
POSITION_NOISE_FLOOR = 1e-5
#: Pa, floor of the pressure noise std a residual is divided by: the same for a clean pressure trace
PRESSURE_NOISE_FLOOR_PA = 20.0

# ------------------------------------------------------------------------------------ options' defaults
#: samples per shooting segment: 25 or 100 in the pre-fit ended at 1.51 and 2.66 times noise where 50
#: reached it (0011)
SEGMENT_SAMPLES = 50
#: samples, the floor of the ``segment_samples`` option (a floor, not tuned)
MIN_SEGMENT_SAMPLES = 10
#: samples of the pre-fit's window: a 1000-sample window, or a 500-sample one first, lost pre-fits (0011)
PREFIT_SAMPLES = 2000
#: pre-fit starts tried at most (the first the rig file's values; :data:`START_FACTORS`)
PREFIT_STARTS = 3
#: IPOPT iterations per round on the exact problem: near the optimum a few suffice; a warm refit still
#: bringing its effect in at the cap gets one more round (0016)
IPOPT_MAX_ITER = 40

# ------------------------------------------------------------------------------------------- the starts
#: the pre-fit's window moves from the recording's start where the piston moves over less than this fraction
#: of the estimation part's position range there: a window at rest says nothing about friction and mass (0012)
INFORMATIVE_WINDOW = 0.1
#: the pre-fit's starts, as factors on the starting values, deterministic: the rig file's, then a weaker and
#: a stronger valve with friction and mass moved the way that keeps the motion plausible (0013)
START_FACTORS = (
    {},
    {"valve_sonic_conductance_m3_per_s_Pa": 0.6, "friction_static_N": 0.6, "friction_coulomb_N": 0.6,
     "moving_mass_kg": 1.5},
    {"valve_sonic_conductance_m3_per_s_Pa": 1.6, "friction_static_N": 1.8, "friction_coulomb_N": 1.8,
     "friction_viscous_N_s_per_m": 0.5, "moving_mass_kg": 0.7},
)
#: relative distance within which a start's pre-fit residual equals an earlier start's: the same basin of the
#: window, whose whole fit is known, so it is not fitted again (0013)
SAME_PREFIT = 1e-3
#: s, width of the Savitzky-Golay filter that differentiates the recorded position into the first start velocity
START_VELOCITY_SMOOTHING_S = 0.05
#: interior pressures per chamber of the grid the first state's search starts from: a stick-slipping start
#: has several local minima (0014)
FIRST_STATE_GRID_POINTS = 8
#: the best grid points refined by least squares in the first state's search (0014)
FIRST_STATE_LOCAL_STARTS = 4
#: residual evaluations of each refinement of the first state, at most (a cap on a small problem: one
#: segment's samples, two or three hidden values)
FIRST_STATE_EVALUATIONS = 50
#: widths of the prior on the first state's hidden values (m/s, Pa): broad, the data dominate where they speak
FIRST_STATE_PRIOR_WIDTH = {"velocity_m_per_s": 0.02, "pressure_a_Pa": 1e5, "pressure_b_Pa": 1e5}

# ------------------------------------------------------------------------------- the trust region (0001)
#: residual evaluations of one trust-region stage, at most (its fresh starts share them): the robustness set's
#: pre-fits from the data sheet take a median of 15-20, the fit benchmark's 35 (0021)
TRUST_REGION_EVALUATIONS = 80
#: SciPy's relative step and cost tolerances of the trust region: the integration error is ~1e-6 relative
TRUST_REGION_TOLERANCE = 1e-4
#: continuity weights of the pre-fit's continuation route in turn; the last is the direct route's weight (0003)
PREFIT_DEFECT_WEIGHTS = (10.0, 1000.0)
#: weight of the continuity defects where they are residuals: the whole fit's trust region, IPOPT's penalty
#: form, the warm refit's trust region and diagnosis's screening and cost comparisons
PENALTY_WEIGHT = 1e4
#: continuity weights of the whole fit's continuation route in turn (0004)
FIT_DEFECT_WEIGHTS = (10.0, 1000.0, PENALTY_WEIGHT)
#: factor by which a second route's residual must be lower to replace the first: two routes ending alike are
#: one basin, and the first is the one the rest was tuned on (0003)
CLEARLY_BETTER = 1.25
#: normalised residual added to a pre-fit's within which a whole fit is not "well above" it (beside
#: :data:`CLEARLY_BETTER` times it): near noise a ratio alone is too strict
WELL_ABOVE_MARGIN = 0.2
#: the pre-fit's fresh trust regions at most after a stop on SciPy's step tolerance alone above noise: the
#: region shrank in the penalty's curved valley while the cost still fell (0005)
PREFIT_RESTARTS = 1
#: samples per segment of the pre-fit's short-segment route (both pressures recorded, pre-fit above noise
#: but within MODEL_SHORT): short segments pin the valve and friction through sample-to-sample stick-slip (0006)
SHORT_SEGMENTS = 10
#: SciPy's tolerances of a warm refit's trust region: near the optimum it only brings the new effect in,
#: IPOPT finishes the exact problem (0016)
WARM_TOLERANCE = 1e-3
#: a warm refit's IPOPT stopped by the iteration cap above noise gets one more round where it lowered the
#: trust region's residual below this fraction: the new effect is still coming in, not stalled (0016)
WARM_CONTINUE_BELOW = 0.75

# ----------------------------------------------------------------------------- the exact problem (0007)
#: IPOPT's continuity tolerance per CVODES relative tolerance: defects below ``20 rtol`` (state-scaled) are
#: within the integration error of the segments' ends
DEFECT_TOL_PER_RTOL = 20
#: IPOPT's acceptable level of the continuity defects (and Gauss-Newton settling's) is this many times that
#: tolerance: three acceptable iterates in a row stop IPOPT instead of its chasing the integration error
ACCEPTABLE_DEFECT_FACTOR = 10
#: IPOPT's acceptable relative change of the objective over three iterates: the residuals carry the
#: integrator's error (about rtol relative), which IPOPT's default tolerances would chase
IPOPT_OBJECTIVE_CHANGE = 1e-3
#: relative and absolute damping added to the Gauss-Newton matrix's diagonal: directions the residuals do
#: not see (a hidden state while the piston sticks) would make the bare matrix singular
GN_DAMPING = (1e-3, 1e-9)
#: the constrained IPOPT run is kept within this factor of the trust region's residual sum, else IPOPT
#: solves the penalty form (whose line search cannot go uphill): a step into another basin is not an answer
KEEP_CONSTRAINED = 1.1
#: (factor, iterates): the constrained run is given up once this many iterates in a row have an objective
#: above this factor times the start's: a run that climbs to stay climbs at once (0008)
GIVE_UP_CLIMB = (8.0, 5)
#: (iterate, defect fraction): from a start more than MODEL_SHORT above noise, the constrained run is given up
#: when at this iterate its objective is above the start's and its largest defect above this fraction of the
#: start's: it approaches neither goal (0008)
GIVE_UP_STALL = (8, 0.8)
#: standard errors: Gauss-Newton settling stops once the next step moves no free parameter by more (0010)
SETTLED_STEP = 0.1
#: Gauss-Newton steps at most before IPOPT takes over
SETTLED_STEPS = 3
#: (steps, largest defect, standard errors): Gauss-Newton settling also stops, settled within the scatter of its
#: steps, after this many steps or more where the residual sum moved by less than IPOPT_OBJECTIVE_CHANGE over
#: the last step and the next step moves no parameter by more than one standard error, at the last two iterates'
#: one with the smaller defects where those are within half the level the result warns at (OPEN_DEFECT_WARNING):
#: on stick-slip recordings each
#: linearisation misses by the integration error, and IPOPT took forty iterations to end at the same residual
#: (0100)
SETTLED_NOISE = (2, 5e-4, 1.0)
#: Gauss-Newton steps at most while the residual sum no longer moves (the scatter of SETTLED_NOISE): each step of
#: a stick-slip recording lands at another point of the scatter, its largest defect anywhere from a third to four
#: times the acceptable level, so whether one of the first few is within half the warning level is a draw of the
#: last bits of the arithmetic; a further step costs a fraction of a second where IPOPT took half a minute to end
#: at the same residual (0108)
SETTLED_SCATTER_STEPS = 12
#: a Gauss-Newton step leaving its largest defect above this many times the acceptable level (and above its
#: start's) hands over to IPOPT: the linearisation does not hold there (stick-slip)
OPENED_DEFECTS = 10.0
#: a Gauss-Newton step that does not shrink the next to this fraction of itself (in standard errors) hands
#: over to IPOPT: the steps are not converging
CONTRACTION = 0.5

# ------------------------------------------------------------------------------------ the rescue routes
#: relative size of the deterministic perturbations of a start where a route is chaotic in its start (the
#: prediction-error fit): far above rounding, far below what changes a parameter's meaning (0103)
NEARBY_START = 1e-6
#: starts of the prediction-error fit at most: the start itself, then nearby ones (NEARBY_START), their broadest
#: stage first and the rest of the schedule from the lowest landings, until two starts agree on the lowest end.
#: From the data sheet where the filter lands is a draw of the last bits of its arithmetic: a chaotic
#: recording's landed right from 3 of 10 and 5 of 6 nearby starts under two arithmetic paths (0103)
PREDICTION_ERROR_ATTEMPTS = 5
#: rounds of the tracked-starts route at most, each from the last one's point while it lowers the residual (0017)
TRACKED_ROUNDS = 2
#: points the tracked-starts route is tried from at most: the best fit's, then the other points the starts reached
#: (their pre-fits and fits within MODEL_SHORT), lowest first, until one reaches noise.  Whether it reaches noise
#: from a fit still above noise is a draw of where that fit landed: a closed-loop stick-slip recording's fit at
#: 4.5 times noise under one arithmetic path, 4.8 under another, and the route reached noise from the second
#: only, and from the first path's second pre-fit (0105)
TRACKED_STARTS = 3
#: the prediction-error route goes on to the shooting problem only where the filter's whitened innovations
#: end at most this many times their noise level: a filter that cannot predict one sample ahead says the
#: model lacks physics (0018)
PLAUSIBLE_INNOVATIONS = 2.0
#: process noise std per sample of the tracking filter, as a fraction of each state's typical magnitude (the
#: position's a thousandth of that): near the truth only the model's chaotic sensitivity needs correcting (0017)
PROCESS_STD = 3e-4
#: prior std of the filter's first state (m/s, Pa); other states 1 % of their typical magnitude
FIRST_STATE_STD = {"velocity_m_per_s": 0.02, "pressure_a_Pa": 2e4, "pressure_b_Pa": 2e4}
#: process noise of the prediction-error fit's stages in turn (fraction of each state's typical magnitude):
#: broad first, where the landscape is smooth, then sharp, a homotopy to the sharp minimum (0018)
PROCESS_SCHEDULE = (1e-2, 3e-3, 1e-3, 3e-4)
#: process noise of the states the recording does not measure (chamber pressures where it does not, every
#: effect's own states), relative to the other states': a filter free to move them explains a wrong valve and
#: friction by them (0018), and an effect's temperatures, spool or supply line moved by it stiffen the
#: integration of every sample (0122)
UNMEASURED_FACTOR = 0.01
#: parameters held at their start in the prediction-error stages whose process noise is above
#: :data:`HELD_UNTIL`: a broad filter trades the friction smoothing velocity for mistimed slips (0018)
HELD_BROAD = ("friction_smoothing_velocity_m_per_s",)
#: process noise (fraction of each state's typical magnitude) above which :data:`HELD_BROAD` are held
HELD_UNTIL = 1e-3
#: filter passes per prediction-error stage at most: each stage starts from the last one's point (0018)
PREDICTION_ERROR_EVALUATIONS = 40
#: SciPy's relative step and cost tolerances of each prediction-error stage, as the trust region's
PREDICTION_ERROR_TOLERANCE = 1e-4
