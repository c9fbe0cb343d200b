"""The structure checks the fit's and the diagnosis's tests share (``tests/pneusim/fit/test_fit_structure.py``,
``tests/pneusim/diagnosis/test_structure.py``): small functions and modules, rules as documented constants, no
diary in comments.

Imported by name (``from structure_checks import ...``): this folder is on ``sys.path`` because of its
``conftest.py``.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

#: what the common ground's check looks for (STYLE.md: code and comments say what, how and why, never when)
DIARY = re.compile(r"\b[Ss]tops? [0-9]+\b|\b[Ii]ssues? [0-9]+\b|\b[0-9a-f]{7,40}\b \(|practice[23]?_[0-9]{2}"
                   r"|\bs10[0-9]{2}\b|\bs50[0-9]{2}\b")


def assert_small(path: Path, max_function_lines: int = 80, max_module_lines: int = 500) -> None:
    """No function of the module at ``path`` over ``max_function_lines`` lines, the module not over
    ``max_module_lines``."""
    source = path.read_text(encoding="utf-8")
    assert len(source.splitlines()) <= max_module_lines, f"{path.name}: {len(source.splitlines())} lines"
    long = [(node.name, node.end_lineno - node.lineno + 1) for node in ast.walk(ast.parse(source))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            and node.end_lineno - node.lineno + 1 > max_function_lines]
    assert not long, f"{path.name}: functions over {max_function_lines} lines: {long}"


def rule_assignments(rules_path: Path) -> tuple[list[str], dict[str, int]]:
    """The lines of a rules module and ``{NAME: line index}`` of each upper-case constant it assigns."""
    lines = rules_path.read_text(encoding="utf-8").splitlines()
    assigned = {}
    for k, line in enumerate(lines):
        match = re.match(r"^([A-Z][A-Z0-9_]*) = ", line)
        if match:
            assigned[match.group(1)] = k
    return lines, assigned
