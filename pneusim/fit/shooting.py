"""Multiple shooting of the one model over a recording window.

The window is cut into segments of about ``segment_s`` seconds.  Decision
variables, all of order one: the free parameters divided by their scales
(``theta``) and the state at the start of every segment divided by the state
scales.  Each segment is simulated from its start state with the recorded
command held between samples (and delayed when a transport delay is part of
the model); CVODES gives the samples and their sensitivities to ``theta`` and
to the start state.  Residuals: model minus measurement at every sample, each
signal divided by its noise standard deviation; constraints: continuity of the
state between consecutive segments.

Why the recorded command and not the controller: the valve saw exactly the
recorded command, so using it needs no model of the controller, and the
recorded command's reaction to sensor noise is then an input like any other.
Output error with white sensor noise stays unbiased in closed loop because the
residual at sample ``k`` is the sensor noise at ``k``, which the commands up to
``k - 1`` (all that the simulated sample depends on) cannot contain.  The
price: an integrating plant driven open loop drifts, which the free segment
start states absorb (and the continuity constraints remove at the optimum).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.special import ndtr

from ..errors import SolverError
from ..model import ActuatorModel
from ..solver.backends import state_scales
from ..solver import work as model_work
from ..solver.sensitivity import SensitivitySimulator, command_schedule
from . import deadline

__all__ = ["FitData", "ShootingProblem", "variable_scales", "position_reading", "expected_position_reading"]

#: typical magnitude of each state as a decision variable (segment start states are divided by it)
_VARIABLE_SCALE = {"velocity_m_per_s": 0.1, "pressure_a_Pa": 1e5, "pressure_b_Pa": 1e5, "spool_opening": 1.0,
                   "spool_rate_per_s": 100.0, "temperature_a_K": 300.0, "temperature_b_K": 300.0,
                   "supply_pressure_Pa": 1e5}


def variable_scales(model: ActuatorModel, stroke_m: float) -> np.ndarray:
    """Scales of the segment start states: the stroke for position, typical magnitudes otherwise."""
    return np.array([stroke_m if s == "position_m" else _VARIABLE_SCALE.get(s, 1.0) for s in model.state_names])


def position_reading(position_m: np.ndarray, stroke_m: float) -> np.ndarray:
    """What the position sensor reads of the model's piston position, noise aside: the position within
    the sensor's range ``0 .. stroke`` (for plots and the validation fit)."""
    return np.clip(position_m, 0.0, stroke_m)


def expected_position_reading(position_m: np.ndarray, stroke_m: float, noise_std_m: float):
    """``(E[y], dE[y]/dx)``: the mean reading ``y = min(max(x + n, 0), stroke)`` of a sensor whose
    range ends at ``0`` and at the stroke, for the model position ``x`` and Gaussian noise ``n`` of
    std ``noise_std_m`` (the censored normal's mean), and its slope.

    Why: pressed against a stop the model's piston goes a little past it (the stop is a stiff spring:
    0.08 mm on paper 2, more than the 0.06 mm noise), while the sensor saturates at the stroke (the
    converter of :mod:`pneusim.sensors`, as a real transducer).  Compared with ``x`` itself every
    sample at a stop left a residual of -1.4 times the noise on average (paper 2, open-loop steps,
    a fifth of the samples at the stop: 1.14 times noise at the true parameters).  Clipping ``x``
    to the range instead zeroes the residual and its slope past the stop, which leaves the segment
    states there free and sent a recording with pressures from 1.05 to 1.9 and 8 times noise.  The
    mean reading is smooth and within one noise std of ``x`` everywhere else."""
    x = np.asarray(position_m, float)
    s = float(noise_std_m)
    if s <= 0:
        return position_reading(x, stroke_m), ((x > 0.0) & (x < stroke_m)).astype(float)
    z_high, z_low = (x - stroke_m) / s, -x / s
    # E[max(X - c, 0)] = s g((x - c)/s) with g(z) = z Phi(z) + phi(z), g' = Phi
    g = lambda z: z * ndtr(z) + np.exp(-0.5 * z * z) / np.sqrt(2.0 * np.pi)
    return x - s * g(z_high) + s * g(z_low), 1.0 - ndtr(z_high) - ndtr(z_low)


def _csr_pattern(rows: np.ndarray, cols: np.ndarray, shape):
    """``data -> scipy CSR matrix`` with the nonzeros ``data`` at ``(rows, cols)`` (no two alike): SciPy's
    conversion from coordinates done once, its order of the entries kept and applied to each ``data``."""
    order = sparse.csr_matrix((np.arange(1.0, rows.size + 1.0), (rows, cols)), shape=shape)
    order.sort_indices()
    if order.nnz != rows.size:
        raise ValueError("a Jacobian pattern lists an entry twice")
    take = order.data.astype(np.intp) - 1
    indices, indptr = order.indices.copy(), order.indptr.copy()

    def build(data):
        return sparse.csr_matrix((np.asarray(data, float)[take], indices.copy(), indptr.copy()), shape=shape)
    return build


