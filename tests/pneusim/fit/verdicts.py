"""Verdicts that hold on any machine: a fit's verdict checked as given and under tiny perturbations.

A fit's verdict (it reaches the noise level; the truth lies within 3 standard errors) that changes when the start
values or the recorded data move by 1e-12 relative is not a result: it hangs on the last bits of the arithmetic,
which another CPU's BLAS kernels (``OPENBLAS_CORETYPE``) change as much.  ``fits_under_perturbations`` fits a
recording as given and under deterministic perturbations of that size, so that a test asserts its verdict on
each of them; ``.ci/run`` runs the same tests again under a second arithmetic path.

    for result in fits_under_perturbations(recording, rig, free=free, truth=truth):
        assert_verdict(result, truth)
"""

from __future__ import annotations

import dataclasses

import numpy as np

from pneusim.fit import fit_recording
from pneusim.fit.robustness import score

#: relative size of the perturbations: a few hundred times the double precision's rounding
PERTURBATION = 1e-12
#: the perturbations every verdict is checked under: the start values, the recorded data
KINDS = ("start", "data")


def _pattern(k: int, size: int) -> np.ndarray:
    """A deterministic pattern in ``[-1, 1]`` (the same on every machine) for perturbation ``k``."""
    return np.random.default_rng(7919 + k).uniform(-1.0, 1.0, size)


def perturbed_start(rig, free, k: int = 1, eps: float = PERTURBATION, start_values: dict | None = None) -> dict:
    """Start values ``{name: value}`` of every free parameter: ``start_values``' (else the rig's) times
    ``1 + eps u`` with ``u`` in ``[-1, 1]`` (:func:`_pattern` ``k``)."""
    base = {name: (start_values or {}).get(name, rig[name]) for name in free}
    u = _pattern(k, len(free))
    return {name: float(value * (1.0 + eps * u[i])) for i, (name, value) in enumerate(base.items())}


def perturbed_recording(recording, k: int = 1, eps: float = PERTURBATION):
    """``recording`` with its position and recorded pressures times ``1 + eps u`` sample by sample (a NaN gap
    stays a gap)."""
    changes = {}
    for i, name in enumerate(("position_m", "pressure_a_Pa", "pressure_b_Pa")):
        values = getattr(recording, name)
        if values is not None:
            changes[name] = values * (1.0 + eps * _pattern(100 * k + i, values.size))
    return dataclasses.replace(recording, **changes)


def fits_under_perturbations(recording, rig, *, free=None, start_values: dict | None = None, kinds=KINDS,
                             fit=fit_recording, **options):
    """Yield ``(label, result)``: the fit of ``recording`` as given, then one per perturbation of ``kinds``
    (``"start"``: :func:`perturbed_start`, ``"data"``: :func:`perturbed_recording`).  ``free`` defaults to the
    fit's default free set; ``options`` go to ``fit`` (``quiet=True`` unless given)."""
    options.setdefault("quiet", True)
    yield "as given", fit(recording, rig, free=free, start_values=start_values, **options)
    names = free
    if names is None:
        from pneusim.fit import DEFAULT_FREE
        names = list(DEFAULT_FREE)
    for kind in kinds:
        if kind == "start":
            yield kind, fit(recording, rig, free=free, start_values=perturbed_start(rig, names, 1, start_values=start_values),
                            **options)
        elif kind == "data":
            yield kind, fit(perturbed_recording(recording, 1), rig, free=free, start_values=start_values, **options)
        else:
            raise ValueError(f"unknown perturbation {kind!r}: 'start' or 'data'")


def assert_verdict(result, truth: dict | None = None, label: str = "", all_inside: bool = False) -> None:
    """The verdict: the fit reaches the noise level, ``solver["success"]`` says so, and (with ``truth``) the truth
    lies within 3 standard errors for every default free parameter (``all_inside``) or all but one."""
    where = f" ({label})" if label else ""
    assert result.converged_to_noise, (f"above noise{where}", result.normalised_residuals,
                                       result.solver.get("prefit_attempts"))
    assert result.solver["success"] is True
    if truth is not None:
        s = score(result, truth)
        assert s["inside_3_sigma"] >= s["parameters"] - (0 if all_inside else 1), (f"truth outside 3 sigma{where}",
                                                                                  s["z"])
