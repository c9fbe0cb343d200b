"""Checks of the fitted physical model's row, shared by both paper scenarios' tests."""

from pneusim.rig import load_rig


def check_physical_fit_recovers_the_rig(metrics):
    """The scenarios simulate the rig file itself, so the fitted physical model must find the rig
    file's values again (within 3 standard errors, and within 10 % where the short test run
    determines them to 3 %) and re-run the validation half to within 2 % of its range (sensor noise included)."""
    row = [r for r in metrics["rows"] if r["kind"] == "physical_fit"][0]
    assert row["status"] == "ok", row.get("reason")
    rig = load_rig(metrics["rig"])
    for key, entry in row["estimates"].items():
        truth = rig[key]
        assert abs(entry["estimate"] - truth) <= 3.0 * entry["std"], (key, entry, truth)
        if entry["std"] < 0.03 * truth:
            assert abs(entry["estimate"] / truth - 1.0) < 0.1, (key, entry, truth)
    assert row["fit_percent"] > 98.0 and row["fit_percent_recorded_command"] > 98.0
