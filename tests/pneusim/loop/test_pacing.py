"""Pacing of the sample loop: absolute deadlines that never drift, on a simulated clock."""

import numpy as np
import pytest

from pneusim.loop import make_pacing


class _FakeClock:
    """perf_counter and sleep of a machine whose sleeps overshoot by 60 us and whose clock reads cost 1 us."""

    def __init__(self):
        self.now, self.sleeps = 100.0, []

    def perf_counter(self):
        self.now += 1e-6
        return self.now

    def sleep(self, dt):
        self.sleeps.append(dt)
        self.now += dt + 60e-6


@pytest.mark.parametrize("kind", ["realtime", "sleep"])
def test_pacing_keeps_absolute_deadlines_through_a_stall(kind):
    fake = _FakeClock()
    pacing = make_pacing(kind, 0.001, clock=fake.perf_counter, sleep=fake.sleep)
    t0 = pacing.start()
    late = []
    for k in range(200):
        deadline = pacing.wait(k)
        assert deadline == t0 + k * 0.001                  # no drift: deadlines never move
        late.append(fake.now - deadline)
        fake.now += 200e-6                                  # the sample's work
        if k == 50:
            fake.now += 5.5e-3                              # one stall of 5.5 samples
    late = np.array(late)
    assert late.min() >= 0.0
    if kind == "realtime":                                  # the busy wait absorbs the sleep's overshoot
        assert late[:51].max() < 3e-6 and late[-100:].max() < 3e-6
    else:                                                   # plain sleep wakes up late by its overshoot
        assert late[:51].max() > 50e-6 and late[-100:].max() < 70e-6
    # after the stall the loop runs at once until it has caught up, then waits again
    assert late[51] > 4e-3 and late[60] < 3e-3 and late[70] < 70e-6
