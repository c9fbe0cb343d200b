"""The diagnosis reads as its method: small functions, the rules in one module, stages passed in, no diary.

* No function in ``pneusim/diagnosis/`` over 80 lines, no module over 500.
* Every rule of :mod:`pneusim.diagnosis.rules` is a documented constant (a ``#: (unit) reason`` comment above
  it), no other module of the diagnosis defines a number of its own, the names other modules re-export are the
  rules' own objects, and the table of ``docs/diagnosis.md`` ("Rules") is the one the module generates.
* :class:`~pneusim.diagnosis.DiagnosisStages` holds today's stages by default, and ``diagnose`` keeps its
  signature.
* A vocabulary effect is named only where the diagnosis does something for it alone: the transport delay's
  scans (:mod:`pneusim.diagnosis.delay`); everything else reads the effect's declared facts.
* No comment or docstring of ``pneusim/diagnosis/`` names a stop, an issue, a commit or a case id: the story is
  in ``docs/decisions/``.
"""

import ast
import inspect
import re
from pathlib import Path

import pytest

import pneusim.diagnosis as diagnosis
from pneusim.diagnosis import rules
from pneusim.model.effects import EFFECTS
from structure_checks import DIARY, assert_small, rule_assignments

PACKAGE = Path(diagnosis.__file__).resolve().parent
DOC = PACKAGE.parents[1] / "docs" / "diagnosis.md"
MODULES = sorted(PACKAGE.glob("*.py"))
#: where a vocabulary effect may be named: what the diagnosis does for that effect alone
NAMED_EFFECTS = {"delay.py": {"transport_delay"}}


@pytest.mark.parametrize("path", MODULES, ids=lambda p: p.name)
def test_no_function_over_80_lines_and_no_module_over_500(path):
    assert_small(path)


def test_every_rule_is_a_documented_constant_with_its_unit():
    lines, assigned = rule_assignments(PACKAGE / "rules.py")
    constants = {name for name in rules.__all__ if name.isupper()}
    assert constants == set(assigned), constants ^ set(assigned)
    undocumented = [name for name, k in assigned.items()
                    if not (lines[k - 1].startswith("#: ") and re.match(r"#: \([^)]+\) \S", _first_comment_line(lines, k)))]
    assert not undocumented, f"rules without a '#: (unit) reason' comment above them: {undocumented}"
    assert [row[0] for row in rules.rules_table()] == sorted(assigned, key=assigned.get)
    assert all(unit and reason for _, _, unit, reason in rules.rules_table())


def _first_comment_line(lines, k):
    """The first line of the ``#:`` comment above line ``k``."""
    while k > 0 and lines[k - 1].startswith("#: "):
        k -= 1
    return lines[k]


@pytest.mark.parametrize("path", [p for p in MODULES if p.name != "rules.py"], ids=lambda p: p.name)
def test_no_module_but_rules_defines_a_number(path):
    """A threshold lives next to its siblings: no module-level constant of the diagnosis holds a number (or a
    tuple of numbers) but those of :mod:`pneusim.diagnosis.rules`."""
    numbers = []
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None:
            value = node.value
            items = value.elts if isinstance(value, ast.Tuple) else [value]
            if items and all(isinstance(v, ast.Constant) and isinstance(v.value, (int, float))
                             and not isinstance(v.value, bool) for v in items):
                numbers.append(node.lineno)
    assert not numbers, f"{path.name}: numbers defined outside rules.py on lines {numbers}"


def test_the_names_other_modules_export_are_the_rules():
    from pneusim.diagnosis import around_nominal, candidates, delay, findings, from_data_sheet
    from pneusim.fit import rules as fit_rules

    assert rules.MODEL_SHORT is fit_rules.MODEL_SHORT              # one definition: the fit's
    assert rules.DEFECT_WEIGHT is fit_rules.PENALTY_WEIGHT
    assert rules.VALIDATION_FRACTION is fit_rules.DEFAULT_VALIDATION_FRACTION
    assert candidates.DEFECT_WEIGHT is rules.DEFECT_WEIGHT
    assert delay.SCAN_FACTOR is rules.SCAN_FACTOR and delay.SCAN_REFITS is rules.SCAN_REFITS
    assert around_nominal.RELATIVE_SCORE is rules.RELATIVE_SCORE and around_nominal.MIN_EXPLAINED is rules.MIN_EXPLAINED
    assert findings.ON_TOP_REFITS is rules.ON_TOP_REFITS
    assert from_data_sheet.WINDOW_SAMPLES is rules.WINDOW_SAMPLES


def _rules_section() -> str:
    text = DOC.read_text(encoding="utf-8")
    section = text.split("\n## Rules\n", 1)[1].split("\n## ", 1)[0]
    return "\n".join(line for line in section.splitlines() if line.startswith("|"))


