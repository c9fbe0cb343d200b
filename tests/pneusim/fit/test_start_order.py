"""The order in which :class:`~pneusim.fit.PhysicalFit` spends its work on the starts, with the stages replaced
by stand-ins that record what ran (the real stages' landscapes are chaotic; the order is a rule):

* where the first start's pre-fit ends above noise within ``MODEL_SHORT``, every start's trust region on the
  window runs before any whole fit, and the whole part is fitted first from the lowest one at noise; nothing
  else runs where that fit reaches noise, and where it does not, the starts go on in their order from the trust
  regions already run;
* where the first start's trust region on the whole part ends above noise, the prediction-error route runs
  before IPOPT, and IPOPT finishes that start only where the route does not reach noise; the route then runs
  once, not again after IPOPT.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from pneusim.fit import FitStages, PhysicalFit
from pneusim.fit.rules import ABOVE_NOISE_WARNING, MODEL_SHORT, START_FACTORS


def _fit(rms):
    """A finished fit whose normalised rms is ``rms`` on a one-residual problem."""
    return SimpleNamespace(objective=rms ** 2, v=np.zeros(1), status="stand-in", iterations=1, seconds=0.0,
                           formulation="stand-in", max_defect=0.0)


class _Starts(PhysicalFit):
    """The start loop with stand-in pre-fits and whole fits: ``prefit_rms[k]``, ``whole_rms[k]``, and the
    prediction-error route's end ``route_rms`` (None: it does not finish)."""

    def __init__(self, prefit_rms, whole_rms, route_rms=None):
        super().__init__(quiet=True)
        self.prefit_rms, self.whole_rms, self.route_rms, self.calls = prefit_rms, whole_rms, route_rms, []

    def _prefit_trust_region(self, run, k, theta0):
        self.calls.append(("prefit", k))
        return np.zeros(1), self.prefit_rms[k], {"start": k + 1}

    def _prefit(self, run, k, theta0, trust=None):
        if trust is None:
            trust = self._prefit_trust_region(run, k, theta0)
        else:
            self.calls.append(("rest of the pre-fit", k))
        return trust[:2]

    def _whole_fit(self, run, k, v_pre, rms_pre):
        self.calls.append(("whole", k))
        run.fits.append((self.whole_rms[k] ** 2, k, _fit(self.whole_rms[k])))
        return self.whole_rms[k]

    def _prediction_error(self, run, res):
        self.calls.append(("route", None))
        if self.route_rms is not None and self.route_rms ** 2 < res.objective:
            res = _fit(self.route_rms)
            run.fits.append((res.objective, len(START_FACTORS), res))
        return res


def _run():
    setup = SimpleNamespace(theta_start=np.ones(2), free=["a", "b"], lower=np.zeros(2), upper=np.full(2, 10.0))
    return SimpleNamespace(setup=setup, open_window=lambda samples: None, say=lambda line: None, fits=[],
                           early_route=None, pb=SimpleNamespace(n_residuals=1))


@pytest.mark.parametrize("prefit_rms, whole_rms, route_rms, calls, best", [
    # the first pre-fit at noise: its whole fit, nothing else
    ([0.98, 2.0, 2.0], {0: 0.99}, None, [("prefit", 0), ("whole", 0)], 0.99),
    # the first pre-fit above noise, the third's at noise: every trust region, then the third's whole fit only
    ([2.2, 2.28, 0.959], {2: 0.989}, None,
     [("prefit", 0), ("prefit", 1), ("prefit", 2), ("rest of the pre-fit", 2), ("whole", 2)], 0.989),
    # the lowest of two pre-fits at noise goes first
    ([2.2, 1.05, 0.96], {2: 0.99}, None,
     [("prefit", 0), ("prefit", 1), ("prefit", 2), ("rest of the pre-fit", 2), ("whole", 2)], 0.99),
    # its whole fit above noise: the starts in their order (the first, its route, the second from the trust region
    # already run), none fitted twice
    ([2.2, 2.3, 0.96], {0: 2.0, 1: 2.5, 2: 3.0}, None,
     [("prefit", 0), ("prefit", 1), ("prefit", 2), ("rest of the pre-fit", 2), ("whole", 2), ("whole", 0),
      ("route", None), ("rest of the pre-fit", 1), ("whole", 1)], 2.0),
    # no other pre-fit at noise: the first start's whole fit and route; the route reaching noise ends the starts
    ([2.2, 2.3, 1.5], {0: 2.0}, 1.0, [("prefit", 0), ("prefit", 1), ("prefit", 2), ("whole", 0), ("route", None)], 1.0),
    # the first pre-fit beyond MODEL_SHORT: the model lacks physics, no other start (and no trust region ahead)
    ([1.2 * MODEL_SHORT, 0.9, 0.9], {0: 7.0}, None, [("prefit", 0), ("whole", 0), ("route", None)], 7.0),
])
def test_the_starts_order(prefit_rms, whole_rms, route_rms, calls, best):
    fit = _Starts(prefit_rms, whole_rms, route_rms)
    res = fit._fit_from_starts(_run())
    assert fit.calls == calls
    assert np.sqrt(res.objective) == pytest.approx(best)


