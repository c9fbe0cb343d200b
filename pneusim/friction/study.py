"""Which friction law seal-friction tests need: leave-one-pressure-out cross-validation.

For each seal (the files of one cylinder at several chamber pressures) both laws of
:mod:`pneusim.friction.laws` are fitted to all pressures but one and scored on the
pressure left out, for every pressure in turn.  The held-out rms error (N) of each
law, per pressure and pooled over all held-out samples, decides: the physics
``pressure_dependent_friction`` is reported missing from the nominal law only when
the pressure law's pooled held-out rms is lower by more than ``min_improvement``
(10 % by default) **and** it is lower at a majority of the held-out pressures.  Both
laws are scored on data neither saw, so the extra parameter cannot win by fitting
noise; a law that does not change with pressure leaves nothing for it to predict.

Fits are nonlinear least squares (SciPy ``least_squares``, trust region reflective,
bounded).  Standard errors are Gauss-Newton ones with white residuals; the
residuals of a friction test are correlated in time (stick-slip, pre-sliding), so
they are optimistic and are given as an indication only.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import PneusimError
from ..outputs import write_json_atomic
from .data import FrictionTest
from .laws import NOMINAL_LAW, PRESSURE_LAW, FrictionLaw

__all__ = ["FrictionStudy", "LawFit", "SealResult"]

EFFECT = "pressure_dependent_friction"

#: fits use every fourth sample (the velocity is a slope over 15 samples); scores use every sample
FIT_STRIDE = 4

#: |velocity| above which a sample counts as sliding for the model-free per-pressure levels, m/s
SLIDING_SPEED_M_PER_S = 3e-3


def sliding_friction_N(test: FrictionTest) -> tuple[float, float]:
    """Model-free friction level of a test: the median friction while sliding out and (sign flipped) in, N."""
    v, f = test.velocity_m_per_s, test.friction_N
    out, back = f[v > SLIDING_SPEED_M_PER_S], f[v < -SLIDING_SPEED_M_PER_S]
    return (float(np.median(out)) if out.size else float("nan"), float(-np.median(back)) if back.size else float("nan"))


@dataclass
class LawFit:
    """One law fitted to some tests.

    Attributes
    ----------
    law : FrictionLaw
    theta : ndarray
        Estimates in SI units, ``law.parameter_names`` order.
    std : ndarray
        Gauss-Newton standard errors (white-residual assumption).
    reference_Pa : float
        Pressure at which the levels are stated (mean of the fitted tests' pressures).
    rms_N : float
        rms residual on the fitted data.
    """

    law: FrictionLaw
    theta: np.ndarray
    std: np.ndarray
    reference_Pa: float
    supply_gauge_Pa: float
    rms_N: float

    def force_N(self, velocity_m_per_s, pressure_Pa):
        return self.law.force_N(self.theta, velocity_m_per_s, pressure_Pa, self.reference_Pa, self.supply_gauge_Pa)

    def parameters(self) -> dict:
        return {n: {"estimate": float(v), "std": float(s)} for n, v, s in
                zip(self.law.parameter_names, self.theta, self.std)}

    def level_N(self, name: str, pressure_Pa: float) -> float:
        """A level (``coulomb_extend_N`` ...) at a pressure: the nominal law's is the same everywhere."""
        value = float(self.theta[self.law.parameter_names.index(name)])
        if "pressure_coefficient" in self.law.parameter_names:
            k = float(self.theta[-1])
            value *= (1.0 + k * abs(pressure_Pa) / self.supply_gauge_Pa) / (
                1.0 + k * self.reference_Pa / self.supply_gauge_Pa)
        return value


@dataclass
class SealResult:
    """Cross-validation of one seal."""

    seal: str
    tests: list
    folds: list = field(default_factory=list)      # dicts: held-out pressure, samples, rms of both laws
    nominal: LawFit | None = None                  # fitted on all pressures
    pressure: LawFit | None = None
    sliding: list = field(default_factory=list)    # per test: median friction sliding out / in, N

    def pooled_rms_N(self, key: str) -> float:
        n = sum(f["samples"] for f in self.folds)
        return float(np.sqrt(sum(f[key] ** 2 * f["samples"] for f in self.folds) / n))


class FrictionStudy:
    """Fit the nominal and the pressure-dependent friction law and compare them on held-out pressures.

    Parameters
    ----------
    supply_gauge_Pa : float
        ``S``, the pressure that normalises the pressure coefficient (default 6 bar, as the shipped
        rigs' supply gauge pressure, so ``k`` compares with ``pressure_dependent_friction.pressure_coefficient``).
    min_improvement : float
        Fraction by which the pressure law's pooled held-out rms must be lower to report the effect.

    Attributes (after :meth:`fit`)
    ------------------------------
    seals_ : list of SealResult
    findings_ : list of dict
        Empty when nothing is missing; else one entry for ``pressure_dependent_friction``.
    rms_nominal_N_, rms_pressure_N_ : float
        Held-out rms over every held-out sample of every seal.
    """

    def __init__(self, supply_gauge_Pa: float = 6.0e5, min_improvement: float = 0.10):
        self.supply_gauge_Pa = float(supply_gauge_Pa)
        self.min_improvement = float(min_improvement)

    # ------------------------------------------------------------------ fit
    def fit(self, tests: Sequence[FrictionTest], progress: bool = False) -> "FrictionStudy":
        """Cross-validate both laws seal by seal, fit them on all pressures, decide; returns ``self``."""
        from threadpoolctl import threadpool_limits

        # the Jacobians are thin (N x 8): one BLAS thread is fastest, and does not fight other processes
        with threadpool_limits(1):
            return self._fit(tests, progress)

    def _fit(self, tests: Sequence[FrictionTest], progress: bool) -> "FrictionStudy":
        groups: dict[str, list] = {}
        for test in tests:
            groups.setdefault(test.seal, []).append(test)
        for seal, group in groups.items():
            pressures = [t.mean_pressure_gauge_Pa for t in group]
            if len(group) < 3 or np.ptp(pressures) < 0.5e5:
                raise PneusimError(f"seal {seal!r}: {len(group)} file(s) at {_bars(pressures)}; leave-one-pressure-"
                                   "out needs at least 3 files per seal at pressures at least 0.5 bar apart")
            if len({round(p / 0.25e5) for p in pressures}) < len(pressures):
                raise PneusimError(f"seal {seal!r}: two files at the same pressure ({_bars(pressures)}); "
                                   "give one file per pressure")
        bar = None
        if progress:
            from ..progress import progress_bar

            bar = progress_bar(sum(len(g) for g in groups.values()), desc="friction folds", unit="fold", leave=False)
        self.seals_ = []
        for seal, group in groups.items():
            group = sorted(group, key=lambda t: t.mean_pressure_gauge_Pa)
            result = SealResult(seal, group)
            for i, held in enumerate(group):
                train = group[:i] + group[i + 1:]
                fold = {"held_out": held.path.name, "pressure_bar": held.mean_pressure_gauge_Pa / 1e5,
                        "samples": int(held.velocity_m_per_s.size)}
                for key, law in (("rms_nominal_N", NOMINAL_LAW), ("rms_pressure_law_N", PRESSURE_LAW)):
                    fitted = self._fit_law(law, train)
                    error = held.friction_N - fitted.force_N(held.velocity_m_per_s, held.pressure_gauge_Pa)
                    fold[key] = float(np.sqrt(np.mean(error ** 2)))
                result.folds.append(fold)
                if bar is not None:
                    bar.update()
            result.nominal = self._fit_law(NOMINAL_LAW, group)
            result.pressure = self._fit_law(PRESSURE_LAW, group)
            result.sliding = [sliding_friction_N(t) for t in group]
            self.seals_.append(result)
        if bar is not None:
            bar.close()
        self._decide()
        return self

    def _fit_law(self, law: FrictionLaw, tests: Sequence[FrictionTest]) -> LawFit:
        from scipy.optimize import least_squares

        step = FIT_STRIDE
        v = np.concatenate([t.velocity_m_per_s[::step] for t in tests])
        p = np.concatenate([t.pressure_gauge_Pa[::step] for t in tests])
        f = np.concatenate([t.friction_N[::step] for t in tests])
        reference = float(np.mean([t.mean_pressure_gauge_Pa for t in tests]))
        scales = law.scales
        lo, hi = law.bounds

        def residual(z):
            return law.force_N(z * scales, v, p, reference, self.supply_gauge_Pa) - f

        def jacobian(z):
            return law.force_N(z * scales, v, p, reference, self.supply_gauge_Pa, jacobian=True)[1] * scales

        res = least_squares(residual, law.start(v, f) / scales, jac=jacobian, bounds=(lo / scales, hi / scales),
                            method="trf", x_scale=1.0, max_nfev=200, tr_solver="lsmr")
        theta = res.x * scales
        dof = max(f.size - theta.size, 1)
        s2 = float(res.fun @ res.fun) / dof
        jac = jacobian(res.x) / scales  # d residual / d theta
        try:
            cov = np.linalg.pinv(jac.T @ jac) * s2
            std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        except np.linalg.LinAlgError:
            std = np.full(theta.size, np.nan)
        return LawFit(law, theta, std, reference, self.supply_gauge_Pa, float(np.sqrt(np.mean(res.fun ** 2))))

    # ------------------------------------------------------------- decision
    def _decide(self):
        folds = [f for s in self.seals_ for f in s.folds]
        n = sum(f["samples"] for f in folds)
        self.rms_nominal_N_ = float(np.sqrt(sum(f["rms_nominal_N"] ** 2 * f["samples"] for f in folds) / n))
        self.rms_pressure_N_ = float(np.sqrt(sum(f["rms_pressure_law_N"] ** 2 * f["samples"] for f in folds) / n))
        self.better_folds_ = sum(f["rms_pressure_law_N"] < f["rms_nominal_N"] for f in folds)
        self.n_folds_ = len(folds)
        self.improvement_percent_ = 100.0 * (1.0 - self.rms_pressure_N_ / self.rms_nominal_N_)
        found = (self.rms_pressure_N_ < (1.0 - self.min_improvement) * self.rms_nominal_N_
                 and self.better_folds_ > self.n_folds_ / 2)
        self.findings_ = []
        if found:
            k = {s.seal: (float(s.pressure.theta[-1]), float(s.pressure.std[-1])) for s in self.seals_}
            levels = "; ".join(
                f"{s.seal}: median sliding friction out/in "
                + ", ".join(f"{t.mean_pressure_gauge_Pa / 1e5:.0f} bar {out:.1f}/{back:.1f} N"
                            for t, (out, back) in zip(s.tests, s.sliding))
                for s in self.seals_)
            self.findings_.append({
                "effect": EFFECT,
                "evidence": (f"held-out rms over {self.n_folds_} left-out pressures: nominal "
                             f"{self.rms_nominal_N_:.2f} N, pressure law {self.rms_pressure_N_:.2f} N "
                             f"({self.improvement_percent_:.0f} % lower, lower at {self.better_folds_} of "
                             f"{self.n_folds_}); {levels}"),
                "parameters": {f"{seal}.pressure_coefficient": {"estimate": v, "std": e}
                               for seal, (v, e) in k.items()},
                "supply_gauge_Pa": self.supply_gauge_Pa,
                "improvement_percent": self.improvement_percent_,
            })
        return self

    # --------------------------------------------------------------- output
    def table(self) -> str:
        """Held-out rms per seal and pressure, both laws, and the verdict."""
        self._check_fitted()
        lines = [f"{'seal':<12} {'held out':>9} {'samples':>8} {'nominal rms':>12} {'pressure-law rms':>17} "
                 f"{'change':>8}   sliding friction out/in (N)"]
        for s in self.seals_:
            for fold, (out, back) in zip(s.folds, s.sliding):
                change = 100.0 * (fold["rms_pressure_law_N"] / fold["rms_nominal_N"] - 1.0)
                lines.append(f"{s.seal:<12} {fold['pressure_bar']:>5.2f} bar {fold['samples']:>8d} "
                             f"{fold['rms_nominal_N']:>10.3f} N {fold['rms_pressure_law_N']:>15.3f} N "
                             f"{change:>+7.1f} %   {out:6.2f} / {back:6.2f}")
            k, e = s.pressure.theta[-1], s.pressure.std[-1]
            pooled_n, pooled_p = s.pooled_rms_N("rms_nominal_N"), s.pooled_rms_N("rms_pressure_law_N")
            lines.append(f"{s.seal:<12} {'pooled':>9} {'':>8} {pooled_n:>10.3f} N {pooled_p:>15.3f} N "
                         f"{100.0 * (pooled_p / pooled_n - 1.0):>+7.1f} %   k = {k:.2f} +- {e:.2f} "
                         f"(S = {self.supply_gauge_Pa / 1e5:g} bar)")
        lines.append(f"all seals: held-out rms nominal {self.rms_nominal_N_:.3f} N, pressure law "
                     f"{self.rms_pressure_N_:.3f} N ({-self.improvement_percent_:+.1f} %), pressure law lower at "
                     f"{self.better_folds_} of {self.n_folds_} held-out pressures")
        if self.findings_:
            lines.append(f"missing physics: {EFFECT} (seal friction grows with the pressure across the seal); "
                         f"held-out error {self.improvement_percent_:.0f} % lower")
        else:
            lines.append("nothing is missing: the pressure law does not predict held-out pressures clearly better "
                         f"(needs > {100 * self.min_improvement:.0f} % lower pooled rms and a majority of pressures)")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        self._check_fitted()
        seals = {}
        for s in self.seals_:
            seals[s.seal] = {
                "files": [t.path.name for t in s.tests],
                "bore_m": s.tests[0].bore_m,
                "pressures_bar": [t.mean_pressure_gauge_Pa / 1e5 for t in s.tests],
                "held_out": s.folds,
                "pooled_rms_nominal_N": s.pooled_rms_N("rms_nominal_N"),
                "pooled_rms_pressure_law_N": s.pooled_rms_N("rms_pressure_law_N"),
                "nominal": {"reference_pressure_Pa": s.nominal.reference_Pa, "rms_N": s.nominal.rms_N,
                            "parameters": s.nominal.parameters()},
                "pressure_law": {"reference_pressure_Pa": s.pressure.reference_Pa, "rms_N": s.pressure.rms_N,
                                 "parameters": s.pressure.parameters()},
                "sliding_friction": [{"file": t.path.name, "pressure_bar": t.mean_pressure_gauge_Pa / 1e5,
                                      "median_extending_N": out, "median_retracting_N": back}
                                     for t, (out, back) in zip(s.tests, s.sliding)],
            }
        return {"method": "leave-one-pressure-out cross-validation of the nominal Stribeck law (one level per "
                          "direction, same at every pressure) against pressure_dependent_friction",
                "supply_gauge_Pa": self.supply_gauge_Pa, "min_improvement": self.min_improvement,
                "held_out_rms_nominal_N": self.rms_nominal_N_, "held_out_rms_pressure_law_N": self.rms_pressure_N_,
                "improvement_percent": self.improvement_percent_,
                "pressure_law_better_folds": self.better_folds_, "folds": self.n_folds_,
                "seals": seals, "findings": self.findings_}

    def write_json(self, path) -> Path:
        """Write :meth:`to_dict` to ``path`` as JSON, atomically (a failed write leaves the previous file whole);
        returns the path."""
        return write_json_atomic(Path(path), self.to_dict(), indent=2)

    def _check_fitted(self):
        if not hasattr(self, "seals_"):
            raise PneusimError("FrictionStudy: call fit(tests) first")


def _bars(pressures) -> str:
    return ", ".join(f"{p / 1e5:.1f}" for p in pressures) + " bar"
