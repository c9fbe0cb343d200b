# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 2. Online recursive least squares on a servo-pneumatic drive (paper 1)
#
# The mixed-reality paper (`shared/papers/mixed-reality-online-identification.md`) identified its rig *online*:
# at every 1 ms sample a recursive least-squares estimator (its eq. 8) updated an ARMA model of order 3, 4 or
# 5 while a controller drove the piston with impulse-like moves. This notebook runs that estimator **inside
# the simulation loop** and explores its three knobs:
#
# * the forgetting factor lambda (the paper: 0.95 < lambda < 0.99),
# * the initial covariance P(0) = c I (the paper: 100 < c < 10 000),
# * the model order n (3, 4, 5),
#
# and one trap: **covariance wind-up** while the piston rests.

# %%
import numpy as np

from pneusim.experiment import Experiment, default_controller, pulse_train
from pneusim.online import PaperRLS
from pneusim.plotting import COLOURS, Curve, colour_for, compare_figure, mark_clipped, new_figure, show_figure
from pneusim.rig import load_rig
from pneusim.scenario.online import simulate_online

rig = load_rig("paper1-mre")
ts = rig.sample_time_s          # 1 ms
rng = np.random.default_rng(1)

# %% [markdown]
# ## One closed-loop run, many estimators in the loop
# Reference pulses of 1-4 cm from a rest at 0.5 cm (as `scenarios/paper1-online-rls.toml`), 4 s. Every
# estimator sees exactly the data the loop produces: it predicts y(k) from theta(k-1), takes the
# measurement, updates; then the controller acts. y in cm, u = valve command in V.

# %%
n = int(4.0 / ts)
ref = pulse_train(n, ts, 0.005, (0.01, 0.04), (0.1, 0.4), (0.4, 1.2), rng)
ref = 0.005 + np.abs(ref - 0.005)                 # positive pulses only (m)
exp = Experiment("closed", ts, ref, default_controller(rig, 40.0))
estimators = {f"order {k}": PaperRLS(k, 0.99, 1000.0) for k in (3, 4, 5)}
estimators.update({f"order 4, lambda {lam}": PaperRLS(4, lam, 1000.0) for lam in (0.95, 0.98, 0.999)})
estimators.update({f"order 4, c {c:g}": PaperRLS(4, 0.99, c) for c in (1.0, 1e5)})
res = simulate_online(rig, exp, estimators, lambda p: 100.0 * p, lambda u, k: u, seed=1)
y = 100.0 * res.recording.position_m
t = res.recording.time_s


def square_error(name, skip=200):
    """Mean one-step squared error (cm^2) after the first 0.2 s of convergence."""
    e = y[skip:] - res.predictions[(name, 1)][skip:]
    return float(np.nanmean(e ** 2))


for name in estimators:
    print(f"{name:22s} one-step square error {square_error(name):.3g} cm^2")
print("paper, Table 1: order 3: 7.09e-5, order 4: 3.22e-5, order 5: 3.397e-5")

# %%
curves = [Curve(f"order {k}, one step ahead", res.predictions[(f"order {k}", 1)], None, "rls") for k in (3, 4, 5)]
fig, axes = compare_figure(t, y, curves, ylabel="position (cm)", unit="cm",
                           title="One-step predictions of orders 3, 4 and 5 follow the position; their errors differ "
                                 "only where a pulse starts or ends")
axes["error"].set_ylim(-0.05, 0.05)
show_figure(fig)

# %% [markdown]
# **Orders.** One step ahead at 1 ms the position barely moves between samples, so every order predicts well;
# differences come from how fast each estimator re-adapts after a pulse starts (compare the numbers above with
# the paper's Table 1). **Forgetting factor.** A smaller lambda forgets faster: it could follow changing
# dynamics, but during the rests between pulses it also forgets what it knew and its covariance grows (see
# wind-up below): look at what lambda = 0.95 and 0.98 do to the one-step error above. **Initial
# covariance.** c sets how far theta may jump at first: with c = 1 the estimator crawls for a while; with
# c = 1e5 it jumps at once; after a second both have converged.
#
# Theta of the order-4 estimator over time (a1..a4, b1..b4):

# %%
th = res.thetas["order 4"]
fig, ax = new_figure(title="theta(k) of the order-4 estimator (lambda 0.99): a (solid) and b (dashed) jump when a "
                           "pulse starts and drift while the piston rests", size=(9, 3.2))
for i in range(4):
    ax.plot(t, th[:, i], lw=0.8, color=f"C{i}", label=f"a{i + 1}")
    ax.plot(t, th[:, 4 + i], lw=0.8, ls="--", color=f"C{i}", label=f"b{i + 1}")
ax.set_xlabel("time (s)")
ax.set_ylabel("coefficient (-)")
ax.legend(fontsize=7, ncol=2)
show_figure(fig)

# %% [markdown]
# ## Covariance wind-up at rest
# Let the piston rest at the retracted end for seconds between pulses (what Table 1's min = 0 suggests the
# paper did). At rest the regressor carries almost nothing new, and eq. 8 divides P by lambda at every sample:
# trace(P) grows like lambda^-k. The next pulse then meets a huge gain and theta jumps.

# %%
n2 = int(6.0 / ts)
ref2 = np.abs(pulse_train(n2, ts, 0.0, (0.02, 0.05), (0.05, 0.2), (2.0, 3.0), np.random.default_rng(3)))
exp2 = Experiment("closed", ts, ref2, default_controller(rig, 40.0), initial_position_m=0.0)
lambdas = (0.99, 0.999)
res2 = simulate_online(rig, exp2, {f"lambda {lam}": PaperRLS(4, lam, 1000.0) for lam in lambdas},
                       lambda p: 100.0 * p, lambda u, k: u, seed=2)
