"""The mixed-reality environment: paced vs fast loop, stop paths, replay, PID, bad files (pneusim.mre)."""

import copy
import functools
import html
import io

import numpy as np
import pytest

import pneusim.commands.mre as mre_command
from pneusim.cli import build_parser, main, run_command
from pneusim.controller import PIDController, ProportionalController
from pneusim.loop import RealtimePacing, StatusLine, run_loop
from pneusim.mre.run import run_mre
from pneusim.mre.scenario import build_components, validate_mre
from pneusim.plant import SimulatedPlant
from pneusim.recording import read_recording

from mre_cases import mre_text

BASE = {
    "mre": {"name": "t", "duration_s": 0.3, "warmup_s": 0.05, "seed": 3, "overrun_budget": 1.0},
    "rig": {"name": "paper1-mre"},
    "controller": {"kind": "proportional", "kp_V_per_m": 40.0},
    "reference": {"kind": "pulses", "unit": "m", "base": 0.01, "amplitude": [0.01, 0.03], "width_s": [0.05, 0.1],
                  "rest_s": [0.05, 0.1], "sign": "positive"},
    "identifiers": [{"name": "RLS ARMA order 4", "kind": "rls", "order": 4, "horizons": [1, 5]},
                    {"name": "sysid order 3", "kind": "recursive_arx", "order": 3}],
}
TIMING = ("lateness_s", "latency_s")


def spec(**mre):
    data = copy.deepcopy(BASE)
    data["mre"].update(mre)
    return validate_mre(data, "test.toml")


@pytest.fixture(scope="module")
def fast_run(tmp_path_factory):
    """A 0.3 s run with its report (seconds to draw): the tests that read it are in the slow tier."""
    return run_mre(spec(), tmp_path_factory.mktemp("fast"), mode="fast")


def _same_except_timing(a, b, n=None):
    ca, cb = a.columns(), b.columns()
    assert ca.keys() == cb.keys()
    for name in ca:
        if name not in TIMING:
            np.testing.assert_array_equal(ca[name][:n], cb[name][:n], err_msg=name)


@pytest.mark.slow
def test_paced_and_fast_loops_give_the_same_recording_and_model(fast_run, tmp_path):
    live = run_mre(spec(), tmp_path, mode="realtime", report=False)
    assert live.summary["stop_reason"] == fast_run.summary["stop_reason"] == "completed"
    fast_rec, live_rec = read_recording(fast_run.recording_path), read_recording(live.recording_path)
    assert live_rec.n_samples == fast_rec.n_samples == 300
    _same_except_timing(fast_rec, live_rec)
    assert np.isfinite(live_rec.extra["lateness_s"]).all() and np.isnan(fast_rec.extra["lateness_s"]).all()
    # the order-4 model identified live is the offline one, to every printed digit
    for name in ("RLS ARMA order 4", "sysid order 3"):
        f, lv = fast_run.summary["identified"][name], live.summary["identified"][name]
        assert f["transfer_function"] == lv["transfer_function"]
        assert f["theta"] == lv["theta"]


@pytest.mark.slow
def test_report_prints_the_identified_transfer_functions_and_timing(fast_run):
    text = (fast_run.out_dir / "report.md").read_text(encoding="utf-8")
    tf = fast_run.summary["identified"]["RLS ARMA order 4"]["transfer_function"]
    assert tf.startswith("G(z) = (") and " z^4 " in tf and tf in text
    assert "yhat_rls_arma_order_4_h5_cm" in text and "computation per sample" in text
    for fig in ("response.png", "predictions.png", "coefficients.png", "timing.png"):
        assert (fast_run.out_dir / fig).stat().st_size > 1000
    theta = np.load(fast_run.out_dir / "coefficients.npz")["theta_rls_arma_order_4"]
    assert theta.shape == (300, 8)
    np.testing.assert_array_equal(theta[-1], fast_run.summary["identified"]["RLS ARMA order 4"]["theta"])


