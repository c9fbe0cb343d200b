"""The operating conditions the locate step tags, the signatures read and the evidence plots draw: each one
threshold of :mod:`pneusim.diagnosis.rules`, on both sides of its edge, and the same samples wherever it is used.

A recording here is a stand-in with the fields the conditions read (time, position, command, pressures), so the
edges can be placed exactly; the end-to-end locate step on a simulated recording is in ``test_diagnosis.py``.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from pneusim.diagnosis import rules
from pneusim.diagnosis.locate import moving_speed, near_null, operating_conditions, valve_null_and_span

STROKE_M = 0.2
PARAMS = {"valve_null_V": 5.0, "valve_min_V": 0.0, "valve_max_V": 10.0, "supply_Pa": 6e5, "atmosphere_Pa": 1e5}
RIG = SimpleNamespace(stroke_m=STROKE_M, params=PARAMS)
DT_S = 0.01


def _recording(command_V, position_m=None, pressures_Pa=None):
    n = len(command_V)
    position = np.full(n, 0.5 * STROKE_M) if position_m is None else np.asarray(position_m, float)
    rec = SimpleNamespace(time_s=np.arange(n) * DT_S, position_m=position, valve_cmd_V=np.asarray(command_V, float),
                          has_pressures=pressures_Pa is not None)
    if pressures_Pa is not None:
        rec.pressure_a_Pa, rec.pressure_b_Pa = (np.asarray(p, float) for p in pressures_Pa)
    return rec


def test_the_valve_is_near_null_within_its_rule_of_the_span_and_the_plots_use_the_same_samples():
    from pneusim.diagnosis.evidence import _near_null

    null, span = valve_null_and_span(RIG)
    assert (null, span) == (5.0, 10.0)
    edge = rules.NEAR_NULL_SPAN * span
    command = null + np.array([0.0, 0.99, -0.99, 1.01, -1.01, 5.0]) * edge
    rec = _recording(command)
    expected = np.array([True, True, True, False, False, False])
    masks = operating_conditions(rec, RIG, velocity_m_per_s=np.zeros(command.size))
    assert np.array_equal(masks["valve near null"], expected)
    assert np.array_equal(near_null(command, RIG), expected)
    # the holding and relaxation plots select the samples the signatures and the locate step read
    result = SimpleNamespace(nominal_fit=SimpleNamespace(rig=RIG, recording=rec))
    assert np.array_equal(_near_null(result, rules.NEAR_NULL_SPAN)[3], expected)


def test_motion_and_holding_split_at_the_moving_speed():
    speed = moving_speed(RIG)
    assert speed == pytest.approx(rules.MOVING_STROKE * STROKE_M)
    v = np.array([1.01, 0.99, 0.0, -0.99, -1.01]) * speed
    masks = operating_conditions(_recording(np.full(v.size, 5.0)), RIG, velocity_m_per_s=v)
    assert masks["extending"].tolist() == [True, False, False, False, False]
    assert masks["retracting"].tolist() == [False, False, False, False, True]
    assert masks["holding still"].tolist() == [False, True, True, True, False]


def test_end_stops_openings_and_pressures_at_their_rules():
    n = 6
    x = np.full(n, 0.5 * STROKE_M)
    x[0:2] = np.array([0.99, 1.01]) * rules.END_STOP_STROKE * STROKE_M
    x[2:4] = STROKE_M - np.array([0.99, 1.01]) * rules.END_STOP_STROKE * STROKE_M
    half_span = 5.0
    command = 5.0 + np.array([1.01, 0.99, 0.0, 0.0, -1.01, 0.0]) * rules.LARGE_OPENING_HALF_SPAN * half_span
    high = rules.HIGH_PRESSURE_SUPPLY * PARAMS["supply_Pa"]
    low = rules.LOW_PRESSURE_ATMOSPHERES * PARAMS["atmosphere_Pa"]
    pa = np.array([1.01 * high, 0.99 * high, 3e5, 3e5, 3e5, 3e5])
    pb = np.array([3e5, 3e5, 0.99 * low, 1.01 * low, 3e5, 3e5])
    masks = operating_conditions(_recording(command, x, (pa, pb)), RIG, velocity_m_per_s=np.zeros(n))
    assert masks["near an end stop"].tolist() == [True, False, True, False, False, False]
    assert masks["large opening"].tolist() == [True, False, False, False, True, False]
    assert masks["high chamber pressure"].tolist() == [True, False, False, False, False, False]
    assert masks["low chamber pressure"].tolist() == [False, False, True, False, False, False]


def test_a_fast_command_change_marks_the_rules_time_after_it_and_a_reversal_both_sides():
    n = 40
    null, span = valve_null_and_span(RIG)
    command = np.full(n, null)
    command[10:] += 1.01 * rules.FAST_CHANGE_SPAN * span        # one step larger than the rule at sample 10
    command[30:] += 0.99 * rules.FAST_CHANGE_SPAN * span        # one smaller at sample 30
    lookback = int(round(rules.FAST_CHANGE_S / DT_S))
    v = np.where(np.arange(n) < 20, 1.0, -1.0) * 2 * moving_speed(RIG)   # one reversal at sample 20
    masks = operating_conditions(_recording(command), RIG, velocity_m_per_s=v)
    assert np.flatnonzero(masks["right after a fast command change"]).tolist() == list(range(10, 10 + lookback))
    half = int(round(rules.REVERSAL_S / DT_S))
    assert np.flatnonzero(masks["velocity reversal"]).tolist() == list(range(20 - half, 20 + half))
