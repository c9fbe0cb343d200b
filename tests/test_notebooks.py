"""The teaching notebooks in examples/: each .ipynb is in sync with its jupytext percent script (the
reviewed source) and runs top to bottom (each ends with an assert on what it teaches).

Run them alone with ``pytest tests/test_notebooks.py`` or, through nbmake, ``pytest --nbmake examples``.
"""

from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCRIPTS = sorted(EXAMPLES.glob("[0-9][0-9]_*.py"))

nbformat = pytest.importorskip("nbformat")
jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")


def test_there_are_three_notebooks():
    assert [p.stem[:2] for p in SCRIPTS] == ["01", "02", "03"]


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.stem)
def test_notebook_is_paired_and_runs(script, tmp_path):
    ipynb = script.with_suffix(".ipynb")
    assert ipynb.exists(), f"{ipynb.name} missing: run `jupytext --sync {script.name}` in examples/"
    nb = nbformat.read(ipynb, as_version=4)
    source = jupytext.read(script)
    code = lambda book: [c.source.strip() for c in book.cells if c.cell_type == "code"]  # noqa: E731
    assert code(nb) == code(source), f"{ipynb.name} is out of sync with {script.name} (jupytext --sync)"
    client = nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                                     resources={"metadata": {"path": str(EXAMPLES)}})
    client.execute()          # raises CellExecutionError with the failing cell and its traceback
    nbformat.write(nb, tmp_path / ipynb.name)     # the executed copy, for inspection after a failure
