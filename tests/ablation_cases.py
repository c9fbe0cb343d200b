"""A tiny ablation sweep, shared by the ablation tests (``tests/pneusim/scenario/test_ablation.py``) and the
figure tests (``tests/test_figures.py``): paper 2's multisine scenario, one seed, its ARX identifier only
(identifiers 1 to 4 off), no physical fits, and the cases given.

Imported by name (``from ablation_cases import ...``): this folder is on ``sys.path`` because of its
``conftest.py``.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["DEADBAND", "write_tiny_ablation"]

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"

#: one ablation case: a 0.5 V valve dead band
DEADBAND = """[[ablation.cases]]
effect = "valve_deadband"
level = "high"
params = { deadband_V = 0.5 }
source = "10 % of the half span"
"""


def write_tiny_ablation(folder: Path, cases: str, duration_s: float = 10.0) -> Path:
    """Write ``folder/ablation.toml``: the tiny ablation of ``duration_s`` seconds with the ``[[ablation.cases]]``
    tables ``cases`` (TOML text); return its path."""
    text = f"""
[sweep]
name = "tiny"
scenario = "{(SCENARIOS / 'paper2-multisine.toml').as_posix()}"
seeds = [2]
[base]
"experiment.duration_s" = {duration_s!r}
"identifiers.1.enabled" = false
"identifiers.2.enabled" = false
"identifiers.3.enabled" = false
"identifiers.4.enabled" = false
[ablation]
metric = "fit_percent"
physical_levels = []
{cases}"""
    path = folder / "ablation.toml"
    path.write_text(text)
    return path
