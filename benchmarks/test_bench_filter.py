"""The tracking filter's pass: the compiled loop (:func:`pneusim.fit.tracking.run_filter`) against the same
extended Kalman filter written with NumPy's small matrices (the peer below, the filter as it was before it was
compiled), on the same integrator, both with the innovations' Jacobian.

The windows: the first 2000 samples of two robustness-set recordings at their true parameters, paper 2's
open-loop multisine with both pressures recorded (three measured values a sample) and paper 1's closed-loop
multisine without (one).  Each benchmark prints its median; the second of each pair the ratio measured in the
same run and the largest difference of the whitened innovations between the two.

    pytest benchmarks/test_bench_filter.py --benchmark-only -s

The rows are written to ``docs/results/filter.md`` (:mod:`results_file`).
"""

import numpy as np
import pytest

from pneusim.errors import PneusimError
from pneusim.fit.initial import initial_starts
from pneusim.fit.robustness import fit_free, make_case, robustness_cases
from pneusim.fit.setup import FitSetup
from pneusim.fit.shooting import expected_position_reading
from pneusim.fit.rules import PROCESS_SCHEDULE, UNMEASURED_FACTOR
from pneusim.fit.tracking import first_state_std, process_std, run_filter
from pneusim.solver.sensitivity import command_schedule
from results_file import write_results

CASES = {"paper2 open-loop multisine, pressures": 1006, "paper1 closed-loop multisine, position only": 1017}
RUNS = {}


def numpy_filter(pb, theta, x_first, process):
    """The peer: the same filter, sample by sample with NumPy's arrays and solvers (batch update in Joseph form)."""
    sim, data, n, nf = pb.sims[0], pb.data, pb.n, pb.n_free
    sim.set_params(pb.params_of(theta))
    rows = np.array([i for (i, _, _, _, _) in pb.outputs])
    values = np.column_stack([v for (_, _, v, _, _) in pb.outputs])
    sigma = np.array([s for (_, _, _, s, _) in pb.outputs])
    seen_at = np.column_stack([m for (_, _, _, _, m) in pb.outputs])
    x, P, Q = np.asarray(x_first, float).copy(), np.diag(first_state_std(pb) ** 2), np.diag(process ** 2)
    Z = np.zeros((n, nf + n))
    Z[:, nf:] = np.diag(pb.x_scale)
    x_lo, x_hi = pb.state_bounds()
    innovations = np.zeros((data.n_samples, rows.size))
    for k in range(data.n_samples):
        if k > 0:
            schedule = command_schedule(data.time_s, data.command_V, k - 1, k, pb.delay_s, data.command_before_V)
            try:
                xs, S = sim.run(data.time_s[k - 1], x, schedule, 2, True)
            except PneusimError:
                xs = None
            if xs is not None and np.all(np.isfinite(xs[1])):
                F = S[1][:, nf:] / pb.x_scale[None, :]
                x, P = xs[1], F @ P @ F.T + Q
                Z = F @ Z
                Z[:, :nf] += S[1][:, :nf]
        seen = seen_at[k]
        if not seen.any():
            x = np.clip(x, x_lo, x_hi)
            continue
        at = rows[seen]
        reading, slope = x[at].copy(), np.ones(at.size)
        p = np.flatnonzero(at == pb.position_index)
        if p.size:
            reading[p[0]], slope[p[0]] = expected_position_reading(x[pb.position_index], pb.stroke_m, sigma[seen][p[0]])
        PHT = P[:, at] * slope
        Sk = PHT[at] * slope[:, None] + np.diag(sigma[seen] ** 2)
        L = np.linalg.cholesky(Sk)
        K = np.linalg.solve(Sk, PHT.T).T
        y = values[k, seen] - reading
        I_KH = np.eye(n)
        I_KH[:, at] -= K * slope
        x = np.clip(x + K @ y, x_lo, x_hi)
        P = I_KH @ P @ I_KH.T + (K * sigma[seen] ** 2) @ K.T
        HZ = Z[at] * slope[:, None]
        Z = Z - K @ HZ
        innovations[k, seen] = np.linalg.solve(L, y)
        np.linalg.solve(L, HZ)                          # the Jacobian's rows, as the compiled pass computes them
    return innovations.ravel()


def _window(seed):
    spec = next(s for s in robustness_cases(48) if s.seed == seed)
    rig, truth, recording = make_case(spec)
    setup = FitSetup(recording, rig, (), fit_free(True), None, None, None, 50)
    pb, _, _ = setup.problem(2000, 1e-6, 1)
    theta = np.array([truth[name] for name in setup.free]) / setup.scales
    first = initial_starts(pb, theta, recording, 2000)[0]
    return pb, theta, first, process_std(pb, PROCESS_SCHEDULE[-1], UNMEASURED_FACTOR)   # the last stage's


@pytest.fixture(scope="module", autouse=True)
def results_table():
    yield
    if len(RUNS) < 2 * len(CASES):
        return
    lines = ["| window | compiled pass | NumPy peer | ratio | largest difference of a whitened innovation |",
             "|---|---|---|---|---|"]
    for name in CASES:
        (ours, mine), (peer, theirs) = RUNS[(name, "compiled")], RUNS[(name, "numpy")]
        lines.append(f"| {name} | {1e3 * ours:.0f} ms | {1e3 * peer:.0f} ms | {peer / ours:.2f}x | "
                     f"{np.max(np.abs(mine - theirs)):.2g} |")
    write_results("filter", "The tracking filter's pass over a 2000-sample window", "\n".join(lines) + "\n")


@pytest.mark.benchmark(group="filter")
@pytest.mark.parametrize("kind", ["numpy", "compiled"])
@pytest.mark.parametrize("name", list(CASES))
def test_filter_pass(benchmark, name, kind):
    pb, theta, first, process = _window(CASES[name])
    try:
        if kind == "compiled":
            out = benchmark.pedantic(lambda: run_filter(pb, theta, first, process, gradients=True)["innovations"],
                                     rounds=5, iterations=1, warmup_rounds=1)
        else:
            out = benchmark.pedantic(lambda: numpy_filter(pb, theta, first, process), rounds=5, iterations=1,
                                     warmup_rounds=1)
    finally:
        pb.close()
    RUNS[(name, kind)] = (benchmark.stats.stats.median, out)
    # at the true parameters the filter follows the recording: its whitened innovations are about 1
    assert 0.5 < np.sqrt(np.mean(out[out != 0] ** 2)) < 2.0
    if kind == "compiled" and (name, "numpy") in RUNS:
        peer, theirs = RUNS[(name, "numpy")]
        ours = benchmark.stats.stats.median
        print(f"\n{name}: compiled {1e3 * ours:.0f} ms, NumPy {1e3 * peer:.0f} ms -> {peer / ours:.2f}x; largest "
              f"difference of a whitened innovation {np.max(np.abs(out - theirs)):.2g}")
        # the same filter, summed in another order: on the position-only window to rounding; on the open-loop
        # stick-slip one a slip a sample early or late moves single innovations by a hundredth of the noise
        assert np.max(np.abs(out - theirs)) < 0.05
        assert np.sqrt(np.mean(out ** 2)) == pytest.approx(np.sqrt(np.mean(theirs ** 2)), rel=1e-3)
