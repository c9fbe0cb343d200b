"""MRE settings that cannot give a result are refused before the loop starts, naming the file and the key;
a run whose recording its own check would refuse does not end with exit 0; SIGTERM stops the loop safely."""

import copy
import json
import signal
import subprocess
import sys
import time

import pytest

from pneusim.cli import main
from pneusim.errors import PneusimError
from pneusim.mre.scenario import build_components, validate_mre

from mre_cases import rig_server_thread

BASE = {
    "mre": {"name": "t", "duration_s": 0.3, "warmup_s": 0.05, "seed": 3, "overrun_budget": 1.0},
    "rig": {"name": "paper1-mre"},
    "controller": {"kind": "proportional", "kp_V_per_m": 40.0},
    "reference": {"kind": "steps", "unit": "m", "low": 0.02, "high": 0.05, "hold_s": [0.05, 0.1]},
    "identifiers": [{"name": "RLS ARMA order 4", "kind": "rls", "order": 4, "horizons": [1, 5]},
                    {"name": "sysid order 3", "kind": "recursive_arx", "order": 3}],
}


def _toml(mre=None, ident=None, ident_index=0, **tables) -> str:
    data = copy.deepcopy(BASE)
    data.update(copy.deepcopy(tables))
    data["mre"].update(mre or {})
    data["identifiers"][ident_index].update(ident or {})
    lines = []
    for table in ("mre", "rig", "controller", "reference"):
        lines.append(f"[{table}]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in data[table].items()]
    for it in data["identifiers"]:
        lines.append("[[identifiers]]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in it.items()]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("mre, ident, index, field", [
    ({"noise_scale": 1e300}, None, 0, "mre.noise_scale"),
    ({"initial_position_m": 5.0}, None, 0, "mre.initial_position_m"),
    ({"initial_position_m": -0.01}, None, 0, "mre.initial_position_m"),
    (None, {"horizons": [100000]}, 0, "identifiers[0].horizons"),
    (None, {"initial_covariance": 1e308}, 0, "identifiers[0].initial_covariance"),
    (None, {"forgetting": 1e-300}, 0, "identifiers[0].forgetting"),
    (None, {"forgetting": 0.5}, 1, "identifiers[1].forgetting"),
    (None, {"initial_covariance": 1e300}, 1, "identifiers[1].initial_covariance"),
])
def test_settings_that_cannot_give_a_result_are_refused_before_the_loop(tmp_path, capsys, mre, ident, index, field):
    data = copy.deepcopy(BASE)
    data["mre"].update(mre or {})
    data["identifiers"][index].update(ident or {})
    with pytest.raises(PneusimError) as err:
        build_components(validate_mre(data, "t.toml"))
    assert field in str(err.value) and "t.toml" in str(err.value)
    f = tmp_path / "m.toml"
    f.write_text(_toml(mre, ident, index))
    assert main(["mre", str(f), "--fast", "--out", str(tmp_path / "o"), "--no-report"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and field in err.strip().splitlines()[-1]
    assert not (tmp_path / "o" / "recording.csv").exists()


def test_a_recording_its_own_check_refuses_ends_the_run_with_an_error(tmp_path, capsys):
    """Noise within the limit, but large enough that a few pressures, read with it, lie beyond what the rig
    can record (the valve fully open, then shut, in open loop: the chambers at supply and at atmosphere)."""
    f = tmp_path / "m.toml"
    f.write_text(_toml({"noise_scale": 60.0, "duration_s": 3.0}, controller={"kind": "none"},
                       reference={"kind": "steps", "unit": "native", "low": 0.0, "high": 10.0, "hold_s": [1.0, 1.0]}))
    assert main(["mre", str(f), "--fast", "--out", str(tmp_path / "o"), "--no-report"]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert "pneusim check" in last and "pressure_" in last
    assert (tmp_path / "o" / "recording.csv").exists()         # kept: everything taken is on disk


@pytest.mark.slow
def test_sigterm_stops_the_loop_with_the_valve_at_null_and_the_summary_written(tmp_path):
    """``pneusim mre --plant udp:...`` on a rig server: SIGTERM ends the session with the valve at null."""
    f = tmp_path / "m.toml"
    f.write_text(_toml({"duration_s": 60.0}))
    out = tmp_path / "o"
    with rig_server_thread(seed=3, watchdog_s=5.0) as (server, _):
        proc = subprocess.Popen([sys.executable, "-m", "pneusim.cli", "mre", str(f), "--realtime", "--rt-priority",
                                 "0", "--plant", f"udp:127.0.0.1:{server.address[1]}", "--out", str(out),
                                 "--no-report", "--no-status"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        try:
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and server.stats.commands < 300:    # the loop runs
                time.sleep(0.05)
            assert server.stats.commands >= 300 and server.active
            proc.send_signal(signal.SIGTERM)
            stdout, stderr = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert proc.returncode == 128 + signal.SIGTERM, stderr
    assert "Traceback" not in stderr and "terminated (SIGTERM): the valve was sent to its null" in stderr
    # the loop said goodbye: the rig's valve is at its null, not at the last command, and not by the watchdog
    assert server.stats.byes == 1 and server.valve_V == 5.0 and not server.active and server.stats.watchdog_trips == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stop_reason"] == "terminated (SIGTERM)" and summary["valve_to_null"]
    assert 0 < summary["samples"] < summary["samples_planned"]
