"""The documents in docs/ hold together: their code runs, their links resolve, their indexes are complete.

* Every fenced bash and python block of every ``docs/**/*.md`` runs as written, the blocks of one
  document in order in one fresh folder, as in ``tests/test_readme.py``.  A block that is skipped
  (``<!-- readme-test: skip: REASON -->``) must say why.
* Every relative link of ``README.md`` and ``docs/`` names a file or folder of the repository; every
  module, class or function named in backticks by its dotted path (``pneusim.fit.rules``,
  ``pneusim.plant.SimulatedPlant``) exists, and so does every repository path named in backticks
  (``pneusim/solver/small_dense.h``).
* ``docs/decisions/README.md`` lists every decision record in the folder, and links only to records
  that exist; every record has the four sections.
* Every table in ``docs/results/`` names the commit, the machine and the date it was measured at.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))   # the README test's block runner, beside this file
from test_readme import ROOT, code_blocks_with_reasons, run_blocks_of  # noqa: E402

DOCS = ROOT / "docs"
DOC_FILES = sorted(DOCS.rglob("*.md"))
#: ``[text](target)`` Markdown links; the target up to a space, a closing parenthesis or a fragment
LINK = re.compile(r"\[[^\]]*\]\(([^)\s#]+)(?:#[^)]*)?\)")
#: a dotted name of the two packages in backticks, e.g. `pneusim.fit.rules` or `sysid.RecursiveARX`
DOTTED = re.compile(r"`((?:pneusim|sysid)(?:\.[A-Za-z_][A-Za-z0-9_]*)+)`")
#: a repository path in backticks, e.g. `pneusim/solver/small_dense.h` (not patterns with * or <>)
REPO_PATH = re.compile(r"`((?:pneusim|sysid|benchmarks|scripts|tests|examples|scenarios|docs)/[^`*<> ]*)`")
#: files a document tells its reader to create (a worked example), which therefore do not exist
TO_BE_CREATED = {"tests/pneusim/model/effects/test_backlash.py"}
RECORD = re.compile(r"^(\d{4})-[a-z0-9-]+\.md$")
SECTIONS = ("## Context", "## Decision", "## Evidence", "## Alternatives considered")


def _name(path: Path) -> str:
    return str(path.relative_to(ROOT))


@pytest.mark.slow
@pytest.mark.parametrize("doc", [p for p in DOC_FILES if "```" in p.read_text(encoding="utf-8")], ids=_name)
def test_doc_blocks_run_as_written(doc, tmp_path):
    blocks = code_blocks_with_reasons(doc.read_text(encoding="utf-8"))
    unexplained = [line for language, _, line, skipped, reason in blocks
                   if skipped and language in ("bash", "python") and not reason]
    assert not unexplained, (f"{_name(doc)}: the skipped blocks at lines {unexplained} must say why "
                             "(<!-- readme-test: skip: REASON -->)")
    run_blocks_of(doc, tmp_path)


@pytest.mark.parametrize("doc", [ROOT / "README.md"] + DOC_FILES, ids=_name)
def test_relative_links_resolve(doc):
    text = doc.read_text(encoding="utf-8")
    text = re.sub(r"```.*?```", "", text, flags=re.S)            # links inside code are code
    missing = [target for target in LINK.findall(text)
               if not re.match(r"^[a-z]+:", target) and not (doc.parent / target).exists()]
    assert not missing, f"{_name(doc)} links to files that do not exist: {missing}"


def _resolves(dotted: str) -> bool:
    """Whether ``dotted`` is a module, or an attribute chain of the longest module prefix of it."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        name = ".".join(parts[:cut])
        try:
            if importlib.util.find_spec(name) is None:
                continue
        except ModuleNotFoundError:
            continue
        obj = importlib.import_module(name)
        for attribute in parts[cut:]:
            if not hasattr(obj, attribute):
                return False
            obj = getattr(obj, attribute)
        return True
    return False


@pytest.mark.parametrize("doc", [ROOT / "README.md"] + [p for p in DOC_FILES if "decisions" not in p.parts], ids=_name)
def test_named_modules_and_paths_exist(doc):
    text = doc.read_text(encoding="utf-8")
    missing = sorted({name for name in DOTTED.findall(text) if not _resolves(name)})
    missing += sorted({path for path in REPO_PATH.findall(text)
                       if path not in TO_BE_CREATED and not (ROOT / path.rstrip("/")).exists()})
    assert not missing, f"{_name(doc)} names what does not exist (renamed or moved?): {missing}"


def test_the_decision_index_lists_every_record():
    folder = DOCS / "decisions"
    records = sorted(p.name for p in folder.glob("*.md") if RECORD.match(p.name))
    index = (folder / "README.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"\]\((\d{4}-[a-z0-9-]+\.md)\)", index))
    assert not set(records) - listed, f"records not in docs/decisions/README.md: {sorted(set(records) - listed)}"
    assert not listed - set(records), f"docs/decisions/README.md lists missing records: {sorted(listed - set(records))}"
    numbers = [RECORD.match(name).group(1) for name in records]
    assert len(numbers) == len(set(numbers)), "two decision records share a number"


@pytest.mark.parametrize("record", sorted(p for p in (DOCS / "decisions").glob("*.md") if RECORD.match(p.name)),
                         ids=lambda p: p.name)
def test_a_decision_record_has_the_four_sections(record):
    text = record.read_text(encoding="utf-8")
    assert text.startswith("# "), f"{record.name}: a record starts with its title"
    missing = [s for s in SECTIONS if not re.search(rf"^{re.escape(s)}\s*$", text, flags=re.M)]
    assert not missing, f"{record.name} lacks the sections {missing}"


@pytest.mark.parametrize("table", sorted(p for p in (DOCS / "results").glob("*.md") if p.name != "README.md"),
                         ids=lambda p: p.name)
def test_a_results_table_names_its_measurement(table):
    head = "\n".join(table.read_text(encoding="utf-8").splitlines()[:4])
    assert re.search(r"[Mm]easured at commit `[0-9a-f]{7,}", head), f"{table.name}: no commit in its header"
    assert re.search(r"\b20\d\d-\d\d-\d\d\b", head), f"{table.name}: no date in its header"
    assert re.search(r" on [^,]+", head) and "by `" in head, f"{table.name}: no machine or command in its header"
