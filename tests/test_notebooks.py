"""The teaching notebooks in examples/: each .ipynb is in sync with its jupytext percent script (the
reviewed source), runs top to bottom (each ends with an assert on what it teaches), and every figure it
shows meets the figure standard (:func:`pneusim.plotting.figure_problems`: a title, labelled axes with
units, legends off the data).

The figures are checked inside the notebook's kernel: a cell put before the notebook's first one wraps
``plt.show`` and looks, at the end of every cell, at the figures still open, before the inline backend
draws and closes them; a cell put after its last one reports what it found.

Run them alone with ``pytest tests/test_notebooks.py`` or, through nbmake, ``pytest --nbmake examples``.
"""

import json
import time
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCRIPTS = sorted(EXAMPLES.glob("[0-9][0-9]_*.py"))

nbformat = pytest.importorskip("nbformat")
jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")

#: at least this many figures each notebook shows (a notebook that stopped showing its lesson fails)
MIN_FIGURES = {"01": 4, "02": 4, "03": 2, "04": 2}

CHECK_FIGURES = '''
import matplotlib.pyplot as _plt
from IPython import get_ipython as _get_ipython
from pneusim.plotting import figure_problems as _figure_problems

_checked = {"figures": 0, "problems": []}


def _check_open_figures():
    for _num in _plt.get_fignums():
        _checked["figures"] += 1
        _checked["problems"] += _figure_problems(_plt.figure(_num), f"figure {_checked['figures']}")


_show = _plt.show


def _checked_show(*args, **kwargs):
    _check_open_figures()
    return _show(*args, **kwargs)


_plt.show = _checked_show
# before the inline backend's own post_execute callback draws and closes what a cell left open
_get_ipython().events.callbacks["post_execute"].insert(0, _check_open_figures)
'''
REPORT_FIGURES = '''
import json as _json
print("FIGURES " + _json.dumps(_checked))
'''


def test_there_are_four_notebooks():
    assert [p.stem[:2] for p in SCRIPTS] == ["01", "02", "03", "04"]


def _figures_report(nb) -> dict:
    for output in nb.cells[-1].get("outputs", []):
        for line in output.get("text", "").splitlines():
            if line.startswith("FIGURES "):
                return json.loads(line[len("FIGURES "):])
    raise AssertionError("the figure check's last cell printed nothing")


def _run_checked(nb, tmp_path, name):
    nb.cells = [nbformat.v4.new_code_cell(CHECK_FIGURES)] + nb.cells + [nbformat.v4.new_code_cell(REPORT_FIGURES)]
    client = nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                                     resources={"metadata": {"path": str(EXAMPLES)}})
    started = time.perf_counter()
    client.execute()          # raises CellExecutionError with the failing cell and its traceback
    seconds = time.perf_counter() - started
    nbformat.write(nb, tmp_path / name)     # the executed copy, for inspection after a failure
    return _figures_report(nb), seconds


@pytest.mark.slow
def test_the_kernel_check_sees_shown_and_unshown_figures(tmp_path):
    """A bare figure shown with plt.show, and one left open at the end of its cell, are both found wanting."""
    nb = nbformat.v4.new_notebook(cells=[
        nbformat.v4.new_code_cell("import matplotlib.pyplot as plt\nplt.plot([0, 1], [0, 1])\nplt.show()"),
        nbformat.v4.new_code_cell("fig, ax = plt.subplots()\nax.plot([0, 1], [1, 0], label='a')\nax.legend()"),
    ])
    report, _ = _run_checked(nb, tmp_path, "bare.ipynb")
    assert report["figures"] == 2
    assert sum("no title" in p for p in report["problems"]) == 2
    assert sum("no label" in p for p in report["problems"]) == 4


@pytest.mark.slow
@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.stem)
def test_notebook_is_paired_runs_and_its_figures_meet_the_standard(script, tmp_path):
    ipynb = script.with_suffix(".ipynb")
    assert ipynb.exists(), f"{ipynb.name} missing: run `jupytext --sync {script.name}` in examples/"
    nb = nbformat.read(ipynb, as_version=4)
    source = jupytext.read(script)
    code = lambda book: [c.source.strip() for c in book.cells if c.cell_type == "code"]  # noqa: E731
    assert code(nb) == code(source), f"{ipynb.name} is out of sync with {script.name} (jupytext --sync)"
    report, seconds = _run_checked(nb, tmp_path, ipynb.name)
    print(f"{script.stem}: ran in {seconds:.1f} s, {report['figures']} figures checked")
    assert report["problems"] == [], "\n".join(report["problems"])
    assert report["figures"] >= MIN_FIGURES[script.stem[:2]], report