y2, u2 = 100.0 * res2.recording.position_m, res2.recording.valve_cmd_V


def trace_of_P(lam, y, u):
    """Replay the same data (y, u) through a fresh estimator of forgetting factor lam: trace(P) at every sample."""
    est, tr = PaperRLS(4, lam, 1000.0), np.empty(len(y))
    for k in range(len(y)):
        est.update(y[k])
        est.add_input(u[k])
        tr[k] = np.trace(est.P)
    return tr


traces = {lam: trace_of_P(lam, y2, u2) for lam in lambdas}
t2 = res2.recording.time_s
fig, ax = new_figure(2, 1, title="Covariance wind-up: while the piston rests, trace(P) grows as lambda^-k, far faster "
                                 "for lambda 0.99 than 0.999", size=(9, 4.6), sharex=True)
ax[0].plot(t2, y2, color=COLOURS["measured"], lw=1)
ax[0].set_ylabel("position (cm)")
for lam, shade in zip(lambdas, ("#31A354", "#006D2C")):
    ax[1].semilogy(t2, traces[lam], color=shade, ls="-" if lam == lambdas[0] else "--", label=f"lambda {lam}")
ax[1].set_ylabel("trace of P (-)")
ax[1].set_xlabel("time (s)")
ax[1].legend(fontsize=8)
show_figure(fig)
growth_at = {lam: traces[lam].max() / traces[lam][200] for lam in lambdas}
print({lam: f"trace(P) grows x{g:.3g} after the first 0.2 s" for lam, g in growth_at.items()})

# %% [markdown]
# ## The forgetting factor's trade-off
# Sweep lambda over the paper's range and beyond, on both experiments: the one-step error on the first (pulses
# with short rests) and the covariance's growth at rest on the second (long rests). Too little memory (small
# lambda) winds the covariance up during the rests until the estimator blows up at the next pulse; too much
# memory (lambda near 1) adapts slowly within a pulse. Here the best one-step error lies between 0.99 and 0.999,
# just above the paper's range: the paper's rig rested for shorter times, or its lambda would have blown up too.

# %%
sweep = (0.95, 0.97, 0.98, 0.99, 0.993, 0.995, 0.997, 0.999, 0.9995)
res_l = simulate_online(rig, exp, {lam: PaperRLS(4, lam, 1000.0) for lam in sweep}, lambda p: 100.0 * p,
                        lambda u, k: u, seed=1)
error = {lam: float(np.nanmean((y[200:] - res_l.predictions[(lam, 1)][200:]) ** 2)) for lam in sweep}
windup = {}
for lam in sweep:
    tr = trace_of_P(lam, y2, u2)
    windup[lam] = float(np.nanmax(tr) / tr[200]) if np.isfinite(tr).all() else np.inf
memory = np.array([1.0 / (1.0 - lam) for lam in sweep])        # samples the estimator remembers
best = min(error, key=error.get)
fig, ax = new_figure(2, 1, title="The forgetting factor's trade-off: short memory winds the covariance up at rest "
                                 f"and the error explodes, long memory adapts slowly; best here lambda = {best}",
                     size=(9, 5.4), sharex=True)
colour = colour_for("order 4", "rls")
err = np.array([error[lam] for lam in sweep])
shown = np.isfinite(err) & (err < 1e-3)
ax[0].loglog(memory[shown], err[shown], "o-", color=colour, label="one-step square error (order 4)")
low, high = 0.8 * err[shown].min(), 1e-3
ax[0].set_ylim(low, high)
mark_clipped(ax[0], memory, np.where(np.isfinite(err), err, 1e300), low, high, colour)
ax[0].axvspan(1 / (1 - 0.95), 1 / (1 - 0.99), color=COLOURS["window"], alpha=0.5, lw=0)
ax[0].set_ylabel("one-step square error (cm^2)")
ax[0].set_title("pulses with short rests (open triangles: off the scale, the estimator blew up); shaded: the "
                "paper's 0.95 < lambda < 0.99", fontsize=8)
ax[0].legend(fontsize=8)
growth = np.array([windup[lam] for lam in sweep])
ax[1].loglog(memory[np.isfinite(growth)], growth[np.isfinite(growth)], "s-", color=COLOURS["command"],
             label="growth of trace(P) at rest")
ax[1].set_ylabel("trace(P) growth (x)")
ax[1].set_xlabel("memory 1 / (1 - lambda) (samples)")
ax[1].legend(fontsize=8)
for lam, m in zip(sweep, memory):
    ax[1].annotate(f"{lam:g}", (m, growth[list(sweep).index(lam)] if np.isfinite(windup[lam]) else 1.0),
                   textcoords="offset points", xytext=(0, 6), fontsize=6, ha="center")
show_figure(fig)
print(f"best lambda {best}: one-step square error {error[best]:.3g} cm^2; "
      + ", ".join(f"lambda {lam}: {error[lam]:.3g}" for lam in sweep))

# %% [markdown]
# Remedies used in practice: a forgetting factor closer to 1, a dead zone on the update (update only when the
# prediction error exceeds the noise level), or constant-trace / directional forgetting. Try `lambdas`, the
# rest times of `ref2`, or adding such a dead zone to a copy of `PaperRLS.update`.
#
# The paper-scale study of order and forgetting is `pneusim sweep scenarios/sweep-paper1-rls.toml`; which
# physics makes the orders differ is in `scenarios/ablation-paper1.toml`.

# %%
assert growth_at[0.99] > 10 * growth_at[0.999], "smaller forgetting factors wind the covariance up faster at rest"
assert error[0.995] < error[0.98] and error[0.995] < error[0.9995], "the best forgetting factor lies in between"
