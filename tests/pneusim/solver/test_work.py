"""The model-work count (:mod:`pneusim.solver.work`) and the deadlines on it (:mod:`pneusim.fit.deadline`): a
run charges its CVODES steps, whichever thread integrates it; work on a branch counts where its result is taken,
and a deadline met there reaches the caller only then."""

import threading

import numpy as np
import pytest

from pneusim.experiment import standard_experiment
from pneusim.fit import DEFAULT_FREE, deadline
from pneusim.model import ActuatorModel
from pneusim.simulate import simulate
from pneusim.solver import work
from pneusim.solver.sensitivity import SensitivitySimulator, command_schedule


def _on(ledger, call, *args):
    """``call(*args)`` with its work charged to ``ledger``, as a side-by-side run does."""
    with work.on(ledger):
        return call(*args)


def test_a_run_charges_its_cvodes_steps_whichever_thread_integrates_it(rig2):
    """Every CVODES step a run takes is charged, :func:`~pneusim.solver.work.step_units` units a step (its fixed
    share and one unit a state of each column: with sensitivities ``1 + ns`` columns, one without); the same run
    takes the same steps and charges the same units on another thread, to the ledger that thread works on."""
    exp = standard_experiment(rig2, "multisine", 1.0, "closed", seed=4)
    sim = simulate(rig2, exp, noise_scale=0.0)
    model = ActuatorModel([])
    params = model.param_vector(rig2)
    scales = params[[model.param_names.index(n) for n in DEFAULT_FREE]].copy()
    integrator = SensitivitySimulator(model, list(DEFAULT_FREE), params, scales, rig2.stroke_m)
    t, u = sim.recording.time_s, sim.recording.valve_cmd_V
    start, stop = 10, 60
    schedule = command_schedule(t, u, start, stop)

    def run(sensitivities=True):
        return integrator.run(t[start], sim.states[start], schedule, stop - start + 1, sensitivities)

    def charged(sensitivities):
        before, steps = work.done(), integrator._integrator.steps_taken
        run(sensitivities)
        return work.done() - before, integrator._integrator.steps_taken - steps

    n = len(model.state_names)
    units, steps = charged(True)
    assert steps > stop - start and units == steps * (work.STEP_UNITS + n * (1 + integrator.ns))
    assert charged(True) == (units, steps)                       # the same run, the same steps
    units_state, steps_state = charged(False)
    assert units_state == steps_state * (work.STEP_UNITS + n) and units_state < units
    ledger, before = work.branch(), work.done()
    worker = threading.Thread(target=lambda: _on(ledger, run))
    worker.start()
    worker.join()
    assert ledger.units == units and work.done() == before   # charged to the branch, not taken yet
    deadline.take(ledger)
    assert work.done() - before == units


def test_work_on_a_branch_counts_and_stops_only_where_its_result_is_taken():
    """A branch opens at its caller's count; a deadline its work meets stops it there without reaching the
    caller's block, which learns of it, with the work, when the result is taken; a branch never taken adds
    nothing and reaches nothing."""
    def spin(units_each):
        while True:
            deadline.check()
            work.charge(units_each)

    start = work.done()
    with deadline.work_deadline(start + 100) as block:
        dropped, taken = work.branch(), work.branch()
        for ledger in (dropped, taken):
            with pytest.raises(deadline.FitDeadlineExceeded):
                _on(ledger, spin, 7)
            assert ledger.stopped and ledger.base == start and ledger.units == 7 * 15   # 14 * 7 <= 100 < 15 * 7
        assert not block.reached and work.done() == start
        deadline.take(taken)
        assert block.reached and not block.by_backstop and work.done() == start + 105
    with deadline.work_deadline(np.inf) as unreached:
        deadline.check()
    assert not unreached.reached
