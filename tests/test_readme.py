"""Every fenced bash and python block of the READMEs runs as written, in a fresh folder, as a new user's would.

The blocks of one README run in order in one temporary folder (a later block may read the files an
earlier one wrote, as a reader following the README would).  The folder holds a link to the
repository's ``scenarios/``, so a block names a shipped scenario as a reader in the repository does.
Bash blocks run with the environment's ``bin`` first on ``PATH`` (so ``pneusim`` is the installed
command), python blocks with this interpreter.  A block directly preceded by the line
``<!-- readme-test: skip -->`` or ``<!-- readme-test: skip: REASON -->`` is not run (long runs,
machine set-up, hardware, data beside the repository); every other block must end with exit status 0
and print no traceback.  ``tests/test_docs.py`` runs the blocks of ``docs/`` the same way.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
READMES = ("README.md", "scenarios/README.md", "sysid/README.md")
#: ``<!-- readme-test: skip -->`` or ``<!-- readme-test: skip: the reason -->``
SKIP_MARK = re.compile(r"^<!-- readme-test: skip(?:: (?P<reason>.+?))? -->$")
FENCE = re.compile(r"^```(\w*)\s*$")
#: folders of the repository a block may name by their relative path, linked into its folder
LINKED = ("scenarios",)


def code_blocks(text: str) -> list[tuple[str, str, int, bool]]:
    """``[(language, code, first line number, skipped)]`` of the fenced blocks of a Markdown text."""
    return [block[:4] for block in code_blocks_with_reasons(text)]


def code_blocks_with_reasons(text: str) -> list[tuple[str, str, int, bool, str]]:
    """``[(language, code, first line number, skipped, skip reason or "")]`` of a Markdown text's fenced blocks."""
    lines = text.splitlines()
    blocks, i = [], 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        if not match:
            i += 1
            continue
        language, start = match.group(1), i
        j = i + 1
        while j < len(lines) and not lines[j].startswith("```"):
            j += 1
        previous = next((lines[k].strip() for k in range(start - 1, -1, -1) if lines[k].strip()), "")
        skip = SKIP_MARK.match(previous)
        blocks.append((language, "\n".join(lines[start + 1:j]) + "\n", start + 1, skip is not None,
                       (skip.group("reason") or "") if skip else ""))
        i = j + 1
    return blocks


def test_code_blocks_reads_languages_and_the_skip_mark():
    text = ("intro\n\n```bash\necho 1\n```\n\n<!-- readme-test: skip -->\n```python\nimport x\n```\n```\nplain\n```\n"
            "<!-- readme-test: skip: takes an hour -->\n```bash\nsleep 3600\n```\n")
    assert code_blocks(text) == [("bash", "echo 1\n", 3, False), ("python", "import x\n", 8, True),
                                 ("", "plain\n", 11, False), ("bash", "sleep 3600\n", 15, True)]
    assert [b[4] for b in code_blocks_with_reasons(text)] == ["", "", "", "takes an hour"]


def prepare_folder(folder: Path) -> Path:
    """Link the repository folders a reader's command may name (:data:`LINKED`) into ``folder``."""
    for name in LINKED:
        link = folder / name
        if not link.exists():
            link.symlink_to(ROOT / name, target_is_directory=True)
    return folder


def run_block(language: str, code: str, folder: Path) -> subprocess.CompletedProcess:
    """Run one bash or python block in ``folder`` as a reader's shell or interpreter would."""
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env["MPLBACKEND"] = "Agg"
    if language == "bash":
        command = ["bash", "-e", "-o", "pipefail", "-c", code]
    else:
        command = [sys.executable, "-c", code]
    return subprocess.run(command, cwd=folder, env=env, capture_output=True, text=True, timeout=300)


def run_blocks_of(path: Path, folder: Path) -> int:
    """Run every bash and python block of the Markdown file ``path`` that is not skipped, in order, in
    ``folder``; fail on the first that exits non-zero or prints a traceback.  Returns how many ran."""
    prepare_folder(folder)
    ran = 0
    for language, code, line, skipped in code_blocks(path.read_text(encoding="utf-8")):
        if skipped or language not in ("bash", "python"):
            continue
        done = run_block(language, code, folder)
        where = f"{path.relative_to(ROOT)}:{line} ({language} block)"
        assert done.returncode == 0, f"{where} failed:\n{code}\n--- stdout\n{done.stdout}\n--- stderr\n{done.stderr}"
        assert "Traceback" not in done.stderr, f"{where} printed a traceback:\n{done.stderr}"
        ran += 1
    return ran


@pytest.mark.slow
@pytest.mark.parametrize("readme", READMES)
def test_readme_blocks_run_as_written(readme, tmp_path):
    blocks = [b for b in code_blocks((ROOT / readme).read_text(encoding="utf-8")) if b[0] in ("bash", "python")]
    if readme == "README.md":
        # the top-level set-up, reproduce and test commands take many minutes: they must be marked
        assert any(skipped and "reproduce.sh" in code for _, code, _, skipped in blocks)
        # the tour runs: simulate, check, plot, fit, diagnose, a scenario, the MRE, sysid from Python
        ran = "".join(code for _, code, _, skipped in blocks if not skipped)
        for step in ("pneusim simulate", "pneusim check", "pneusim plot", "pneusim fit", "pneusim diagnose",
                     "pneusim run", "pneusim mre", "import sysid", "fit_recording"):
            assert step in ran, f"the README's tour no longer runs {step!r}"
    run_blocks_of(ROOT / readme, tmp_path)
