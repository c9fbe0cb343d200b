"""Which starts the prediction-error route continues, and which end it keeps, with a stand-in fit whose ends are
given: the rule is deterministic whatever the arithmetic, the landings themselves are not.  Then the real fits
side by side on a chaotic window: the same doubles as one after the other, and stopped cleanly by a deadline."""

import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

from pneusim.fit import prediction_error
from pneusim.fit.deadline import FitDeadlineExceeded, work_deadline
from pneusim.fit.initial import initial_starts
from pneusim.fit.prediction_error import prediction_error_attempts
from pneusim.fit.rescue_routes import nearby_start
from pneusim.fit.robustness import fit_free, make_case, robustness_cases
from pneusim.fit.setup import FitSetup


def _stand_in(ends: dict, landings: dict, calls: list):
    """A prediction_error_fit whose start k (read from the scaled parameters' first entry) lands at
    ``landings[k]`` after the broadest stage and ends at ``ends[k]`` after the whole schedule."""
    def fit(pb, theta0, x_first, lower, upper, schedule, give_up_above=np.inf, **hooks):
        k = int(round(theta0[0]))
        whole = len(schedule) > 1 and theta0[1] == 0.0          # the whole schedule from a start
        rest = theta0[1] == 1.0                                  # the rest of the schedule from a landing
        rms = ends[k] if (whole or rest) else landings[k]
        calls.append((k, "whole" if whole else "rest" if rest else "landing"))
        theta = np.array([k, 1.0])                               # a landing carries its start's number
        if hooks.get("after_first_stage"):
            hooks["after_first_stage"](rms)
        return theta, x_first, {"stages": [{"rms_innovations": rms}] * (1 if not whole else 4),
                                "rms_innovations": rms, "seconds": 0.0}
    return fit


def _attempts(monkeypatch, ends, landings, give_up_above=2.0, pb=None):
    calls = []
    monkeypatch.setattr(prediction_error, "prediction_error_fit", _stand_in(ends, landings, calls))
    starts = [np.array([float(k), 0.0]) for k in range(len(ends))]
    out = prediction_error.prediction_error_attempts(pb, starts, np.zeros(3), None, None,
                                                     give_up_above=give_up_above, schedule=(1.0, 0.5, 0.1))
    kept = min((a[2]["rms_innovations"], a[2]["start"]) for a in out if a[0] is not None)
    return out, kept, calls


def test_a_start_at_noise_in_a_wrong_basin_does_not_end_the_search(monkeypatch):
    """The order of a chaotic recording under one arithmetic path: start 0 ends at 0.956 (under the noise level
    1.1, a wrong basin); start 3 lands lowest and ends at 0.767, start 1 ends in the wrong basin again (which
    does not confirm the lowest end), start 2 at 0.767 confirms it: 0.767 is kept, and start 4 is never
    continued."""
    ends = {0: 0.956, 1: 0.956, 2: 0.767, 3: 0.767, 4: 1.3}
    landings = {1: 0.79, 2: 0.80, 3: 0.78, 4: 1.2}
    out, kept, calls = _attempts(monkeypatch, ends, landings)
    assert kept[0] == 0.767
    assert [c for c in calls if c[1] != "landing"] == [(0, "whole"), (3, "rest"), (1, "rest"), (2, "rest")]
    assert {a[2]["start"] for a in out if a[0] is None} == {4}


def test_the_first_start_confirmed_by_the_best_landing_ends_the_search(monkeypatch):
    ends = {0: 0.77, 1: 0.77, 2: 0.95, 3: 0.95, 4: 0.95}
    landings = {1: 0.70, 2: 0.90, 3: 0.91, 4: 0.92}
    out, kept, calls = _attempts(monkeypatch, ends, landings)
    assert kept == (0.77, 0)
    assert [c for c in calls if c[1] != "landing"] == [(0, "whole"), (1, "rest")]


def test_every_start_is_continued_when_none_agree(monkeypatch):
    ends = {0: 1.00, 1: 0.90, 2: 0.80, 3: 0.70, 4: 0.60}
    landings = {1: 0.5, 2: 0.6, 3: 0.7, 4: 0.8}
    out, kept, calls = _attempts(monkeypatch, ends, landings)
    assert kept == (0.60, 4)
    assert len([c for c in calls if c[1] == "rest"]) == 4


def test_a_first_stage_far_above_noise_tries_no_other_start(monkeypatch):
    """A filter that cannot predict one sample ahead at its broadest stage says the model lacks physics."""
    calls = []

    def fit(pb, theta0, x_first, lower, upper, schedule, give_up_above=np.inf, **hooks):
        calls.append(theta0[0])
        if hooks.get("after_first_stage"):
            hooks["after_first_stage"](5.0)
        return theta0, x_first, {"stages": [{"rms_innovations": 5.0}], "rms_innovations": 5.0, "seconds": 0.0}

    monkeypatch.setattr(prediction_error, "prediction_error_fit", fit)
    out = prediction_error.prediction_error_attempts(None, [np.array([0.0, 0.0]), np.array([1.0, 0.0])],
                                                     np.zeros(3), None, None, give_up_above=2.0)
    assert len(out) == 1 and calls == [0.0]


