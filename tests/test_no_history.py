"""The code and the README say what, how and why -- never when.

A comment or docstring that narrates the project's history ("since stop 40", "measured on
practice2_21", "as in 1970ea1 (...)") goes stale the day it is written and hides the reason behind
the anecdote. The reason belongs in the code in general terms; the diary belongs in a decision
record (``docs/decisions/``), the commit message and ``CHANGELOG.md``. This test lists what is left.

What is searched: every source and text file of ``pneusim/`` and ``sysid/`` (``.py``, ``.pyx``,
``.pxd``, ``.h``, ``.toml``, ``.md``; not the C that Cython generates, not compiled objects) and
``README.md``. What is refused, line by line:

* :data:`HISTORY` -- development stops and issue numbers, a hash followed by a parenthesis (a commit
  cited as a source), the practice sets' case ids (``practice_NN``, ``practice2_NN``,
  ``practice3_NN``) and the robustness sets' case ids (``s10NN``, ``s50NN``);
* :data:`COMMIT` -- any other commit hash in prose: a word of 7 to 40 hexadecimal digits holding at
  least one digit and one letter. Hexadecimal literals (``0x1f...``), quoted values (an example run id
  ``'3f0c9a1b2d4e'`` is a value, not a citation), identifiers and words with other letters do not match,
  and neither do decimal numbers (no letter) or English words made of a-f (no digit).

:data:`HISTORY` is the pattern of the common check every engineer runs (``git grep -nE ...``), kept
as it is so that the two agree; it can catch a sentence such as "the piston stops 5 mm short", which
is then worded otherwise.

One place may name commits: the rows of the README's "Current results" table, where each
measurement names the commit it was measured at (a number in a doc names its measurement). Those rows
are checked against :data:`HISTORY` but not :data:`COMMIT`.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("pneusim", "sysid")
SUFFIXES = {".py", ".pyx", ".pxd", ".h", ".toml", ".md"}
HISTORY = re.compile(r"\b[Ss]tops? [0-9]+\b|\b[Ii]ssues? [0-9]+\b|\b[0-9a-f]{7,40}\b \(|practice[23]?_[0-9]{2}"
                     r"|\bs10[0-9]{2}\b|\bs50[0-9]{2}\b")
COMMIT = re.compile(r"(?<![0-9A-Za-z_.'\"])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![0-9A-Za-z_'\"])")
#: the README section whose table rows name the commit each measurement was made at
RESULTS_SECTION = "## Current results"


def _sources() -> list[Path]:
    files = [p for folder in FOLDERS for p in sorted((ROOT / folder).rglob("*"))
             if p.is_file() and p.suffix in SUFFIXES and "__pycache__" not in p.parts]
    return files + [ROOT / "README.md"]


def history_in(text: str, *, results_rows_may_name_commits: bool = False) -> list[tuple[int, str]]:
    """``[(line number, line)]`` of the lines of ``text`` that hold history."""
    found, section = [], ""
    for number, line in enumerate(text.splitlines(), 1):
        if line.startswith("## "):
            section = line.strip()
        exempt = results_rows_may_name_commits and section == RESULTS_SECTION and line.startswith("|")
        if HISTORY.search(line) or (not exempt and COMMIT.search(line)):
            found.append((number, line.strip()))
    return found


def test_the_patterns_catch_history_and_spare_code():
    caught = ["# since stop 40 the rule reads", "issue 9's targets", "as measured at 46bd3f5 (the benchmark)",
              "on practice2_21's leak", "practice_09", "`s1007` from its truth", "the s5000 case",
              "see commit 7c53af1 for the run", "Stops 31-38 measured"]
    spared = ["the end stops of 1e7 N/m", "mask = 0x7fffffff", "run id ``'3f0c9a1b2d4e'``", "SMALL_DENSE_MAX_N 8",
              "1.0e7 N/m", "deadbeef", "a 1234567 sample record", "practice sets", "s100 Hz",
              "file_0a1b2c3d4e.csv", "effaced"]
    assert all(history_in(line) for line in caught), [line for line in caught if not history_in(line)]
    assert not any(history_in(line) for line in spared), [line for line in spared if history_in(line)]
    table = f"{RESULTS_SECTION}\n\n| fit | 2.3 s | `46bd3f5` | 2026-11-27 |\n\n## Next\n\nsee 46bd3f5\n"
    assert history_in(table, results_rows_may_name_commits=True) == [(7, "see 46bd3f5")]


@pytest.mark.parametrize("path", _sources(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_history_in(path):
    text = path.read_text(encoding="utf-8", errors="replace")
    found = history_in(text, results_rows_may_name_commits=path.name == "README.md" and path.parent == ROOT)
    assert not found, (f"{path.relative_to(ROOT)} narrates history (move the diary to docs/decisions/, keep "
                       "the reason in general terms):\n" + "\n".join(f"  {n}: {line[:160]}" for n, line in found))
