"""The package's architecture holds: its layers, no import circles, no private names across packages.

* the import-linter contracts of ``pyproject.toml`` (``[tool.importlinter]``: the layers from the command
  line down to the utilities, independent applications, ``sysid`` without ``pneusim``, private modules
  kept private, no circles between the modules of a package) pass, run by the venv's ``lint-imports``;
* every module of ``pneusim`` has a place in the layers (a new module must be given one);
* no module imports a ``_private`` name (or a name from a ``_private`` module) of another package;
* no module imports, through any chain, a module that imports it back (grimp's graph of every import,
  those inside functions included), and nothing imports the package root ``pneusim`` itself.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

grimp = pytest.importorskip("grimp")

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("pneusim", "sysid")
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")

#: imports of a private module of another package that are known and explained, ``(importer, imported)``:
#: the compiled sample loop is the solver's extension module, which has no public name in pneusim.solver
KNOWN_PRIVATE_IMPORTS = {("pneusim.plant", "pneusim.solver._cvode_compiled")}


@pytest.fixture(scope="module")
def graph():
    return grimp.build_graph(*PACKAGES)


def _contracts() -> list[dict]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]["contracts"]


def test_the_import_contracts_are_kept():
    if not LINT_IMPORTS.exists():
        pytest.skip(f"import-linter is not installed in this environment ({LINT_IMPORTS} missing)")
    run = subprocess.run([str(LINT_IMPORTS), "--config", str(ROOT / "pyproject.toml"), "--no-cache"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-6000:] + run.stderr[-2000:]
    assert f"{len(_contracts())} kept, 0 broken" in run.stdout


def test_every_module_has_a_layer(graph):
    layers = next(c for c in _contracts() if c["type"] == "layers")["layers"]
    placed = {name.strip() for layer in layers for name in layer.split("|")}
    top = {".".join(m.split(".")[:2]) for m in graph.modules if m.startswith("pneusim.")}
    assert sorted(top - placed) == [], "modules without a layer in pyproject.toml's layers contract"
    assert sorted(placed - top) == [], "layers naming modules that do not exist"


def _is_package(module: str) -> bool:
    return (ROOT / module.replace(".", "/")).is_dir()


def _package_of(module: str) -> str:
    """The package a module belongs to: itself for a package (its ``__init__``), else its parent."""
    return module if _is_package(module) else module.rpartition(".")[0]


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _imports(path: Path, module: str):
    """``(imported module, imported name or None, line)`` for every import of a file, relative ones resolved."""
    package = _package_of(module)
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, None, node.lineno
        elif isinstance(node, ast.ImportFrom):
            target = node.module or ""
            if node.level:
                parts = package.split(".")
                target = ".".join(parts[:len(parts) - node.level + 1] + ([node.module] if node.module else []))
            for alias in node.names:
                yield target, alias.name, node.lineno


def _modules():
    for root in PACKAGES:
        for path in sorted((ROOT / root).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            yield path, ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def test_no_private_name_is_imported_from_another_package():
    """``from ..x import _y``, or any name from ``..x._y``, where ``x`` is another package than the importer's."""
    found = []
    for path, module in _modules():
        own = _package_of(module)
        for target, name, line in _imports(path, module):
            if target.split(".")[0] not in PACKAGES:
                continue
            # the imported object lives in ``target`` when it is a package (a submodule or a name of its
            # __init__), else in the package around the module ``target``
            home = target if _is_package(target) else target.rpartition(".")[0]
            if home == own:
                continue
            common = 0
            while common < min(len(own.split(".")), len(target.split("."))) and \
                    own.split(".")[common] == target.split(".")[common]:
                common += 1
            private_path = [p for p in target.split(".")[common:] if _private(p)]
            if ((name and _private(name)) or private_path) and (module, target) not in KNOWN_PRIVATE_IMPORTS:
                found.append(f"{path.relative_to(ROOT)}:{line}: {name or target} from {target}")
    assert found == [], "private names imported across packages:\n" + "\n".join(found)


def test_no_import_circles(graph):
    circles = set()
    for module in sorted(graph.modules):
        for imported in graph.find_modules_directly_imported_by(module):
            chain = graph.find_shortest_chain(importer=imported, imported=module)
            if chain:
                circle = (module,) + tuple(chain[:-1])
                first = circle.index(min(circle))
                circles.add(circle[first:] + circle[:first])
    assert sorted(circles) == [], "import circles:\n" + "\n".join(" -> ".join(c + c[:1]) for c in sorted(circles))


def test_nothing_imports_the_package_root(graph):
    """``pneusim/__init__.py`` offers ``pneusim.diagnose`` lazily; a module importing the root would depend on
    everything the root may reach (the version lives in ``pneusim.version``)."""
    importers = sorted(graph.find_modules_that_directly_import("pneusim"))
    assert importers == []
