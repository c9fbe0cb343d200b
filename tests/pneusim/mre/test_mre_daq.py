"""The NI-DAQmx plant with the nidaqmx calls replaced by fakes: channels, ranges and unit conversions
exactly as the rig file's [daq] section says; clear messages for a missing package or a bad section."""

import enum
import sys
import types

import numpy as np
import pytest

from pneusim.cli import main
from pneusim.controller import ProportionalController
from pneusim.errors import InputFileError, PneusimError
from pneusim.loop import run_loop
from pneusim.mre.daq import DaqPlant, daq_config
from pneusim.rig import RIG_DIR, load_rig, write_rig

DAQ = """
[daq]
valve_channel = "cDAQ1Mod2/ao1"
valve_range_V = [0.0, 10.0]
position_channel = "cDAQ1Mod1/ai3"
position_range_V = [-10.0, 10.0]
position_V_per_m = 80.0
position_offset_V = 0.5
terminal_config = "DIFF"
pressure_a_channel = "cDAQ1Mod1/ai4"
pressure_b_channel = "cDAQ1Mod1/ai5"
pressure_range_V = [0.0, 5.0]
pressure_Pa_per_V = 200000.0
pressure_offset_Pa = 101325.0
timeout_s = 0.005
"""


def _rig_file(tmp_path, daq=DAQ):
    text = (RIG_DIR / "paper1-mre.toml").read_text(encoding="utf-8")
    text = text[:text.index("[daq]")].replace("position_sensor_V_per_m = 100.0", "")
    path = tmp_path / "myrig.toml"
    path.write_text(text + daq, encoding="utf-8")
    return path


class _Fake:
    """nidaqmx and nidaqmx.constants as far as the plant uses them; every call is logged."""

    def __init__(self, volts):
        self.log, self.tasks, self.volts = [], [], volts
        fake = self

        class TerminalConfiguration(enum.Enum):   # the members of nidaqmx 1.x
            RSE, NRSE, DIFF, PSEUDO_DIFF, DEFAULT = 10083, 10078, 10106, 12529, -1

        class VoltageUnits(enum.Enum):
            VOLTS = 10348

        class Channels:
            def __init__(self, task):
                self.task = task

            def add_ai_voltage_chan(self, physical_channel, name_to_assign_to_channel="",
                                    terminal_config=TerminalConfiguration.DEFAULT, min_val=-5.0, max_val=5.0,
                                    units=VoltageUnits.VOLTS, custom_scale_name=""):
                self.task.channels.append(physical_channel)
                fake.log.append(("ai", physical_channel, terminal_config, min_val, max_val, units))

            def add_ao_voltage_chan(self, physical_channel, name_to_assign_to_channel="", min_val=-10.0,
                                    max_val=10.0, units=VoltageUnits.VOLTS, custom_scale_name=""):
                self.task.channels.append(physical_channel)
                fake.log.append(("ao", physical_channel, min_val, max_val, units))

        class Task:
            def __init__(self, new_task_name=""):
                self.channels, self.closed, self.written = [], False, []
                self.ai_channels = self.ao_channels = Channels(self)
                fake.tasks.append(self)

            def start(self):
                fake.log.append(("start", tuple(self.channels)))

            def read(self, number_of_samples_per_channel=-1, timeout=10.0):
                fake.log.append(("read", timeout))
                v = [fake.volts[ch] for ch in self.channels]
                return v[0] if len(v) == 1 else v          # nidaqmx: a float for one channel, else a list

            def write(self, data, auto_start=False, timeout=10.0):
                assert auto_start is True and isinstance(data, float)
                self.written.append(data)
                fake.log.append(("write", data, timeout))

            def close(self):
                self.closed = True

        self.module = types.SimpleNamespace(Task=Task)
        self.constants = types.SimpleNamespace(TerminalConfiguration=TerminalConfiguration, VoltageUnits=VoltageUnits)


def test_daq_plant_uses_the_channels_and_converts_exactly_as_the_rig_file_says(tmp_path):
    rig = load_rig(_rig_file(tmp_path))
    volts = {"cDAQ1Mod1/ai3": 3.7, "cDAQ1Mod1/ai4": 2.25, "cDAQ1Mod1/ai5": 1.5}
    fake = _Fake(volts)
    plant = DaqPlant(rig, (fake.module, fake.constants))
    plant.reset(0.0, 5.0, 0.0)
    TC, V = fake.constants.TerminalConfiguration, fake.constants.VoltageUnits.VOLTS
    assert fake.log[:5] == [("ai", "cDAQ1Mod1/ai3", TC.DIFF, -10.0, 10.0, V),
                            ("ai", "cDAQ1Mod1/ai4", TC.DIFF, 0.0, 5.0, V),
                            ("ai", "cDAQ1Mod1/ai5", TC.DIFF, 0.0, 5.0, V),
                            ("ao", "cDAQ1Mod2/ao1", 0.0, 10.0, V),
                            ("start", ("cDAQ1Mod1/ai3", "cDAQ1Mod1/ai4", "cDAQ1Mod1/ai5"))]
    assert fake.log[5] == ("write", 5.0, 0.005)
    m = plant.measure()
    assert m.position_m == (3.7 - 0.5) / 80.0                  # (V - offset) / (V/m)
    assert m.pressure_a_Pa == 101325.0 + 2.25 * 200000.0     # offset + V * Pa/V
    assert m.pressure_b_Pa == 101325.0 + 1.5 * 200000.0
    assert fake.log[-1] == ("read", 0.005)
    ao = fake.tasks[1]
    plant.step(7.25)
    plant.step(12.0)                                          # outside the card's range: clipped, counted
    plant.step(-1.0)
    assert ao.written[1:] == [7.25, 10.0, 0.0] and plant.clipped == 2
    plant.safe_stop(None)                                      # valve to the rig's null, tasks released
    assert ao.written[-1] == 5.0 == rig.params["valve_null_V"]
    assert all(t.closed for t in fake.tasks)


