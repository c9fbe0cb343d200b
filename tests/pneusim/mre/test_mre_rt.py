"""The real-time settings of the process while the loop is paced: applied and given back, or refused with one
line (pneusim.mre.rt)."""

import json
import os

import pytest

from pneusim.cli import main
from pneusim.mre.rt import RealtimeScope, RealtimeSettings


class _Refusing:
    """``os`` whose SCHED_FIFO call is refused, as for a user without the privilege."""

    def __getattr__(self, name):
        return getattr(os, name)

    def sched_setscheduler(self, *args):
        raise PermissionError(1, "Operation not permitted")


@pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="Linux scheduling calls")
def test_realtime_settings_are_restored_or_refused_with_one_line():
    before = (os.sched_getscheduler(0), os.sched_getparam(0), os.sched_getaffinity(0))
    with RealtimeScope(RealtimeSettings(priority=10, cpu=min(os.sched_getaffinity(0)))) as scope:
        if "SCHED_FIFO 10" in scope.applied:
            assert os.sched_getscheduler(0) == os.SCHED_FIFO
        else:                                   # not permitted here: said so in one line
            assert any("SCHED_FIFO" in n for n in scope.notices)
    assert (os.sched_getscheduler(0), os.sched_getparam(0), os.sched_getaffinity(0)) == before

    with RealtimeScope(RealtimeSettings(priority=10, lock_memory=False, timer_slack=False),
                       system=_Refusing()) as scope:
        pass
    assert scope.applied == [] and scope.describe() == "normal scheduling"
    assert scope.notices == ["mre: SCHED_FIFO priority 10 not available (Operation not permitted); "
                             "normal scheduling: expect more lateness under load"]


@pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="Linux scheduling calls")
def test_cli_realtime_run_says_what_it_got_and_gives_the_scheduler_back(tmp_path, capsys):
    mre = tmp_path / "m.toml"
    # overruns allowed: this test is about the scheduler settings, not timing (a loaded machine overruns)
    mre.write_text('[mre]\nname = "t"\nduration_s = 0.1\nwarmup_s = 0.0\noverrun_budget = 1.0\n'
                   '[rig]\nname = "paper1-mre"\n'
                   '[controller]\nkind = "proportional"\nkp_V_per_m = 40.0\n[reference]\nkind = "steps"\n'
                   'unit = "m"\nlow = 0.02\nhigh = 0.05\nhold_s = [0.02, 0.04]\n', encoding="utf-8")
    before = (os.sched_getscheduler(0), os.sched_getparam(0))
    assert main(["mre", str(mre), "--realtime", "--rt-priority", "10", "--no-report", "--out", str(tmp_path / "o")]) == 0
    out, err = capsys.readouterr()
    assert (os.sched_getscheduler(0), os.sched_getparam(0)) == before
    line = next(x for x in out.splitlines() if x.startswith("real-time settings: "))
    assert "SCHED_FIFO 10" in line or ("normal scheduling" in line and "SCHED_FIFO priority 10 not available" in err)
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["realtime_os"]["applied"] == line[len("real-time settings: "):]
