"""Scenarios: reproducible identification studies on simulated rigs, their reports, and sweeps.

* :func:`load_scenario` reads and validates a ``scenarios/*.toml`` file (schema in ``scenarios/README.md``);
* :func:`run_scenario` simulates it, runs the online identifiers inside the loop and scores every identifier;
* :func:`write_report` writes report.md, report.html, metrics.json, recordings and figures;
* :mod:`pneusim.scenario.sweep` varies scenario keys over grids or random draws, locally or on Dask.
"""

from .report import write_report
from .runner import ScenarioResult, run_scenario
from .schema import load_scenario, validate_scenario

__all__ = ["load_scenario", "validate_scenario", "run_scenario", "ScenarioResult", "write_report"]