@dataclass
class FitData:
    """What the fit sees of a recording window (SI units).

    Attributes
    ----------
    time_s : ndarray (N,)
    command_V : ndarray (N,)
        Command sent at each sample, held until the next.
    command_before_V : float
        Command the valve saw before ``time_s[0]`` (matters with a transport delay).
    signals : dict
        ``{state name: (measured values (N,), noise std)}``; NaN marks a gap.
    """

    time_s: np.ndarray
    command_V: np.ndarray
    command_before_V: float
    signals: dict

    @property
    def n_samples(self) -> int:
        return int(self.time_s.size)


class ShootingProblem:
    """Residuals, continuity defects and their exact Jacobians for one window.

    Parameters
    ----------
    model : ActuatorModel
    params : ndarray (n_params,)
        Full parameter vector (SI); the free entries are replaced by ``theta * scales``.
    free : list of str
    scales : ndarray (n_free,)
    data : FitData
    stroke_m : float
    segment_samples : int
        Samples per shooting segment.
    delay_s : float
        Transport delay between command and valve (fixed).
    rtol : float
        CVODES relative tolerance.
    threads : int
        Segments are integrated in this many threads (CVODES runs without the GIL).
    """

    def __init__(self, model: ActuatorModel, params, free, scales, data: FitData, stroke_m: float,
                 segment_samples: int, delay_s: float = 0.0, rtol: float = 1e-6, threads: int = 2):
        self.model, self.free, self.data = model, list(free), data
        self.stroke_m = float(stroke_m)
        self.delay_s = float(delay_s)
        self.position_index = model.state_names.index("position_m")
        self.params = np.asarray(params, float).copy()
        self.scales = np.asarray(scales, float)
        self.index = np.array([model.param_names.index(name) for name in self.free], dtype=int)
        self.n = n = len(model.state_names)
        self.n_free = nf = len(self.free)
        N = data.n_samples
        L = max(2, int(segment_samples))
        starts = list(range(0, N - 1, L))
        if len(starts) > 1 and N - 1 - starts[-1] < L // 2:
            starts.pop()  # fold a short tail into the last segment
        self.starts = np.array(starts, dtype=int)
        self.stops = np.append(self.starts[1:], N - 1)
        self.n_segments = S = len(starts)
        self.n_v = nf + S * n
        self.schedules = [command_schedule(data.time_s, data.command_V, a, b, delay_s, data.command_before_V)
                          for a, b in zip(self.starts, self.stops)]
        self.x_scale = variable_scales(model, stroke_m)
        # defects are measured in the integrator's tolerance units, so that "continuous to within the
        # integration error" is one tolerance for every state
        self.g_scale = state_scales(model, stroke_m)
        self.sims = [SensitivitySimulator(model, self.free, self.params, self.scales, stroke_m, rtol, self.x_scale)
                     for _ in range(max(1, threads))]
        self._pool = ThreadPoolExecutor(len(self.sims)) if len(self.sims) > 1 else None
        # measured signals: state index, values, noise std, sample mask
        self.outputs = []
        for name, (values, sigma) in data.signals.items():
            values = np.asarray(values, float)
            self.outputs.append((model.state_names.index(name), name, values, float(sigma),
                                 np.isfinite(values)))
        self._build_patterns()
        self._cache_key = None

    # ----------------------------------------------------------------- layout
    def samples_of(self, j: int) -> np.ndarray:
        """Samples whose residuals segment ``j`` gives (its start up to the next start; the last also its end)."""
        stop = self.stops[j] + (1 if j == self.n_segments - 1 else 0)
        return np.arange(self.starts[j], stop)

    def _build_patterns(self):
        """Row order of the residuals and the sparsity of their Jacobian."""
        nf, n = self.n_free, self.n
        rows, self.row_blocks = 0, []
        for j in range(self.n_segments):
            ks = self.samples_of(j)
            blocks = []
            for (i, name, values, sigma, mask) in self.outputs:
                keep = ks[mask[ks]]
                blocks.append((i, keep, rows))
                rows += keep.size
            self.row_blocks.append(blocks)
        self.n_residuals = rows
        cols_r = []
        for j, blocks in enumerate(self.row_blocks):
            for (_, keep, r0) in blocks:
                r = np.arange(r0, r0 + keep.size)
                cols = np.concatenate([np.arange(nf), nf + j * n + np.arange(n)])
                cols_r.append((np.repeat(r, cols.size), np.tile(cols, r.size)))
        self.jr_rows = np.concatenate([c[0] for c in cols_r]) if cols_r else np.zeros(0, int)
        self.jr_cols = np.concatenate([c[1] for c in cols_r]) if cols_r else np.zeros(0, int)
        self.n_constraints = n * (self.n_segments - 1)
        g_rows, g_cols = [], []
        for j in range(self.n_segments - 1):
            r = j * n + np.arange(n)
            cols = np.concatenate([np.arange(nf), nf + j * n + np.arange(n)])
            g_rows.append(np.repeat(r, cols.size)); g_cols.append(np.tile(cols, n))
            g_rows.append(r); g_cols.append(nf + (j + 1) * n + np.arange(n))
        self.jg_rows = np.concatenate(g_rows) if g_rows else np.zeros(0, int)
        self.jg_cols = np.concatenate(g_cols) if g_cols else np.zeros(0, int)
        # the same rows gathered per output, for evaluate's whole-window arithmetic: where each residual's
        # sample sits in the segments' outputs stacked one after another, and where the segment ends are
        lengths = self.stops - self.starts + 1
        first_row = np.concatenate([[0], np.cumsum(lengths)[:-1]])
        self._gather = []
        for o, (i, name, values, sigma, mask) in enumerate(self.outputs):
            blocks = [self.row_blocks[j][o] for j in range(self.n_segments)]
            at = np.concatenate([first_row[j] + keep - self.starts[j] for j, (_, keep, _) in enumerate(blocks)])
            rows = np.concatenate([np.arange(r0, r0 + keep.size) for (_, keep, r0) in blocks])
            kept = np.concatenate([values[keep] for (_, keep, _) in blocks])
            self._gather.append((i, at.astype(np.intp), rows.astype(np.intp), kept, sigma))
        self._ends = (first_row + lengths - 1)[:-1]
        # CSR structure of the two Jacobians (jacobians() fills it with each evaluation's nonzeros)
        self._csr_r = _csr_pattern(self.jr_rows, self.jr_cols, (self.n_residuals, self.n_v))
        self._csr_g = _csr_pattern(self.jg_rows, self.jg_cols, (self.n_constraints, self.n_v))

    # -------------------------------------------------------------- variables
    def params_of(self, theta: np.ndarray) -> np.ndarray:
        p = self.params.copy()
        p[self.index] = np.asarray(theta, float) * self.scales
        return p

    def split(self, v: np.ndarray):
        v = np.asarray(v, float)
        return v[:self.n_free], v[self.n_free:].reshape(self.n_segments, self.n) * self.x_scale

    def state_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Physical bounds of a state (SI): position within the stroke and beyond it into a stop by at
        most five times what the full supply force compresses the stop, speeds below 10 m/s,
        absolute pressures between 10 % of atmosphere and 1.5 times supply.

        Why so tight into the stops: the sensor reads no further than the stroke
        (:func:`expected_position_reading`), so a segment starting at a stop is held there by
        physics alone; with 5 % of the stroke allowed (15 mm on paper 2), nearly independent
        segments of the pre-fit's continuation route started deep in the stop and the fit of a
        recording with pressures ended at 5.5 times noise instead of 1.0."""
        p = dict(zip(self.model.param_names, self.params))
        lower = np.full(self.n, -np.inf)
        upper = np.full(self.n, np.inf)
        bore_area_m2 = 0.25 * np.pi * p["bore_m"] ** 2
        into_stop_m = 5.0 * p["supply_Pa"] * bore_area_m2 / p["endstop_stiffness_N_per_m"]
        bounds = {"position_m": (-into_stop_m, p["stroke_m"] + into_stop_m), "velocity_m_per_s": (-10.0, 10.0)}
        for name in ("pressure_a_Pa", "pressure_b_Pa", "supply_pressure_Pa"):
            bounds[name] = (0.1 * p["atmosphere_Pa"], 1.5 * max(p["supply_Pa"], p.get("supply_pressure_droop.regulator_Pa", 0.0)))
        for i, name in enumerate(self.model.state_names):
            if name in bounds:
                lower[i], upper[i] = bounds[name]
        return lower, upper

    def join(self, theta: np.ndarray, starts: np.ndarray) -> np.ndarray:
        return np.concatenate([np.asarray(theta, float), (np.asarray(starts, float) / self.x_scale).ravel()])

    # ------------------------------------------------------------- evaluation
    def map_sims(self, work, items) -> list:
        """``[work(sim, item) for item in items]``, the items dealt in turn to the problem's simulators,
        each simulator working through its share in its own thread (CVODES runs without the GIL).
        ``work`` must use only the simulator it is given."""
        items = list(items)
        k = len(self.sims)
        ledger = model_work.current()   # every part finishes: the caller's count, whichever thread integrates

        def share(worker):
            with model_work.on(ledger):
                return [work(self.sims[worker], item) for item in items[worker::k]]

        parts = [share(0)] if self._pool is None else list(self._pool.map(share, range(k)))
        out = [None] * len(items)
        for worker, part in enumerate(parts):
            out[worker::k] = part
        return out

    def simulate_segments(self, v: np.ndarray, sensitivities: bool):
        """Per segment ``(x (L+1, n), S (L+1, n, ns) or None)``; ``None`` for a segment whose integration failed."""
        theta, starts = self.split(v)
        p = self.params_of(theta)
        for sim in self.sims:
            sim.set_params(p)

        def work(sim, j):
            deadline.check(backstop_only=True)   # a long evaluation stops between its segments too
            n_out = self.stops[j] - self.starts[j] + 1
            try:
                return sim.run(self.data.time_s[self.starts[j]], starts[j], self.schedules[j], n_out, sensitivities)
            except SolverError:
                return None

        return self.map_sims(work, range(self.n_segments))

    def evaluate(self, v: np.ndarray, derivatives: bool = True) -> dict:
        """Residuals ``r``, defects ``g`` and (with ``derivatives``) the nonzeros of their Jacobians.

        A failed integration gives NaN residuals (the optimiser then shortens its step).
        Results are cached for the last ``v``.
        """
        deadline.check()   # a caller's processor-time deadline ends the fit here, whatever route it is in
        v = np.asarray(v, float)
        key = (v.tobytes(), derivatives)
        if self._cache_key is not None and self._cache_key[0] == key[0] and (self._cache_key[1] or not derivatives):
            return self._cache
        n, ns = self.n, self.n_free + self.n
        segs = self.simulate_segments(v, derivatives)
        r = np.empty(self.n_residuals)
        g = np.empty(self.n_constraints)
        ok = all(s is not None for s in segs)
        out = {"r": r, "g": g, "ok": ok, "segments": segs}
        if not ok:
            r[:] = np.nan
            g[:] = np.nan
        else:
            # the whole window at once (the segments' outputs stacked): each element sees the arithmetic
            # a segment at a time did, in fewer numpy calls (a Python loop over segments and outputs took
            # 4.7 ms of the paper-2 pre-fit window's 50 ms evaluation)
            x = np.concatenate([seg[0] for seg in segs])
            S = np.concatenate([seg[1] for seg in segs]) if derivatives else None
            jr = np.empty((self.n_residuals, ns)) if derivatives else None
            for i, at, rows, kept, sigma in self._gather:
                model_out, slope = x[at, i], None
                if i == self.position_index:
                    model_out, slope = expected_position_reading(model_out, self.stroke_m, sigma)
                r[rows] = (model_out - kept) / sigma
                if derivatives:
                    d = S[at, i, :] / sigma
                    jr[rows] = d if slope is None else d * slope[:, None]
            starts = self.split(v)[1]
            g[:] = ((x[self._ends] - starts[1:]) / self.g_scale).ravel()
            if derivatives:
                out["jr"] = jr.ravel()
                # per segment end: d end / d (theta, start_j), then d end / d start_{j+1}
                d_end = (S[self._ends] / self.g_scale[:, None]).reshape(len(self._ends), n * ns)
                d_next = np.broadcast_to(-self.x_scale / self.g_scale, (len(self._ends), n))
                out["jg"] = np.hstack([d_end, d_next]).ravel()
        self._cache_key, self._cache = (key[0], derivatives and ok), out
        return out

    def jacobians(self, v: np.ndarray):
        """``(J_r, J_g)`` as scipy CSR matrices at ``v``."""
        e = self.evaluate(v, True)
        if not e["ok"]:
            raise SolverError("the model could not be integrated at these parameters")
        if "matrices" not in e:
            e["matrices"] = (self._csr_r(e["jr"]), self._csr_g(e["jg"]))
        return e["matrices"]

    def trajectory(self, v: np.ndarray) -> np.ndarray:
        """Model states at every sample (N, n), from the segments at ``v`` (segment starts at their own
        start state; NaN where a segment failed).  Uses the cached evaluation at ``v`` when there is one."""
        segs = self.evaluate(v, derivatives=False)["segments"]
        X = np.full((self.data.n_samples, self.n), np.nan)
        for j, seg in enumerate(segs):
            if seg is not None:
                ks = self.samples_of(j)
                X[ks] = seg[0][ks - self.starts[j]]
        return X

    def close(self):
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