def test_daq_plant_in_the_loop(tmp_path):
    """A closed loop through the fake card: the command the card gets is the controller's law on the
    position the card's volts mean."""
    rig = load_rig(_rig_file(tmp_path, DAQ.replace("pressure_a_channel", "#").replace("pressure_b_channel", "#")))
    fake = _Fake({"cDAQ1Mod1/ai3": 0.5})
    plant = DaqPlant(rig, (fake.module, fake.constants))
    ref = np.full(60, 0.04)
    plant.reset(0.0, 5.0)
    volts = np.linspace(0.5, 4.5, 60)
    it = iter(volts)
    orig = fake.module.Task.read
    fake.module.Task.read = lambda self, **k: (orig(self, **k), next(it))[1]
    res = run_loop(plant, ref, ProportionalController(40.0), {}, lambda p: p, lambda u, k: u, null_V=5.0)
    assert res.completed
    np.testing.assert_array_equal(res.position_m, (volts - 0.5) / 80.0)
    expected = np.clip(5.0 + 40.0 * (0.04 - (volts - 0.5) / 80.0), 0.0, 10.0)
    assert fake.tasks[1].written[1:-1] == expected[:-1].tolist()   # last sample: no step, then null
    assert fake.tasks[1].written[-1] == 5.0 and np.isnan(res.pressure_a_Pa).all()


def test_missing_nidaqmx_is_one_clear_line(monkeypatch):
    monkeypatch.setitem(sys.modules, "nidaqmx", None)          # import nidaqmx -> ImportError
    with pytest.raises(PneusimError, match=r"pip install '\.\[daq\]'"):
        DaqPlant(load_rig("paper1-mre"))


def test_shipped_paper1_rig_has_the_example_daq_section():
    d = daq_config(load_rig("paper1-mre"))
    assert d.valve_channel == "Dev1/ao0" and d.position_V_per_m == 100.0 and d.valve_range_V == (0.0, 10.0)
    assert daq_config(load_rig("paper2-enfield")) is None


@pytest.mark.parametrize("edit, field", [
    (("valve_range_V = [0.0, 10.0]", "valve_range_V = [10.0, 0.0]"), "daq.valve_range_V"),
    (("valve_range_V = [0.0, 10.0]", "valve_range_V = [0.0, 5.0]"), "daq.valve_range_V"),
    (('terminal_config = "DIFF"', 'terminal_config = "differential"'), "daq.terminal_config"),
    (("position_V_per_m = 80.0", "position_V_per_m = -80.0"), "daq.position_V_per_m"),
    (('pressure_b_channel = "cDAQ1Mod1/ai5"', ""), "daq.pressure_b_channel"),
    (("timeout_s = 0.005", "timeout = 0.005"), "daq.timeout"),
])
def test_bad_daq_sections_are_refused_naming_the_key(tmp_path, capsys, edit, field):
    """The rig keeps [daq] as data; the card's plant refuses a bad section, and so does any command that
    takes the rig file, in one line naming the file and the key."""
    path = _rig_file(tmp_path, DAQ.replace(*edit))
    rig = load_rig(path)
    with pytest.raises(InputFileError) as err:
        DaqPlant(rig, (None, None))
    assert str(path) in str(err.value) and field in str(err.value)
    assert main(["rigs", str(path)]) == 2
    out = capsys.readouterr().err.strip()
    assert len(out.splitlines()) == 1 and str(path) in out and field in out


def test_gain_given_twice_must_agree(tmp_path):
    text = (RIG_DIR / "paper1-mre.toml").read_text(encoding="utf-8").replace(
        'terminal_config = "RSE"', 'terminal_config = "RSE"\nposition_V_per_m = 99.0')
    path = tmp_path / "r.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputFileError, match="disagrees with"):
        daq_config(load_rig(path))


def test_daq_section_survives_writing_the_rig_back(tmp_path):
    for rig in (load_rig("paper1-mre"), load_rig(_rig_file(tmp_path))):
        back = load_rig(write_rig(rig, tmp_path / "back.toml"))
        assert back.daq == rig.daq
        assert daq_config(back) == daq_config(rig)