@pytest.mark.slow
def test_report_page_is_self_contained_and_says_what_report_md_says(fast_run):
    """index.html is the same page as report.md (one list of blocks, two renderings), every figure inlined."""
    page = (fast_run.out_dir / "index.html").read_text(encoding="utf-8")
    text = (fast_run.out_dir / "report.md").read_text(encoding="utf-8")
    figures = ("response.png", "predictions.png", "coefficients.png", "timing.png")
    assert page.startswith("<!DOCTYPE html>") and page.count("data:image/png;base64,") == len(figures)
    assert "src=\"response.png\"" not in page and "<table>" in page
    for fig in figures:
        assert f"]({fig})" in text
    tf = fast_run.summary["identified"]["RLS ARMA order 4"]["transfer_function"]
    for line in (tf, "computation per sample", "yhat_rls_arma_order_4_h5_cm", "MRE run: t"):
        assert line in text and html.escape(line) in page, line


class _Interrupting:
    """A simulated plant that records what the loop sends it and raises at one measurement."""

    def __init__(self, plant, at, exc):
        self.plant, self.at, self.exc = plant, at, exc
        self.sample_time_s = plant.sample_time_s
        self.calls = 0
        self.nulls = []

    def reset(self, *a, **k):
        self.plant.reset(*a, **k)

    def measure(self):
        self.calls += 1
        if self.calls == self.at:
            raise self.exc
        return self.plant.measure()

    def step(self, u):
        self.plant.step(u)

    def safe_stop(self, null_V):
        self.nulls.append(null_V)


@pytest.mark.slow
@pytest.mark.parametrize("exc", [KeyboardInterrupt(), RuntimeError("sensor cable pulled")])
def test_ctrl_c_or_a_fault_leaves_a_complete_valid_recording(fast_run, tmp_path, exc):
    s = spec()
    comp = build_components(s)
    warm = comp.n_warm
    plant = _Interrupting(SimulatedPlant(comp.rig, seed=3), warm + 121, exc)
    run = run_mre(s, tmp_path, mode="fast", plant_object=plant, report=False)
    assert plant.nulls == [5.0]                       # valve to its null
    rec = read_recording(tmp_path / "recording.csv")   # what pneusim check reads
    assert rec.n_samples == 120 == run.summary["samples"]
    _same_except_timing(read_recording(fast_run.recording_path).slice(None, 0.1195), rec)
    expected = "interrupted (Ctrl-C)" if isinstance(exc, KeyboardInterrupt) else "fault"
    assert run.summary["stop_reason"] == expected
    if expected == "fault":
        assert "sensor cable pulled" in run.summary["error"]
    assert main(["check", str(tmp_path / "recording.csv")]) == 0


