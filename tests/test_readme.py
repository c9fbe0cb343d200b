"""Every fenced bash and python block of the READMEs runs as written, in a fresh folder, as a new user's would.

The blocks of one README run in order in one temporary folder (a later block may read the files an
earlier one wrote, as a reader following the README would).  Bash blocks run with the
environment's ``bin`` first on ``PATH`` (so ``pneusim`` is the installed command), python blocks
with this interpreter.  A block directly preceded by the line ``<!-- readme-test: skip -->`` is
not run (long runs, machine set-up, hardware); every other block must end with exit status 0 and
print no traceback.
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
SKIP_MARK = "<!-- readme-test: skip -->"
FENCE = re.compile(r"^```(\w*)\s*$")


def code_blocks(text: str) -> list[tuple[str, str, int, bool]]:
    """``[(language, code, first line number, skipped)]`` of the fenced blocks of a Markdown text."""
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
        blocks.append((language, "\n".join(lines[start + 1:j]) + "\n", start + 1, previous == SKIP_MARK))
        i = j + 1
    return blocks


def test_code_blocks_reads_languages_and_the_skip_mark():
    text = "intro\n\n```bash\necho 1\n```\n\n<!-- readme-test: skip -->\n```python\nimport x\n```\n```\nplain\n```\n"
    assert code_blocks(text) == [("bash", "echo 1\n", 3, False), ("python", "import x\n", 8, True),
                                 ("", "plain\n", 11, False)]


def _run(language: str, code: str, folder: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env["MPLBACKEND"] = "Agg"
    if language == "bash":
        command = ["bash", "-e", "-o", "pipefail", "-c", code]
    else:
        command = [sys.executable, "-c", code]
    return subprocess.run(command, cwd=folder, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("readme", READMES)
def test_readme_blocks_run_as_written(readme, tmp_path):
    blocks = [b for b in code_blocks((ROOT / readme).read_text(encoding="utf-8")) if b[0] in ("bash", "python")]
    if readme == "README.md":
        # the top-level set-up, reproduce and test commands take many minutes: they must be marked
        assert any(skipped and "reproduce.sh" in code for _, code, _, skipped in blocks)
        assert sum(not skipped for *_, skipped in blocks) >= 3
    for language, code, line, skipped in blocks:
        if skipped:
            continue
        done = _run(language, code, tmp_path)
        where = f"{readme}:{line} ({language} block)"
        assert done.returncode == 0, f"{where} failed:\n{code}\n--- stdout\n{done.stdout}\n--- stderr\n{done.stderr}"
        assert "Traceback" not in done.stderr, f"{where} printed a traceback:\n{done.stderr}"
