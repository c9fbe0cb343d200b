# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
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
import matplotlib.pyplot as plt
import numpy as np

from pneusim.experiment import Experiment, default_controller, pulse_train
from pneusim.rig import load_rig
from pneusim.online import PaperRLS
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
fig, ax = plt.subplots(2, 1, sharex=True, figsize=(8, 4))
ax[0].plot(t, y, "k", lw=1, label="position (cm)")
ax[0].plot(t, res.predictions[("order 4", 1)], lw=0.7, ls="--", label="order 4, one step ahead")
ax[0].legend(fontsize=8)
for k in (3, 4, 5):
    ax[1].plot(t, y - res.predictions[(f"order {k}", 1)], lw=0.6, label=f"order {k}")
ax[1].set_ylim(-0.05, 0.05)
ax[1].set_ylabel("error (cm)")
ax[1].set_xlabel("time (s)")
ax[1].legend(fontsize=8)
plt.show()

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
fig, ax = plt.subplots(figsize=(8, 2.6))
ax.plot(t, th, lw=0.7)
ax.set_xlabel("time (s)")
ax.set_title("theta(k), order 4, lambda 0.99", fontsize=9)
plt.show()

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
# replay the same data through fresh estimators to record trace(P) at every sample
traces = {}
for lam in lambdas:
    est, tr = PaperRLS(4, lam, 1000.0), np.empty(n2)
    for k in range(n2):
        est.update(y2[k])
        est.add_input(u2[k])
        tr[k] = np.trace(est.P)
    traces[lam] = tr
t2 = res2.recording.time_s
fig, ax = plt.subplots(2, 1, sharex=True, figsize=(8, 4))
ax[0].plot(t2, y2, "k", lw=1)
ax[0].set_ylabel("position (cm)")
for lam in lambdas:
    ax[1].semilogy(t2, traces[lam], label=f"lambda {lam}")
ax[1].set_ylabel("trace P")
ax[1].set_xlabel("time (s)")
ax[1].legend(fontsize=8)
plt.show()
growth = {lam: traces[lam].max() / traces[lam][200] for lam in lambdas}
print({lam: f"trace(P) grows x{g:.3g} after the first 0.2 s" for lam, g in growth.items()})

# %% [markdown]
# Remedies used in practice: a forgetting factor closer to 1, a dead zone on the update (update only when the
# prediction error exceeds the noise level), or constant-trace / directional forgetting. Try `lambdas`, the
# rest times of `ref2`, or adding such a dead zone to a copy of `PaperRLS.update`.
#
# The paper-scale study of order and forgetting is `pneusim sweep scenarios/sweep-paper1-rls.toml`; which
# physics makes the orders differ is in `scenarios/ablation-paper1.toml`.

# %%
assert growth[0.99] > 10 * growth[0.999], "smaller forgetting factors wind the covariance up faster at rest"
