"""The diagnosis's time budget on stand-in stages: a fit that would end past the budget is refused, one that runs to
its end is stopped there (counted in model work, with a processor-time backstop), and a step given a share of it
stops at that share and leaves the rest.
"""

import pytest

def test_the_time_budget_refuses_a_fit_that_would_end_past_it_and_the_diagnosis_says_so():
    """A whole fit expected to cost more than is left is not started: the stage raises TimeBudgetExhausted (a
    PneusimError, reported as a failed fit), every later stage is refused too, and the status names the first
    step refused; a screening is refused only once the budget is spent."""
    from pneusim.diagnosis.budget import Budget, TimeBudgetExhausted, gated_stages
    from pneusim.diagnosis.estimator import DiagnosisStages
    from pneusim.errors import PneusimError

    calls = []
    stages = DiagnosisStages(refit=lambda *a, **k: calls.append("refit") or "fit",
                             screen=lambda *a, **k: calls.append("screen") or {"cost": 1.0})
    budget = Budget(1000.0)
    gated = gated_stages(stages, budget, fit_cost_s=10.0)
    assert gated.refit() == "fit" and gated.screen()["cost"] == 1.0 and budget.status == "complete"
    tight = Budget(1000.0)
    tight.seconds = tight.used() + 5.0          # 5 s left: a screening fits, a 10 s fit does not
    gated = gated_stages(stages, tight, fit_cost_s=10.0)
    assert gated.screen()["cost"] == 1.0
    with pytest.raises(TimeBudgetExhausted, match="the refit .*does not fit in the 5 s left") as refused:
        gated.refit()
    assert isinstance(refused.value, PneusimError)
    with pytest.raises(TimeBudgetExhausted):
        gated.screen()                          # once a step is refused, the rest are too
    assert calls == ["refit", "screen", "screen"]
    assert tight.status.startswith("stopped by the time budget: the refit (expected 10 s")
    with pytest.raises(PneusimError, match="positive number of seconds"):
        Budget(0.0)


def test_a_fit_that_runs_to_the_end_of_the_budget_is_stopped_and_its_result_not_used():
    """A fit that started within the budget but runs on is stopped at the budget's end by the deadline its
    evaluations check; whatever it returns after catching that (a half-way fit) is not used: the step raises
    TimeBudgetExhausted and the status says it was stopped.  The budget is counted in model work, so where it
    stops is exact: the evaluations that began within it, on any machine.  A fit whose work the count misses is
    stopped by the processor-time backstop, and the status says so.  Outside a budget, the check does nothing."""
    import time

    from pneusim.diagnosis.budget import Budget, TimeBudgetExhausted, gated_stages
    from pneusim.diagnosis.estimator import DiagnosisStages
    from pneusim.diagnosis.rules import WORK_UNITS_PER_S
    from pneusim.fit import deadline
    from pneusim.solver import work

    def long_refit(units_each):
        def refit(*args, **kwargs):
            try:
                while True:                          # a fit's evaluations, each checking the deadline
                    deadline.check()
                    evaluations.append(work.done())
                    work.charge(units_each)
            except deadline.FitDeadlineExceeded:
                return "a fit stopped half-way"      # a route that catches the stop and returns what it has
        return refit

    evaluations = []
    # each evaluation charges a million units: the budget (10.5 evaluations, a third of a second at the reference
    # rate) is then far above what the loop costs in processor time, so its backstop (4 times the budget) cannot
    # end it first, even in a process whose other threads are busy
    units = 1_000_000
    budget = Budget(10.5 * units / WORK_UNITS_PER_S)
    gated = gated_stages(DiagnosisStages(refit=long_refit(units)), budget, fit_cost_s=0.0)
    with pytest.raises(TimeBudgetExhausted, match="ran to the end of the 0 s time budget and was stopped$"):
        gated.refit()
    assert len(evaluations) == 11 and evaluations[0] == budget.started   # the 11th began at 10 of 10.5 units
    assert budget.status.startswith("stopped by the time budget: the refit ran to the end")
    evaluations.clear()
    budget = Budget(0.05)                            # backstop: 4 x 0.05 s of processor time, no work counted
    gated = gated_stages(DiagnosisStages(refit=long_refit(0)), budget, fit_cost_s=0.0)
    with pytest.raises(TimeBudgetExhausted, match="stopped .by its processor-time backstop.$"):
        gated.refit()
    assert evaluations and time.process_time() - budget.cpu_started >= 0.2
    deadline.check()                              # no deadline set: nothing happens


def test_a_step_given_a_share_of_the_budget_stops_there_and_leaves_the_rest():
    """A step run in ``Budget.share(f)`` (the best set's whole fit) stops where it has used ``f`` of the budget left
    at its start, exactly, in model work; the budget is not stopped by it, and the steps after the block run
    against the whole budget, up to its end (where the budget itself stops them)."""
    from pneusim.diagnosis.budget import Budget, TimeBudgetExhausted, gated_stages
    from pneusim.diagnosis.estimator import DiagnosisStages
    from pneusim.diagnosis.rules import WORK_UNITS_PER_S
    from pneusim.fit import deadline
    from pneusim.solver import work

    evaluations = []

    def long_fit(*args, **kwargs):
        while True:                                  # a fit's evaluations, each checking the deadline
            deadline.check()
            evaluations.append(work.done())
            work.charge(1000)

    budget = Budget(20.5 * 1000 / WORK_UNITS_PER_S)
    gated = gated_stages(DiagnosisStages(fit=long_fit, refit=long_fit), budget, fit_cost_s=0.0)
    with budget.share(0.5):
        with pytest.raises(TimeBudgetExhausted, match="ran to the end of its share of the time budget"):
            gated.fit()
    assert len(evaluations) == 11                    # the 11th began at 10 of the 10.25 units of its share
    assert budget.stopped is None and budget.status == "complete" and budget.share_ends is None
    evaluations.clear()
    with pytest.raises(TimeBudgetExhausted, match="ran to the end of the 0 s time budget and was stopped$"):
        gated.refit()                                # after the block: on to the budget's own end
    assert len(evaluations) == 10                    # from 11 to 20.5 units
    assert budget.status.startswith("stopped by the time budget: the refit ran to the end")