# ------------------------------------------------------------------- the route before the first start's IPOPT
class _Whole(PhysicalFit):
    """``_whole_fit`` on stand-in stages: the trust region ends at ``rms_ls``, IPOPT at ``ipopt_rms``, the
    prediction-error route at ``route_rms``; ``calls`` records which ran."""

    def __init__(self, rms_ls, ipopt_rms, route_rms):
        self.calls = []

        def whole_fit(pb, v0, lo, hi, rms_pre, finish):
            self.calls.append("trust region")
            return np.zeros(1), rms_ls, {"status": "stand-in", "evaluations": 1, "seconds": 0.0, "routes": [{}],
                                         "route": "continuation"}

        def route(window, pb, lo, hi, theta0, first, rms, finish):
            self.calls.append(("route against", rms))
            attempts = [{"start": 0, "rms_innovations": 1.0, "stages": 4, "seconds": 0.0}]
            return _fit(route_rms), {"attempts": attempts, "seconds": 0.0}

        super().__init__(quiet=True, stages=FitStages(whole_fit=whole_fit, prediction_error=route))
        self.ipopt_rms = ipopt_rms

    @staticmethod
    def _whole_starts(run, theta0, prefit_states):
        return np.zeros(1)


def _whole_run(fit, starts=1):
    pb = SimpleNamespace(n_residuals=1, join=lambda theta, x: np.zeros(1), split=lambda v: (np.zeros(1), None))

    def finish(v, rms):
        fit.calls.append("ipopt")
        return _fit(fit.ipopt_rms), fit.ipopt_rms

    return SimpleNamespace(pb=pb, lo=None, hi=None, window=(pb,), window_start=0, first_at_start=None,
                           attempts=[{"start": k + 1} for k in range(starts)], fits=[], early_route=None,
                           predicted=None, finish=finish, say=lambda line: None,
                           setup=SimpleNamespace(n_est=10, theta_start=np.ones(1)))


def test_the_route_at_noise_replaces_the_first_starts_ipopt():
    fit = _Whole(rms_ls=2.5, ipopt_rms=3.5, route_rms=0.99)
    run = _whole_run(fit)
    assert fit._whole_fit(run, 0, np.zeros(1), 2.6) == pytest.approx(0.99)
    assert fit.calls == ["trust region", ("route against", 2.5)]
    assert run.predicted["kept"] and run.early_route is None and len(run.fits) == 1
    assert run.attempts[0]["ipopt_status"].startswith("not run")


def test_the_route_above_noise_runs_once_and_ipopt_finishes_the_start():
    fit = _Whole(rms_ls=2.5, ipopt_rms=3.5, route_rms=1.8)
    run = _whole_run(fit)
    assert fit._whole_fit(run, 0, np.zeros(1), 2.6) == pytest.approx(3.5)
    assert fit.calls == ["trust region", ("route against", 2.5), "ipopt"]
    best = fit._prediction_error(run, run.fits[0][2])      # as the start loop calls it next: the same route's fit
    assert fit.calls == ["trust region", ("route against", 2.5), "ipopt"]
    assert np.sqrt(best.objective) == pytest.approx(1.8) and run.predicted["kept"] and run.early_route is None


@pytest.mark.parametrize("k, rms_ls", [(1, 2.5), (0, 0.99 * ABOVE_NOISE_WARNING)])
def test_no_route_before_ipopt_at_a_later_start_or_from_a_trust_region_at_noise(k, rms_ls):
    fit = _Whole(rms_ls=rms_ls, ipopt_rms=1.0, route_rms=0.9)
    run = _whole_run(fit, starts=2)
    fit._whole_fit(run, k, np.zeros(1), 2.6)
    assert fit.calls == ["trust region", "ipopt"] and run.predicted is None
