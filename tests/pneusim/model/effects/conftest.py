"""Shared fixture of the effect tests: an open-loop experiment from a command."""

import numpy as np
import pytest

from pneusim.experiment import Experiment


@pytest.fixture
def open_loop():
    """``open_loop(rig, command, position=None, warmup_s=0.0)``: an open-loop experiment of the valve
    commands ``command`` (V), from rest at ``position`` (m, default mid-stroke)."""
    def make(rig, command, position=None, warmup_s=0.0):
        return Experiment("open", rig.sample_time_s, np.asarray(command, float), warmup_s=warmup_s,
                          initial_position_m=0.5 * rig.stroke_m if position is None else position)
    return make
