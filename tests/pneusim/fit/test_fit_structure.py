"""The fit reads as its method: small functions, the rules in one module, stages passed in, no diary.

* No function in ``pneusim/fit/`` over 80 lines, no module over 500.
* Every rule of :mod:`pneusim.fit.rules` is a documented constant (a ``#:`` comment with its reason), and the
  names other packages import from a stage's module are the rules' own objects.
* :class:`~pneusim.fit.FitStages` holds today's stages by default, and the restart rule of
  :class:`~pneusim.fit.PhysicalFit` decides as documented.
* No comment or docstring of ``pneusim/fit/`` or ``pneusim/solver/`` names a stop, an issue, a commit or a case
  id: the story is in ``docs/decisions/``.
"""

from pathlib import Path

import pytest

import pneusim.fit as fit
from pneusim.fit import rules
from structure_checks import DIARY, assert_small, rule_assignments

PACKAGE = Path(fit.__file__).resolve().parent
SOLVER = PACKAGE.parent / "solver"


@pytest.mark.parametrize("path", sorted(PACKAGE.glob("*.py")), ids=lambda p: p.name)
def test_no_function_over_80_lines_and_no_module_over_500(path):
    assert_small(path)


def test_every_rule_is_a_documented_constant():
    lines, assigned = rule_assignments(PACKAGE / "rules.py")
    assert set(rules.__all__) == set(assigned), set(rules.__all__) ^ set(assigned)
    undocumented = [name for name, k in assigned.items() if not lines[k - 1].startswith("#: ")]
    assert not undocumented, f"rules without a '#:' comment above them: {undocumented}"


def test_the_names_other_packages_import_are_the_rules():
    from pneusim.fit import result, setup, stages

    assert stages.MODEL_SHORT is rules.MODEL_SHORT and stages.PENALTY_WEIGHT is rules.PENALTY_WEIGHT
    assert result.ABOVE_NOISE_WARNING is rules.ABOVE_NOISE_WARNING and result.FAR_ABOVE_NOISE is rules.FAR_ABOVE_NOISE
    assert setup.INFORMATIVE_WINDOW is rules.INFORMATIVE_WINDOW
    assert setup.DEFAULT_VALIDATION_FRACTION is rules.DEFAULT_VALIDATION_FRACTION
    from pneusim.fit.trust_region import trust_region

    assert stages.trust_region is trust_region


def test_fit_stages_default_to_todays_stages():
    from pneusim.fit.constrained import settle_gauss_newton, solve_ipopt_exact
    from pneusim.fit.rescue_routes import prediction_error_route, short_segments_route, tracked_route
    from pneusim.fit.stages import full_fit, prefit
    from pneusim.fit.trust_region import trust_region
    from pneusim.fit.uncertainty import covariance
    from pneusim.fit.validation import validate

    stages = fit.FitStages()
    assert (stages.prefit, stages.short_segments, stages.whole_fit) == (prefit, short_segments_route, full_fit)
    assert (stages.settle, stages.finish, stages.warm_trust_region) == (settle_gauss_newton, solve_ipopt_exact,
                                                                         trust_region)
    assert (stages.tracked, stages.prediction_error) == (tracked_route, prediction_error_route)
    assert (stages.uncertainty, stages.validate) == (covariance, validate)
    with pytest.raises(AttributeError):
        stages.settle = None                    # frozen: a fit's stages do not change under it
    assert fit.PhysicalFit().stages == stages


def test_restart_rule():
    """The next start is tried where a fit ends well above its pre-fit or both end above noise, never where the
    pre-fit itself ends more than MODEL_SHORT times above noise (then the stage line says why)."""
    lines = []

    class Run:
        def say(self, message):
            lines.append(message)

    restart = fit.PhysicalFit._restart
    assert not restart(Run(), 0, 0.99, 0.98)                 # at noise, near its pre-fit
    assert restart(Run(), 0, 2.0, 0.98)                      # well above its pre-fit
    assert restart(Run(), 0, 1.5, 1.4)                       # both above noise
    assert restart(Run(), 0, float("nan"), 0.98)             # a fit that is not finite is well above
    assert not lines
    assert not restart(Run(), 0, 7.0, 1.01 * rules.MODEL_SHORT)
    assert len(lines) == 1 and "lacks physics" in lines[0]


@pytest.mark.parametrize("path", sorted([*PACKAGE.glob("*.py"), *SOLVER.glob("*.py"), *SOLVER.glob("*.pyx"),
                                         *SOLVER.glob("*.h")]), ids=lambda p: p.name)
def test_no_diary_in_the_code(path):
    found = [(k + 1, line.strip()) for k, line in enumerate(path.read_text(encoding="utf-8").splitlines())
             if DIARY.search(line)]
    assert not found, f"{path.name} names a stop, an issue, a commit or a case id (move the story to docs/decisions/)"
