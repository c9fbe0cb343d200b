"""Property: whatever a user types, ``pneusim`` ends with exit status 0 or 2 and never a traceback.

Hypothesis draws option values (valid, out of range, not numbers, NaN, infinities, misspelt names)
for ``simulate``, ``check`` and ``plot``; valid runs are kept short (at most 60 samples) so the
property is cheap.  Any exception escaping :func:`pneusim.cli.main` fails the test.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pneusim.cli import main
from pneusim.experiment import MAX_SAMPLES
from pneusim.recording import Recording, write_recording

NUMBERS = st.one_of(st.sampled_from(["nan", "inf", "-inf", "-1", "0", "1e308", "abc", "", "1_0", "0x10", "1e-300"]),
                    st.floats(allow_nan=True, allow_infinity=True).map(repr),
                    st.integers(-10, 2).map(str))
PARAMS = st.tuples(st.sampled_from(["moving_mass_kg", "moving_mas_kg", "supply_Pa", "position_adc_bits",
                                    "valve_null_V", "friction_static_N", "endstop_damping_N_s_per_m", ""]),
                   NUMBERS).map(lambda kv: f"{kv[0]}={kv[1]}")
EFFECTS = st.one_of(st.sampled_from(["valve_deadband", "nosuch", "valve_deadband:", "valve_deadband:deadband_V",
                                     ":", "transport_delay:delay_s=1e9"]),
                    st.tuples(st.sampled_from(["valve_deadband:deadband_V", "valve_dynamics:damping",
                                               "heat_transfer:time_constant_s", "valve_offset:offset_V"]),
                              NUMBERS).map(lambda kv: f"{kv[0]}={kv[1]}"))
SETTINGS = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


#: durations: short valid ones (10 s at most), and ones to refuse -- not numbers, not finite, too short for 50
#: samples, or more samples than a recording may hold (experiment.MAX_SAMPLES); arbitrary floats in between
#: would be valid runs of hours, which this property does not need
DURATIONS = st.one_of(st.sampled_from(["0.05", "0.06", "1_0", "nan", "inf", "-inf", "-1", "0", "1e308", "abc", "",
                                       "0x10", "1e-300", "12348031.0", "1152921504606847.0"]),
                      st.floats(max_value=0.0495).map(repr), st.floats(min_value=1e5).map(repr))


@SETTINGS
@given(duration=DURATIONS, seed=NUMBERS,
       noise=st.one_of(st.just("0.5"), NUMBERS), backend=st.sampled_from(["cvode", "euler", "", "scipy-bdf"]),
       loop=st.sampled_from(["open", "closed", "half"]), param=st.lists(PARAMS, max_size=2),
       effect=st.lists(EFFECTS, max_size=1), out=st.sampled_from(["x.csv", "x.mat", "x.txt", "no/dir/x.csv"]))
def test_simulate_never_ends_in_a_traceback(tmp_path, duration, seed, noise, backend, loop, param, effect, out):
    argv = ["simulate", "--rig", "paper1-mre", "--input", "steps", f"--duration={duration}", f"--seed={seed}",
            f"--noise-scale={noise}", f"--backend={backend}", f"--loop={loop}", "--out", str(tmp_path / out)]
    argv += [f"--param={p}" for p in param] + [f"--effect={e}" for e in effect]
    try:
        # a 1e300 s or 1e-300 s duration must be refused, not attempted
        float_duration = float(duration)
    except ValueError:
        float_duration = None
    code = main(argv)
    assert code in (0, 2)
    if code == 0:   # only a finite duration of 50 samples (1 ms each) to MAX_SAMPLES can have run
        assert float_duration is not None and 0.0495 <= float_duration <= MAX_SAMPLES * 1e-3


@st.composite
def files(draw):
    """A recording written by pneusim and then damaged: a cell, a metadata value, or random bytes."""
    n = draw(st.integers(40, 80))
    t = np.arange(n) * 0.01
    rec = Recording(time_s=t, valve_cmd_V=5 + np.sin(t), position_m=0.1 + 0.01 * np.sin(t),
                    pressure_a_Pa=4e5 + 0 * t, pressure_b_Pa=3e5 + 0 * t,
                    metadata={"format": "pneusim-recording/1", "sample_time_s": "0.01",
                              "rig": draw(st.sampled_from(["paper2-enfield", "paper1-mre", "no-such-rig", ""])),
                              "loop": "open"})
    return rec, draw(st.sampled_from(["none", "cell", "meta", "bytes"])), draw(NUMBERS), draw(st.binary(max_size=300))


@pytest.mark.slow
@SETTINGS
@given(case=files(), rig=st.sampled_from([None, "paper2-enfield", "nope", "x.toml"]),
       command=st.sampled_from(["check", "plot"]))
def test_check_and_plot_never_end_in_a_traceback(tmp_path, case, rig, command):
    rec, damage, value, raw = case
    path = tmp_path / "r.csv"
    write_recording(rec, path)
    lines = path.read_text().split("\n")
    if damage == "cell":
        lines[6] = lines[6].split(",", 1)[0] + "," + value + "," + lines[6].split(",", 2)[-1]
    elif damage == "meta":
        lines[1] = f"# sample_time_s: {value}"
    path.write_text("\n".join(lines)) if damage != "bytes" else path.write_bytes(raw)
    argv = [command, str(path)] + (["--out", str(tmp_path / "r.png")] if command == "plot" else [])
    if rig and command == "check":
        argv += ["--rig", rig]
    assert main(argv) in (0, 2)
