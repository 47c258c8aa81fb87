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

import pytest

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


def _layers(container: str) -> list[str]:
    (layers,) = [c["layers"] for c in _config()["contracts"] if c.get("containers") == [container]]
    return layers


def test_the_package_top_level_holds_only_the_layers():
    layers = _layers("lenticalib")
    declared = {name.strip() for layer in layers for name in layer.split("|")}
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and p.name != "__pycache__"}
    files = {p.name for p in PACKAGE.iterdir() if p.is_file()}
    assert packages == declared, f"lenticalib/ holds {sorted(packages)}; the layer contract declares {sorted(declared)}"
    assert files == {"__init__.py", "__main__.py"}, f"lenticalib/ holds modules beside the layers: {sorted(files)}"


@pytest.mark.parametrize("layer", ["render", "calib"])
def test_render_and_calib_hold_only_their_stage_packages(layer):
    declared = {name.strip() for stage in _layers(f"lenticalib.{layer}") for name in stage.split("|")}
    folder = PACKAGE / layer
    packages = {p.name for p in folder.iterdir() if (p / "__init__.py").is_file()}
    files = {p.name for p in folder.glob("*.py")}
    assert packages == declared, f"lenticalib/{layer}/ holds {sorted(packages)}; its stage contract declares {sorted(declared)}"
    assert files == {"__init__.py"}, f"lenticalib/{layer}/ holds modules beside its stages: {sorted(files)}"


MAX_MODULES_PER_FOLDER = 20
MAX_MODULE_LINES = 450


def test_no_folder_holds_more_than_20_modules():
    crowded = {str(d.relative_to(ROOT)): n for d in [PACKAGE, *PACKAGE.rglob("*")] if d.is_dir()
               and (n := len(list(d.glob("*.py")))) > MAX_MODULES_PER_FOLDER}
    assert not crowded, f"folders of more than {MAX_MODULES_PER_FOLDER} modules (make stage packages): {crowded}"


def test_no_module_is_longer_than_450_lines():
    long = {str(p.relative_to(ROOT)): n for p in PACKAGE.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines (split them by job): {long}"


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


def _is_module(root: Path, dotted: str) -> bool:
    """Whether ``dotted`` names a module or package under ``root`` (not a name inside one)."""
    path = root.joinpath(*dotted.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def private_names_imported_across_modules(root: Path) -> list[str]:
    """``path:line module.name`` of each private name (leading underscore, dunders excepted) a lenticalib
    module takes from another lenticalib module: ``from m import _name`` or ``alias._name`` on an imported
    module, imports inside functions included.  A private submodule (``from pkg import _flags``) is a module,
    not a name, and is allowed."""
    found = []
    for path in sorted((root / "lenticalib").rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        package = parts[:-1]
        tree = ast.parse(path.read_text())
        modules: dict[str, str] = {}  # local alias -> dotted lenticalib module
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("lenticalib.") and alias.asname:
                        modules[alias.asname] = alias.name
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = ".".join(package[:len(package) - node.level + 1] + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                if base.split(".")[0] != "lenticalib":
                    continue
                for alias in node.names:
                    target = f"{base}.{alias.name}"
                    if _is_module(root, target):
                        modules[alias.asname or alias.name] = target
                    elif _private(alias.name):
                        found.append(f"{path.relative_to(root)}:{node.lineno} {target}")
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in modules and _private(node.attr)):
                found.append(f"{path.relative_to(root)}:{node.lineno} {modules[node.value.id]}.{node.attr}")
    return found


def test_no_module_imports_a_private_name_of_another():
    found = private_names_imported_across_modules(ROOT)
    assert not found, ("private names taken from another lenticalib module; give each a public name "
                       "(with a docstring) in the module that owns it:\n" + "\n".join(found))


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def module_import_graph(root: Path) -> dict[str, set[str]]:
    """``{module: modules it imports}`` over lenticalib, read from the AST, imports inside functions included.

    Relative imports are resolved; ``from pkg import name`` counts as an import of ``pkg.name`` when that
    is a module, else of ``pkg``.  A package's ``__init__`` importing its own submodules (its re-exports)
    is left out: a module that imports the package would otherwise close a cycle with every sibling.
    """
    paths = sorted((root / "lenticalib").rglob("*.py"))
    modules = {_module_name(p, root): p for p in paths}
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        is_package = path.name == "__init__.py"
        package = name.split(".") if is_package else name.split(".")[:-1]
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            for target in _imported_modules(node, package):
                if target.split(".")[0] != "lenticalib":
                    continue
                if isinstance(node, ast.ImportFrom) and target not in modules:
                    target = target.rsplit(".", 1)[0]
                while target not in modules and "." in target:
                    target = target.rsplit(".", 1)[0]
                if target == name or (is_package and target.startswith(name + ".")):
                    continue
                graph[name].add(target)
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in sorted(graph[node]):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return sorted(found)


def test_no_import_cycles_between_modules():
    cycles = import_cycles(module_import_graph(ROOT))
    assert not cycles, "import cycles between modules (imports inside functions included):\n" + "\n".join(
        " <-> ".join(c) for c in cycles)