def test_the_docs_rules_table_is_the_modules():
    """``docs/diagnosis.md``'s "Rules" table is generated from :mod:`pneusim.diagnosis.rules`; regenerate it with
    ``python -c "from pneusim.diagnosis import rules; print(rules.table_markdown())"``."""
    assert _rules_section() == rules.table_markdown()


def test_the_keep_test_reads_as_its_rules():
    """The keep test's thresholds are the named rules: moving one moves the test."""
    F = 0.2
    assert rules.validation_room(100 - rules.CLEARLY_SHORT * F, F) == pytest.approx(0.0)
    # just above max(0.5, F) points with the error shrunk by more than 10 %: kept; just below: not
    kept, threshold, _ = rules.passes_test(2.0, 1.0, 100, 1, 95.0, 95.0 + rules.MIN_IMPROVEMENT_POINTS + 0.01, F)
    assert kept and threshold == rules.MIN_IMPROVEMENT_POINTS
    assert not rules.passes_test(2.0, 1.0, 100, 1, 95.0, 95.0 + rules.MIN_IMPROVEMENT_POINTS - 0.01, F)[0]
    assert rules.information_gain(2.0, 1.0, 100, 1) == pytest.approx(100 * 0.6931471805599453 - 4.605170185988092)
    assert rules.screening_route(-1.0, 100.0) == "none"
    assert rules.screening_route(1.0, rules.MODEL_SHORT * 1.01) == "from the data sheet"
    assert rules.screening_route(1.0, rules.MODEL_SHORT) == "around the nominal fit"
    assert "max(0.5, F) = 0.50 points" in rules.keep_test_text(F, 95.0, 1.0)
    assert "at least 10 % smaller" in rules.keep_test_text(F, 95.0, 1.0)


def test_diagnosis_stages_default_to_todays_stages():
    from pneusim.diagnosis.around_nominal import confirm_around_nominal, screen_around_nominal
    from pneusim.diagnosis.candidates import polished_costs, screen
    from pneusim.diagnosis.delay import scan_kept_delay
    from pneusim.diagnosis.findings import add_findings, drop_one
    from pneusim.diagnosis.from_data_sheet import confirm_from_data_sheet, screen_from_data_sheet
    from pneusim.diagnosis.locate import locate_mismatch
    from pneusim.diagnosis.other import other_finding
    from pneusim.diagnosis.refits import fit_from_data_sheet, fit_nominal, refit
    from pneusim.diagnosis.signatures import compute_signatures
    from pneusim.fit import prefit_recording

    stages = diagnosis.DiagnosisStages()
    assert (stages.nominal_fit, stages.locate, stages.signatures) == (fit_nominal, locate_mismatch, compute_signatures)
    assert (stages.screen_around_nominal, stages.confirm_around_nominal) == (screen_around_nominal,
                                                                               confirm_around_nominal)
    assert (stages.screen_from_data_sheet, stages.confirm_from_data_sheet) == (screen_from_data_sheet,
                                                                                 confirm_from_data_sheet)
    assert (stages.delay_scan, stages.findings, stages.drop_one, stages.other) == (scan_kept_delay, add_findings,
                                                                                   drop_one, other_finding)
    assert (stages.screen, stages.polished_costs, stages.prefit) == (screen, polished_costs, prefit_recording)
    assert (stages.refit, stages.fit, stages.keep_test) == (refit, fit_from_data_sheet, rules.passes_test)
    with pytest.raises(AttributeError):
        stages.refit = None                     # frozen: a diagnosis's stages do not change under it
    assert diagnosis.Diagnosis().stages == stages


def test_diagnose_keeps_its_signature():
    signature = inspect.signature(diagnosis.diagnose)
    defaults = {name: p.default for name, p in signature.parameters.items()}
    assert defaults == {"recording": inspect.Parameter.empty, "rig": None, "effects": None, "validation_fraction": 0.3,
                        "max_refits": 3, "max_lookalikes": 2, "max_findings": None, "screen_samples": None,
                        "progress": False, "several_effects": None, "time_budget_s": None}


@pytest.mark.parametrize("path", MODULES, ids=lambda p: p.name)
def test_an_effect_is_named_only_where_the_diagnosis_does_something_for_it_alone(path):
    names = {node.value for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
             if isinstance(node, ast.Constant) and node.value in EFFECTS}
    assert names <= NAMED_EFFECTS.get(path.name, set()), f"{path.name} names {sorted(names)}"


@pytest.mark.parametrize("path", MODULES, ids=lambda p: p.name)
def test_no_diary_in_the_code(path):
    found = [(k + 1, line.strip()) for k, line in enumerate(path.read_text(encoding="utf-8").splitlines())
             if DIARY.search(line)]
    assert not found, f"{path.name} names a stop, an issue, a commit or a case id (move the story to docs/decisions/)"