@pytest.mark.parametrize("ends, landings", [
    ({0: 0.956, 1: 0.956, 2: 0.767, 3: 0.767, 4: 1.3}, {1: 0.79, 2: 0.80, 3: 0.78, 4: 1.2}),
    ({0: 0.77, 1: 0.77, 2: 0.95, 3: 0.95, 4: 0.95}, {1: 0.70, 2: 0.90, 3: 0.91, 4: 0.92}),
    ({0: 1.00, 1: 0.90, 2: 0.80, 3: 0.70, 4: 0.60}, {1: 0.5, 2: 0.6, 3: 0.7, 4: 0.8}),
    ({0: 0.9, 1: 0.9, 2: 0.9}, {1: 2.5, 2: 3.0})])
def test_fits_side_by_side_keep_what_one_after_the_other_keeps(monkeypatch, ends, landings):
    """With two simulators the fits run in two threads, a continuation beside the next one in order; the
    attempts returned (which ran, which were dropped, what each ended at) are those of the fits one after the
    other."""
    alone, kept_alone, _ = _attempts(monkeypatch, ends, landings)
    side, kept_side, _ = _attempts(monkeypatch, ends, landings, pb=SimpleNamespace(sims=["sim 1", "sim 2"]))
    assert kept_side == kept_alone
    assert [(a[0] is None, a[2]["start"], a[2]["rms_innovations"]) for a in side] == \
        [(a[0] is None, a[2]["start"], a[2]["rms_innovations"]) for a in alone]


@pytest.mark.parametrize("attempt", [1, 2, 4])
def test_nearby_starts_are_the_same_on_every_run_and_tiny(attempt):
    theta0 = np.array([1.0, -2.0, 3.0e-3])
    moved = nearby_start(theta0, attempt)
    np.testing.assert_array_equal(moved, nearby_start(theta0, attempt))
    assert np.all(np.abs(moved / theta0 - 1.0) <= 1e-6) and np.any(moved != theta0)
    np.testing.assert_array_equal(nearby_start(theta0, 0), theta0)


def _chaotic_window(n_starts: int):
    """``(problem with two simulators, setup, first state, starts)``: the first 600 samples of ``s1007`` (paper 2,
    open-loop multisine without pressures, chaotic) from the data sheet, the start and ``n_starts - 1`` nearby."""
    spec = next(s for s in robustness_cases(48) if s.seed == 1007)
    rig, _, recording = make_case(spec)
    setup = FitSetup(recording, rig, (), fit_free(True), None, None, None, 50)
    pb, _, _ = setup.problem(600, 1e-6, 2)
    first = initial_starts(pb, setup.theta_start, setup.recording, pb.data.n_samples)[0]
    return pb, setup, first, [nearby_start(setup.theta_start, k) for k in range(n_starts)]


@pytest.mark.slow
def test_prediction_error_attempts_side_by_side_are_the_same_doubles_as_one_after_the_other():
    """The prediction-error fit from the data sheet and two nearby starts, on a problem with two simulators (the
    fits in two threads, each on its own simulator) and one after the other on one of them: every attempt ends at
    the same parameters, first state and innovations, to the last bit."""
    pb, setup, first, starts = _chaotic_window(3)

    def attempts(side_by_side):
        return prediction_error_attempts(pb, starts, first, setup.lower, setup.upper, schedule=(1e-2, 1e-3),
                                         side_by_side=side_by_side)

    try:
        side, alone = attempts(True), attempts(False)
    finally:
        pb.close()
    assert len(side) == len(alone) >= 2
    for (theta_s, first_s, info_s), (theta_a, first_a, info_a) in zip(side, alone):
        assert info_s["start"] == info_a["start"]
        assert (theta_s is None) == (theta_a is None)
        if theta_s is not None:
            np.testing.assert_array_equal(theta_s, theta_a)
            np.testing.assert_array_equal(first_s, first_a)
            assert info_s["rms_innovations"] == info_a["rms_innovations"]


@pytest.mark.slow
def test_prediction_error_attempts_side_by_side_stop_at_a_deadline_and_leave_no_thread():
    """A caller's work deadline that passes halfway through the route (the starts then run side by side: the
    first start's first stage is a tenth of it) ends it with :class:`FitDeadlineExceeded` before the route's
    own end, and every thread the route started has ended by then: nothing integrates on the problem after the
    call returns.  The work counted is the route's logic's, not its threads' timing: twice the same count, whole
    or stopped, though the runs the route drops are cancelled at whatever sample their thread has reached."""
    from pneusim.solver import work

    pb, setup, first, starts = _chaotic_window(5)
    threads_before = threading.active_count()

    def counted(at=None):
        units, cpu = work.done(), time.process_time()
        if at is None:
            prediction_error_attempts(pb, starts, first, setup.lower, setup.upper)
        else:
            with pytest.raises(FitDeadlineExceeded), work_deadline(units + at) as block:
                prediction_error_attempts(pb, starts, first, setup.lower, setup.upper)
            assert block.reached
        return work.done() - units, time.process_time() - cpu

    try:
        whole, whole_s = counted()
        assert counted()[0] == whole
        stopped, stopped_s = counted(at=0.5 * whole)
        assert counted(at=0.5 * whole)[0] == stopped
        assert threading.active_count() == threads_before
    finally:
        pb.close()
    # a run beside another sees only its own work and the count at its start (what its partner has done is
    # counted when taken), so the route stops past the deadline by up to its partner's work, before its end
    assert 0.5 * whole < stopped < whole, (stopped, whole)
    assert stopped_s < whole_s, (stopped_s, whole_s)
