"""The prediction-error route's starts (:func:`pneusim.fit.prediction_error.prediction_error_attempts`) side by
side, one per simulator of the window's problem, against the same starts one after the other on one simulator,
in the same run; both must return the same doubles.

The window: the first 2000 samples of a chaotic robustness-set recording (paper 2's open-loop multisine without
pressures), from the data sheet, the route's own starts (the start and nearby ones), schedule and give-up level.

    pytest benchmarks/test_bench_prediction_error.py --benchmark-only -s

The row is written to ``docs/results/prediction-error.md`` (:mod:`results_file`).
"""

import time

import numpy as np
import pytest

from pneusim.fit.initial import initial_starts
from pneusim.fit.prediction_error import prediction_error_attempts
from pneusim.fit.rescue_routes import nearby_start
from pneusim.fit.robustness import fit_free, make_case, robustness_cases
from pneusim.fit.rules import PLAUSIBLE_INNOVATIONS, PREDICTION_ERROR_ATTEMPTS
from pneusim.fit.setup import FitSetup
from results_file import write_results

SEED = 1007


@pytest.mark.benchmark(group="prediction-error")
def test_prediction_error_starts_side_by_side(benchmark):
    spec = next(s for s in robustness_cases(48) if s.seed == SEED)
    rig, _, recording = make_case(spec)
    setup = FitSetup(recording, rig, (), fit_free(True), None, None, None, 50)
    pb, _, _ = setup.problem(2000, 1e-6, 2)
    first = initial_starts(pb, setup.theta_start, recording, 2000)[0]
    starts = [nearby_start(setup.theta_start, k) for k in range(PREDICTION_ERROR_ATTEMPTS)]

    def attempts(side_by_side):
        return prediction_error_attempts(pb, starts, first, setup.lower, setup.upper,
                                         give_up_above=PLAUSIBLE_INNOVATIONS, side_by_side=side_by_side)

    try:
        started = time.perf_counter()
        alone = attempts(False)
        alone_s = time.perf_counter() - started
        side = benchmark.pedantic(lambda: attempts(True), rounds=1, iterations=1)
        side_s = benchmark.stats.stats.median
    finally:
        pb.close()
    ran = [a for a in side if a[0] is not None]
    for (theta_s, first_s, info_s), (theta_a, first_a, info_a) in zip(side, alone):
        assert info_s["start"] == info_a["start"] and (theta_s is None) == (theta_a is None)
        if theta_s is not None:
            np.testing.assert_array_equal(theta_s, theta_a)
            np.testing.assert_array_equal(first_s, first_a)
    lowest = min(a[2]["rms_innovations"] for a in ran)
    print(f"\n{spec.name}, 2000 samples: {len(ran)} of {len(starts)} starts continued, lowest innovations "
          f"{lowest:.4g}; one after the other {alone_s:.1f} s, side by side {side_s:.1f} s -> "
          f"{alone_s / side_s:.2f}x, the same doubles")
    write_results("prediction-error", "The prediction-error route's starts over a 2000-sample window",
                  "| window | starts continued | one after the other | side by side | ratio | results |\n"
                  "|---|---|---|---|---|---|\n"
                  f"| {spec.name} | {len(ran)} of {len(starts)} | {alone_s:.1f} s | {side_s:.1f} s | "
                  f"{alone_s / side_s:.2f}x | the same doubles |\n")
