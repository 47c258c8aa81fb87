"""The package's shape: imports point only down the layers, and nothing sits beside the layers.

The rule is the ``[tool.importlinter]`` contracts in ``pyproject.toml`` (calib, render and device
use only core; sim may use core, calib and render; cli on top; core uses none of them); this
test runs them with import-linter, so the test command fails on an import that breaks them,
one made inside a function included.  Imports between packages sit at the module top; one inside
a function (a heavy optional dependency, a cycle) carries a ``# lazy: <reason>`` comment.
"""

from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "lenticalib"


def _config() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]


def test_imports_keep_the_layer_contracts(capsys):
    from importlinter import api  # noqa: F401  (configures import-linter)
    from importlinter.application import use_cases

    result = use_cases.lint_imports(config_filename=str(ROOT / "pyproject.toml"), cache_dir=None, no_logo=True)
    report = capsys.readouterr().out
    assert result == use_cases.SUCCESS, report


def test_the_package_top_level_holds_only_the_layers():
    (layers,) = [c["layers"] for c in _config()["contracts"] if c["type"] == "layers"]
    declared = {name.strip() for layer in layers for name in layer.split("|")}
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and p.name != "__pycache__"}
    files = {p.name for p in PACKAGE.iterdir() if p.is_file()}
    assert packages == declared, f"lenticalib/ holds {sorted(packages)}; the layer contract declares {sorted(declared)}"
    assert files == {"__init__.py", "__main__.py"}, f"lenticalib/ holds modules beside the layers: {sorted(files)}"


LAZY_MARKER = re.compile(r"#\s*lazy:\s*\S")


def _imported_modules(node: ast.Import | ast.ImportFrom, package: list[str]) -> list[str]:
    """The dotted modules (or module attributes) an import statement in ``package`` names."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if node.level:
        base = ".".join(package[:len(package) - node.level + 1] + ([node.module] if node.module else []))
    else:
        base = node.module or ""
    return [f"{base}.{alias.name}" for alias in node.names]


def function_level_cross_package_imports(root: Path) -> list[str]:
    """``path:line target`` of each import, inside a function of a module under calib, render, device
    or sim, of a lenticalib package other than the module's own that has no ``# lazy:`` comment."""
    found = []
    for layer in ("calib", "render", "device", "sim"):
        for path in sorted((root / "lenticalib" / layer).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            package = parts[:-1]
            source = path.read_text()
            lines = source.splitlines()
            for function in ast.walk(ast.parse(source)):
                if not isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    continue
                for node in ast.walk(function):
                    if not isinstance(node, (ast.Import, ast.ImportFrom)):
                        continue
                    targets = [t for t in _imported_modules(node, package)
                               if t.split(".")[0] == "lenticalib" and t.split(".")[1:2] != [layer]]
                    text = "\n".join(lines[node.lineno - 1:node.end_lineno])
                    if targets and not LAZY_MARKER.search(text):
                        found.append(f"{path.relative_to(root)}:{node.lineno} {', '.join(targets)}")
    return found


def test_imports_between_packages_sit_at_the_module_top():
    found = function_level_cross_package_imports(ROOT)
    assert not found, ("imports of another lenticalib package inside a function; move them to the module top, "
                       "or mark a needed one '# lazy: <reason>':\n" + "\n".join(found))
