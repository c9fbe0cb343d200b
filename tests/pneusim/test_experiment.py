"""Experiments: the open-loop doublets kept off the end stops by a supervisor."""

import numpy as np
import pytest

from pneusim.errors import PneusimError
from pneusim.experiment import Experiment, recentering_doublets
from pneusim.model import make_effect
from pneusim.rig import load_rig
from pneusim.simulate import simulate


def _time_at_stops(rec, stroke):
    return float(np.mean((rec.position_m < 0.005 * stroke) | (rec.position_m > 0.995 * stroke)))


def test_recentering_keeps_a_drifting_piston_off_the_end_stops():
    """A valve null offset makes open-loop doublets drift into a stop; with the supervisor a pulse towards
    the middle replaces a doublet whenever the piston is beyond the band, and the piston stays in the stroke."""
    rig = load_rig("paper2-enfield")
    offset = [make_effect("valve_offset", offset_V=-0.08)]
    planned = recentering_doublets(rig, 40.0, seed=3)
    plain = Experiment("open", planned.sample_time_s, planned.signal, None)
    drifted = simulate(rig, plain, offset, seed=1).recording
    kept = simulate(rig, planned, offset, seed=1).recording
    assert _time_at_stops(drifted, rig.stroke_m) > 0.3
    assert _time_at_stops(kept, rig.stroke_m) < 0.02
    # the recording holds the commands the valve got: the plan where nothing was replaced
    replaced = kept.valve_cmd_V != planned.signal
    assert 0 < replaced.mean() < 0.2
    assert kept.loop == "open" and kept.reference_m is None


def test_a_supervisor_is_for_open_loop_only():
    with pytest.raises(PneusimError, match="supervisor"):
        Experiment("closed", 0.01, np.zeros(10), controller=object(), supervisor=lambda k, x: None)
