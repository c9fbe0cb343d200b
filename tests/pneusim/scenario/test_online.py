"""The scenarios' online run: the simulated rig with the estimators inside the sample loop."""

import numpy as np

from pneusim.experiment import Experiment, default_controller
from pneusim.online import PaperRLS
from pneusim.rig import load_rig
from pneusim.scenario.online import simulate_online


class _Counting(PaperRLS):
    """PaperRLS that keeps what it was given, in order."""

    def __init__(self, *args):
        super().__init__(*args)
        self.seen = []

    def update(self, y):
        self.seen.append(("y", y))
        return super().update(y)

    def add_input(self, u):
        self.seen.append(("u", u))
        super().add_input(u)


def test_the_estimators_see_every_sample_of_the_run_inside_the_loop():
    """One output, then the command applied after it, per sample: the data the loop produces, in its order
    (the order against the plant's steps is the sample loop's, tests/pneusim/loop/test_sample_loop.py)."""
    rig = load_rig("paper1-mre")
    n = 60
    exp = Experiment("closed", 0.001, np.full(n, 0.03), default_controller(rig), warmup_s=0.0)
    est = _Counting(2)
    res = simulate_online(rig, exp, {"r": est}, lambda p: p * 100, lambda c, k: c)
    assert [kind for kind, _ in est.seen] == ["y", "u"] * n
    np.testing.assert_array_equal([v for kind, v in est.seen if kind == "y"], res.recording.position_m * 100)
    np.testing.assert_array_equal([v for kind, v in est.seen if kind == "u"], res.recording.valve_cmd_V)
    assert res.predictions[("r", 1)].shape == (n,) and res.thetas["r"].shape == (n, 4)


def test_ctrl_c_or_sigterm_inside_the_online_run_stops_the_scenario():
    """The interrupt the loop stopped on is raised again (a sweep stops), not turned into a failed run
    ('TypeError: exceptions must derive from BaseException' for SIGTERM, and the sweep went on)."""
    import pytest

    from pneusim.shutdown import Terminated

    rig = load_rig("paper1-mre")
    for interrupt in (KeyboardInterrupt, Terminated):
        class _Interrupted(PaperRLS):
            def update(self, y):
                raise interrupt()

        exp = Experiment("closed", 0.001, np.full(60, 0.03), default_controller(rig), warmup_s=0.0)
        with pytest.raises(interrupt):
            simulate_online(rig, exp, {"r": _Interrupted(2)}, lambda p: p * 100, lambda c, k: c)
