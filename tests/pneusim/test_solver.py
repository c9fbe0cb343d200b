"""CVODE against an independent solver, solver failures, and the practice recordings re-run."""

import json

import numpy as np
import pytest

from pneusim.errors import SolverError
from pneusim.experiment import Experiment, standard_experiment
from pneusim.model import ActuatorModel, make_effect
from pneusim.model.effects import EFFECTS
from pneusim.recording import read_recording
from pneusim.rig import load_rig
from pneusim.simulate import rerun_recording, simulate
from pneusim.solver.backends import CvodeBackend, make_backend


def test_cvode_agrees_with_scipy_radau_at_tight_tolerance(rig2):
    """Paper-2 closed-loop multisine run: CVODE and Radau differ by < 1e-6 m in position."""
    exp = standard_experiment(rig2, "multisine", 6.0, "closed", seed=2)
    exp.signal = exp.signal[:400]
    cv = simulate(rig2, exp, noise_scale=0, rtol=1e-10)
    radau = simulate(rig2, exp, noise_scale=0, rtol=1e-10, backend="scipy-radau")
    assert np.ptp(cv.state("position_m")) > 0.05  # the run moves
    assert np.max(np.abs(cv.state("position_m") - radau.state("position_m"))) < 1e-6
    assert np.max(np.abs(cv.state("pressure_a_Pa") - radau.state("pressure_a_Pa"))) < 5.0


def test_cvode_converges_with_tolerance(rig1):
    # open loop: in closed loop the 16-bit converter in the loop turns tiny differences into
    # different commands, which is the rig's behaviour, not the solver's error
    exp = standard_experiment(rig1, "pulses", 1.0, "open", seed=5)
    ref = simulate(rig1, exp, noise_scale=0, rtol=1e-11).state("position_m")
    errors = [np.max(np.abs(simulate(rig1, exp, noise_scale=0, rtol=tol).state("position_m") - ref))
              for tol in (1e-5, 1e-7, 1e-9)]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 1e-7


def test_solver_failure_names_time_and_state(rig2):
    model = ActuatorModel()
    backend = CvodeBackend(model, model.param_vector(rig2), max_steps=3, stroke_m=rig2.stroke_m)
    backend.reset(0.0, model.initial_state(rig2, 0.1))
    with pytest.raises(SolverError, match=r"t = .* s .*position_m="):
        backend.advance(0.5, 9.0)


def test_unknown_backend_is_refused():
    with pytest.raises(ValueError, match="unknown solver backend"):
        make_backend("euler", ActuatorModel(), np.zeros(1))


def test_same_seed_same_recording(rig1):
    exp = standard_experiment(rig1, "steps", 1.0, "closed", seed=1)
    a = simulate(rig1, exp, seed=7).recording
    b = simulate(rig1, exp, seed=7).recording
    c = simulate(rig1, exp, seed=8).recording
    assert np.array_equal(a.position_m, b.position_m)
    assert not np.array_equal(a.position_m, c.position_m)


def _fit_percent(y, yhat):
    return 100 * (1 - np.linalg.norm(y - yhat) / np.linalg.norm(y - np.mean(y)))


def _effects_from_answer(entry):
    effects = []
    for e in entry["effects"]:
        cls = EFFECTS[e["effect"]]
        values = {k: v for k, v in e["parameters"].items() if k in cls.parameters or k in cls.options}
        effects.append(make_effect(e["effect"], **values))
    return effects


def test_practice_recordings_are_reproduced_by_the_model_with_their_effects(shared_dir):
    """An independent simulator made the practice set; with the answers' effects our model matches it.

    Closed-loop re-runs see different sensor noise in the loop, and open-loop
    recordings without pressures do not say the chambers' initial pressures, so
    the bar is set per case: 98.5 % (closed loop or with pressures) or 90 %.
    The effects must also explain what the nominal model cannot.
    """
    answers = json.loads((shared_dir / "practice" / "answers.json").read_text())["cases"]
    for name, entry in sorted(answers.items()):
        rec = read_recording(shared_dir / "practice" / name)
        rig = load_rig(rec.rig)
        rig = rig.with_params({k: v for k, v in entry["plant"].items() if k in rig.params
                               and not k.startswith("endstop")})
        effects = _effects_from_answer(entry)
        fit = _fit_percent(rec.position_m, rerun_recording(rig, rec, effects, noise_scale=0).recording.position_m)
        bar = 90.0 if (rec.loop == "open" and not rec.has_pressures) else 98.5
        assert fit > bar, f"{name}: fit {fit:.2f} % with {entry['effects']}"
        if effects and name in ("practice_06.csv", "practice_10.csv", "practice_17.csv", "practice_14.csv"):
            nominal = _fit_percent(rec.position_m, rerun_recording(rig, rec, [], noise_scale=0).recording.position_m)
            assert fit > nominal + 5.0