def test_cli_fault_is_one_line_and_the_recording_stays(tmp_path, capsys):
    path = tmp_path / "m.toml"
    path.write_text(MRE_TEXT, encoding="utf-8")
    args = build_parser().parse_args(["mre", str(path), "--fast", "--out", str(tmp_path / "o"), "--no-report"])
    args.func = functools.partial(mre_command.run, run_mre=functools.partial(run_mre, stop_after=60))
    assert run_command(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "60 samples taken" in err
    assert read_recording(tmp_path / "o" / "recording.csv").n_samples == 60


@pytest.mark.slow
def test_replay_plays_the_recording_back_open_loop(fast_run, tmp_path):
    s = spec(warmup_s=0.0, duration_s=0.2)
    s["controller"]["kp_V_per_m"] = 80.0               # other commands than the recording's
    run = run_mre(s, tmp_path, plant=f"replay:{fast_run.recording_path}", mode="fast", report=False)
    src, rec = read_recording(fast_run.recording_path), read_recording(run.recording_path)
    np.testing.assert_array_equal(rec.position_m, src.position_m[:200])      # measurements played back
    assert not np.allclose(rec.valve_cmd_V, src.valve_cmd_V[:200])           # the loop's own commands
    assert "open loop" in rec.metadata["mre_plant_note"]
    assert run.summary["plant_counts"]["commands_logged"] == 199


def test_pid_without_integral_and_derivative_is_the_proportional_law():
    rng = np.random.default_rng(0)
    p, pid = ProportionalController(40.0, 5.0, 0.0, 10.0), PIDController(40.0, sample_time_s=0.001)
    for r, y in rng.uniform(0, 0.1, (200, 2)):
        assert pid.command(0.0, r, y) == p.command(0.0, r, y)


def test_pid_anti_windup_leaves_saturation_at_once():
    """A long saturated stretch must not wind the integrator up: once the error changes sign the
    command leaves the limit at the next sample (a plain integrator would stay saturated for seconds)."""
    pid = PIDController(40.0, ki_V_per_m_s=200.0, sample_time_s=0.001)
    out = [pid.command(0.0, 0.09, 0.0) for _ in range(5000)]    # 5 s far below the reference
    assert out[0] == pytest.approx(5.0 + 40.0 * 0.09) and out[-1] == 10.0
    integral = pid.integral_V
    # frozen once the output hit the limit: 1.4 V, plus at most one step (a plain integrator: 90 V)
    assert 10.0 - 8.6 <= integral <= 10.0 - 8.6 + 200.0 * 0.001 * 0.09 + 1e-12
    u = pid.command(0.0, 0.05, 0.06)                    # overshoot by 1 cm
    assert u < 10.0
    assert u == pytest.approx(5.0 + 40.0 * -0.01 + integral)


MRE_TEXT = mre_text(duration_s=0.2, seed=None)


@pytest.mark.parametrize("edit, field", [
    (("[controller]", "[controler]"), "controler"),
    (('kind = "proportional"', 'kind = "pi"'), "controller.kind"),
    (("order = 3", "order = 0"), "identifiers[0].order"),
    (("duration_s = 0.2", 'duration_s = "long"'), "mre.duration_s"),
    (("warmup_s = 0.0", 'warmup_s = 0.0\nplant = "serial:COM1"'), "mre.plant"),
    (("hold_s = [0.05, 0.1]", "hold_s = [0.1, 0.05]"), "reference.hold_s"),
])
def test_bad_mre_files_give_one_clear_line(tmp_path, capsys, edit, field):
    path = tmp_path / "bad.toml"
    path.write_text(MRE_TEXT.replace(*edit), encoding="utf-8")
    assert main(["mre", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert str(path) in err and field in err


@pytest.mark.parametrize("plant, words", [("udp:127.0.0.1:9", "no rig server"), ("tcp:1.2.3.4", "expected one of"),
                                          ("udp:localhost", "udp:HOST:PORT"), ("replay:nope.csv", "not found")])
def test_unreachable_or_unknown_plants_give_one_clear_line(tmp_path, capsys, plant, words):
    path = tmp_path / "m.toml"
    path.write_text(MRE_TEXT, encoding="utf-8")
    assert main(["mre", str(path), "--plant", plant, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err


def test_status_line_shows_samples_overruns_lateness_and_one_step_error():
    comp = build_components(spec(duration_s=0.1))
    plant = SimulatedPlant(comp.rig, seed=3)
    plant.reset(comp.x0_m, comp.u_init_V, t0_s=0.0)
    stream = io.StringIO()
    run_loop(plant, comp.reference, comp.controller, comp.estimators, comp.to_output, comp.to_input,
             pacing=RealtimePacing(0.001), status=StatusLine(stream, interval_s=0.0))
    text = stream.getvalue()
    assert "mre: 100/100 samples (100 %), overruns" in text and "lateness p50" in text
    assert "1-step error (RLS ARMA order 4)" in text


@pytest.mark.parametrize("edit, option, words", [
    (None, ["--duration", "1e12"], "at most 10000000"),
    (("warmup_s = 0.0", "warmup_s = 1e12"), [], "mre.warmup_s = 1e+12 s"),
])
def test_runs_longer_than_a_recording_holds_give_one_clear_line(tmp_path, capsys, edit, option, words):
    path = tmp_path / "m.toml"
    path.write_text(MRE_TEXT.replace(*edit) if edit else MRE_TEXT, encoding="utf-8")
    assert main(["mre", str(path), *option, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err
