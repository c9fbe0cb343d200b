"""The sample loop: the order of its steps, what it records, and how it stops."""

import numpy as np

from pneusim.controller import ProportionalController
from pneusim.loop import run_loop
from pneusim.loop.sample_loop import STOP_FAULT, STOP_INTERRUPTED
from pneusim.plant import Measurement


class _Plant:
    """A plant that logs its calls: position grows with the command."""

    sample_time_s = 0.001

    def __init__(self, log, fail_at=None, fault=None):
        self.log, self.x, self.k, self.nulls = log, 0.02, 0, []
        self.fail_at, self.fault = fail_at, fault

    def measure(self):
        if self.k == self.fail_at:
            raise self.fault
        self.log.append("measure")
        return Measurement(self.k * self.sample_time_s, self.x, 2e5, 3e5)

    def step(self, u):
        self.log.append("actuate")
        self.k += 1
        self.x += 1e-4 * (u - 5.0)

    def safe_stop(self, null_V):
        self.nulls.append(null_V)


class _Estimator:
    horizons = (1,)

    def __init__(self, log):
        self.log, self.theta = log, np.zeros(2)

    def update(self, y):
        self.log.append("identify")
        return {1: 0.5 * y}

    def add_input(self, u):
        self.log.append("learn")
        self.theta = self.theta + u


class _Controller(ProportionalController):
    def __init__(self, log):
        super().__init__(40.0)
        self.log = log

    def command(self, t_s, reference_m, measured_m):
        self.log.append("control")
        return super().command(t_s, reference_m, measured_m)


def test_each_sample_measures_identifies_controls_actuates_then_learns_the_input():
    log = []
    n, warm = 5, 2
    res = run_loop(_Plant(log), np.full(n, 0.03), _Controller(log), {"e": _Estimator(log)}, lambda p: p * 100,
                   lambda u, k: u, n_warm=warm)
    warmup = ["measure", "control", "actuate"] * warm
    recorded = ["measure", "identify", "control", "actuate", "learn"] * (n - 1) + ["measure", "identify",
                                                                                    "control", "learn"]
    assert log == warmup + recorded             # the last sample is measured, not stepped
    assert res.completed and res.n_samples == n
    np.testing.assert_array_equal(res.predictions[("e", 1)], 0.5 * 100 * res.position_m)
    np.testing.assert_array_equal(res.thetas["e"][-1], np.full(2, res.valve_cmd_V.sum()))


def test_a_fault_or_ctrl_c_stops_with_the_valve_at_null_and_keeps_the_samples_taken():
    for fault, reason in ((RuntimeError("cable"), STOP_FAULT), (KeyboardInterrupt(), STOP_INTERRUPTED)):
        plant = _Plant([], fail_at=7, fault=fault)
        res = run_loop(plant, np.full(20, 0.03), ProportionalController(40.0), {}, lambda p: p, lambda u, k: u,
                       null_V=5.0)
        assert res.stop_reason == reason and res.n_samples == 7 and plant.nulls == [5.0]
        assert res.valve_to_null and (res.error == "RuntimeError: cable" if reason == STOP_FAULT else True)


class _BrokenSensor(_Plant):
    """A position sensor that fails at sample ``at``: NaN, or a value at the float's end."""

    def __init__(self, log, at, value):
        super().__init__(log)
        self.at, self.value, self.commands = at, value, []

    def measure(self):
        m = super().measure()
        return Measurement(m.t_s, self.value, m.pressure_a_Pa, m.pressure_b_Pa) if self.k == self.at else m

    def step(self, u):
        self.commands.append(u)
        super().step(u)


def test_a_command_that_is_not_a_number_never_reaches_the_valve():
    """A sensor reading NaN (or a controller dividing by it) makes the command NaN; the loop stops as on a
    fault, with the valve at its null, instead of sending it on."""
    for value in (float("nan"), float("inf"), -1e308 * 10):
        plant = _BrokenSensor([], at=4, value=value)
        res = run_loop(plant, np.full(20, 0.03), ProportionalController(40.0), {}, lambda p: p, lambda u, k: u,
                       null_V=5.0)
        assert res.stop_reason == STOP_FAULT and "not a finite number" in res.error
        assert plant.nulls == [5.0] and all(np.isfinite(plant.commands)) and len(plant.commands) == 4
