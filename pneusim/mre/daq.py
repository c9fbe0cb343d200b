"""A real rig through an NI data-acquisition card, with NI's ``nidaqmx`` Python API.

The rig file's ``[daq]`` section says which channels to use and how volts map
to SI units::

    [daq]
    valve_channel = "Dev1/ao0"          # analog output to the proportional valve
    valve_range_V = [0.0, 10.0]         # range of that output, V (must hold valve_min_V .. valve_max_V)
    position_channel = "Dev1/ai0"       # analog input from the position sensor
    position_range_V = [0.0, 10.0]      # input range, V
    position_V_per_m = 100.0            # sensor gain, V/m (default: [known] position_sensor_V_per_m)
    position_offset_V = 0.0             # sensor output at position 0 (fully retracted), V
    terminal_config = "RSE"             # DEFAULT, RSE, NRSE, DIFF or PSEUDO_DIFF
    # optional chamber pressure sensors (both or neither):
    pressure_a_channel = "Dev1/ai1"
    pressure_b_channel = "Dev1/ai2"
    pressure_range_V = [0.0, 10.0]
    pressure_Pa_per_V = 100000.0        # transducer gain, Pa/V
    pressure_offset_Pa = 101325.0       # absolute pressure at 0 V, Pa
    timeout_s = 0.01                    # read/write timeout of one sample, s

``position_m = (V - position_offset_V) / position_V_per_m`` and
``pressure_Pa = pressure_offset_Pa + V * pressure_Pa_per_V``.  Commands outside
``valve_range_V`` are clipped to it before they reach the card (and counted).

The tasks are software-timed single-point tasks (the loop's clock paces them):
one ``nidaqmx.Task`` with ``ai_channels.add_ai_voltage_chan`` per input channel,
one with ``ao_channels.add_ao_voltage_chan`` for the valve; ``read()`` returns
one sample per channel and ``write(value, auto_start=True)`` sets the output.
``nidaqmx`` is an optional dependency (``pip install '.[daq]'``), and it needs
NI's driver; our tests replace the ``nidaqmx`` calls by fakes.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass

from ..errors import InputFileError, PneusimError
from ..plant import Measurement

__all__ = ["DaqConfig", "DaqPlant", "daq_config", "parse_daq_section", "TERMINAL_CONFIGS", "import_nidaqmx"]

TERMINAL_CONFIGS = ("DEFAULT", "RSE", "NRSE", "DIFF", "PSEUDO_DIFF")
_STR = ("valve_channel", "position_channel", "pressure_a_channel", "pressure_b_channel", "terminal_config")
_RANGES = ("valve_range_V", "position_range_V", "pressure_range_V")
_NUMS = ("position_V_per_m", "position_offset_V", "pressure_Pa_per_V", "pressure_offset_Pa", "timeout_s")
_REQUIRED = ("valve_channel", "valve_range_V", "position_channel", "position_range_V")
MISSING_MESSAGE = ("the nidaqmx plant needs NI's Python API: install it with pip install '.[daq]' "
                   "(or pip install nidaqmx) and NI-DAQmx, NI's driver")


@dataclass(frozen=True)
class DaqConfig:
    """The ``[daq]`` section of a rig file, checked (see the module docstring for the keys)."""

    valve_channel: str
    valve_range_V: tuple[float, float]
    position_channel: str
    position_range_V: tuple[float, float]
    position_V_per_m: float
    position_offset_V: float = 0.0
    terminal_config: str = "DEFAULT"
    pressure_a_channel: str = ""
    pressure_b_channel: str = ""
    pressure_range_V: tuple[float, float] = (0.0, 10.0)
    pressure_Pa_per_V: float = 0.0
    pressure_offset_Pa: float = 0.0
    timeout_s: float = 0.01

    @property
    def has_pressures(self) -> bool:
        return bool(self.pressure_a_channel)

    def position_m(self, volts: float) -> float:
        """Sensor volts to position, m."""
        return (volts - self.position_offset_V) / self.position_V_per_m

    def position_V(self, position_m: float) -> float:
        """Position (m) to sensor volts."""
        return self.position_offset_V + position_m * self.position_V_per_m

    def pressure_Pa(self, volts: float) -> float:
        """Transducer volts to absolute pressure, Pa."""
        return self.pressure_offset_Pa + volts * self.pressure_Pa_per_V


def parse_daq_section(table, path, known: dict | None = None) -> DaqConfig:
    """Check a rig file's ``[daq]`` table; every fault names the file and ``daq.KEY``.

    ``known`` is the rig's parameters: ``position_V_per_m`` defaults to ``position_sensor_V_per_m``
    and must agree with it when both are given; ``valve_range_V`` must hold ``valve_min_V .. valve_max_V``.
    """
    known = known or {}

    def fail(key, message):
        raise InputFileError(message, path=path, field=f"daq.{key}" if key else "daq")

    if not isinstance(table, dict):
        fail(None, "[daq] must be a table of channel names and numbers")
    allowed = _STR + _RANGES + _NUMS
    for key in table:
        if key not in allowed:
            fail(key, f"unknown key; expected one of {', '.join(allowed)}")
    for key in _REQUIRED:
        if key not in table:
            fail(key, "required key missing")
    out = {}
    for key, value in table.items():
        if key in _STR:
            if not isinstance(value, str) or (key != "terminal_config" and not value.strip()):
                fail(key, f"expected a channel name such as \"Dev1/ai0\", got {value!r}")
            out[key] = value.strip()
        elif key in _RANGES:
            ok = (isinstance(value, list) and len(value) == 2
                  and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value))
            if not ok or not value[0] < value[1]:
                fail(key, f"expected [low_V, high_V] with low < high, got {value!r}")
            out[key] = (float(value[0]), float(value[1]))
        else:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                fail(key, f"expected a finite number, got {value!r}")
            out[key] = float(value)
    tc = out.get("terminal_config", "DEFAULT")
    if tc not in TERMINAL_CONFIGS:
        fail("terminal_config", f"expected one of {', '.join(TERMINAL_CONFIGS)}, got {tc!r}")
    sensor = known.get("position_sensor_V_per_m")
    if "position_V_per_m" not in out:
        if sensor is None:
            fail("position_V_per_m", "required key missing (or give [known] position_sensor_V_per_m)")
        out["position_V_per_m"] = float(sensor)
    elif sensor is not None and float(sensor) != out["position_V_per_m"]:
        fail("position_V_per_m", f"{out['position_V_per_m']!r} V/m disagrees with [known] position_sensor_V_per_m = "
                                 f"{float(sensor)!r} V/m; give one value")
    if not out["position_V_per_m"] > 0:
        fail("position_V_per_m", f"expected a positive gain in V/m, got {out['position_V_per_m']!r}")
    if out.get("timeout_s", 0.01) <= 0:
        fail("timeout_s", f"expected a positive time in s, got {out['timeout_s']!r}")
    if bool(out.get("pressure_a_channel")) != bool(out.get("pressure_b_channel")):
        fail("pressure_b_channel" if out.get("pressure_a_channel") else "pressure_a_channel",
             "give both chamber pressure channels or neither")
    if out.get("pressure_a_channel"):
        for key in ("pressure_Pa_per_V", "pressure_offset_Pa"):
            if key not in out:
                fail(key, "required with pressure channels")
        if not out["pressure_Pa_per_V"] > 0:
            fail("pressure_Pa_per_V", f"expected a positive gain in Pa/V, got {out['pressure_Pa_per_V']!r}")
    lo, hi = out["valve_range_V"]
    if "valve_min_V" in known and not (lo <= known["valve_min_V"] and known["valve_max_V"] <= hi):
        fail("valve_range_V", f"[{lo!r}, {hi!r}] V does not hold the valve's range [{known['valve_min_V']!r}, "
                              f"{known['valve_max_V']!r}] V of [known]")
    return DaqConfig(**out)


def daq_config(rig) -> DaqConfig | None:
    """The rig's ``[daq]`` table checked against its parameters, or ``None`` when the rig file has none.

    Raises
    ------
    InputFileError
        Naming the rig file and ``daq.KEY`` (see :func:`parse_daq_section`).
    """
    if rig.daq is None:
        return None
    return parse_daq_section(rig.daq, rig.source or rig.name, dict(rig.params))


def import_nidaqmx():
    """``(nidaqmx, nidaqmx.constants)``, or one clear line saying how to install them."""
    try:
        return importlib.import_module("nidaqmx"), importlib.import_module("nidaqmx.constants")
    except ImportError:
        raise PneusimError(MISSING_MESSAGE) from None


class DaqPlant:
    """A real rig behind an NI card (analog output to the valve, analog inputs from the sensors).

    Parameters
    ----------
    rig : Rig
        Its ``[daq]`` section (:func:`daq_config`) gives the channels and conversions.
    modules : (nidaqmx, nidaqmx.constants) or None
        The API; ``None`` imports it (tests pass fakes).

    Attributes
    ----------
    clipped : int
        Commands clipped to ``valve_range_V`` before reaching the card.
    last_written_V : float
        The last value written to the valve channel.
    """

    def __init__(self, rig, modules=None):
        config = daq_config(rig)
        if config is None:
            raise PneusimError(f"rig {rig.name!r} ({rig.source or 'shipped'}): the nidaqmx plant needs a [daq] "
                               "section in the rig file (channels, ranges, volts per metre)")
        self.rig = rig
        self.config: DaqConfig = config
        self.sample_time_s = rig.sample_time_s
        self.nidaqmx, self.constants = modules if modules is not None else import_nidaqmx()
        self.null_V = float(rig.params["valve_null_V"])
        self.clipped = 0
        self.last_written_V = float("nan")
        self.measurement_flag = 0
        self._ai = self._ao = None

    def _daq_call(self, what, fn, *args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except Exception as exc:   # nidaqmx.errors.DaqError and driver faults: one line naming the call
            raise PneusimError(f"nidaqmx: {what} failed: {str(exc).splitlines()[0] if str(exc) else exc!r}") from None

    def reset(self, position_m: float, command_V: float, t0_s: float = 0.0) -> None:
        """Open the tasks and apply ``command_V`` (a real rig starts wherever it is: ``position_m`` is unused)."""
        self.close()
        c, k = self.config, self.constants
        self._t0, self._k = float(t0_s), 0
        term = getattr(k.TerminalConfiguration, c.terminal_config, None)
        if term is None and c.terminal_config == "DIFF":      # nidaqmx before 0.6 spelled it DIFFERENTIAL
            term = getattr(k.TerminalConfiguration, "DIFFERENTIAL")
        volts = k.VoltageUnits.VOLTS
        self._ai = self._daq_call("creating the input task", self.nidaqmx.Task)
        self._daq_call(f"adding input {c.position_channel}", self._ai.ai_channels.add_ai_voltage_chan,
                       c.position_channel, terminal_config=term, min_val=c.position_range_V[0],
                       max_val=c.position_range_V[1], units=volts)
        if c.has_pressures:
            for ch in (c.pressure_a_channel, c.pressure_b_channel):
                self._daq_call(f"adding input {ch}", self._ai.ai_channels.add_ai_voltage_chan, ch,
                               terminal_config=term, min_val=c.pressure_range_V[0], max_val=c.pressure_range_V[1],
                               units=volts)
        self._ao = self._daq_call("creating the output task", self.nidaqmx.Task)
        self._daq_call(f"adding output {c.valve_channel}", self._ao.ao_channels.add_ao_voltage_chan,
                       c.valve_channel, min_val=c.valve_range_V[0], max_val=c.valve_range_V[1], units=volts)
        self._daq_call("starting the input task", self._ai.start)
        self._write(command_V)

    def _write(self, command_V: float) -> None:
        lo, hi = self.config.valve_range_V
        value = min(max(float(command_V), lo), hi)
        if value != command_V:
            self.clipped += 1
        self._daq_call(f"writing {value:g} V to {self.config.valve_channel}", self._ao.write, value,
                       auto_start=True, timeout=self.config.timeout_s)
        self.last_written_V = value

    def measure(self) -> Measurement:
        c = self.config
        raw = self._daq_call(f"reading {c.position_channel}", self._ai.read, timeout=c.timeout_s)
        volts = list(raw) if isinstance(raw, (list, tuple)) else [raw]
        t_s = self._t0 + self._k * self.sample_time_s
        if c.has_pressures:
            return Measurement(t_s, c.position_m(volts[0]), c.pressure_Pa(volts[1]), c.pressure_Pa(volts[2]))
        return Measurement(t_s, c.position_m(volts[0]))

    def step(self, command_V: float) -> None:
        self._write(command_V)
        self._k += 1

    def safe_stop(self, null_V: float | None = None) -> None:
        """Valve to its null, then release the card."""
        if self._ao is not None:
            try:
                self._write(self.null_V if null_V is None else null_V)
            finally:
                self.close()

    def close(self) -> None:
        for task in (self._ai, self._ao):
            if task is not None:
                try:
                    task.close()
                except Exception:   # closing a task the driver already dropped must not hide the real fault
                    pass
        self._ai = self._ao = None
