"""Which starts the prediction-error route continues, and which end it keeps, with a stand-in fit whose ends are
given: the rule is deterministic whatever the arithmetic, the landings themselves are not."""

from types import SimpleNamespace

import numpy as np
import pytest

from pneusim.fit import prediction_error
from pneusim.fit.rescue_routes import nearby_start


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
