"""docs/architecture.md is drawn from the code, and this keeps it true.

Every stage package of every layer is named on the page, the stage contracts of ``pyproject.toml``
are quoted word for word, every registry of choices by name is in its table, and every module,
folder or module attribute the page names in backquotes exists.
"""

from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "lenticalib"
DOC = ROOT / "docs" / "architecture.md"
LAYERS = ("core", "calib", "render", "device", "sim", "cli")


def _text() -> str:
    return DOC.read_text()


def _stage_packages() -> list[str]:
    return sorted(f"{layer}/{p.name}/" for layer in LAYERS for p in (PACKAGE / layer).iterdir()
                  if (p / "__init__.py").is_file())


@pytest.mark.parametrize("package", _stage_packages())
def test_the_page_names_every_stage_package(package):
    assert f"`{package}" in _text(), f"docs/architecture.md does not name `{package}`"


def test_the_page_quotes_every_stage_contract():
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    for contract in contracts:
        if contract["type"] == "layers" and contract["containers"] != ["lenticalib"]:
            assert f"`{contract['name']}`" in _text(), f"docs/architecture.md does not quote {contract['name']!r}"


def test_the_page_lists_every_registry():
    names = set()
    for path in PACKAGE.rglob("*.py"):
        for node in ast.parse(path.read_text()).body:
            if (isinstance(node, ast.Assign) and isinstance(node.value, ast.Call)
                    and getattr(node.value.func, "id", None) == "Registry"):
                names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    assert names, "no registry found: the test no longer reads the code"
    missing = sorted(n for n in names if f"| `{n}`" not in _text())
    assert not missing, f"docs/architecture.md's registry table lacks {missing}"


REFERENCE = re.compile(r"`((?:%s)(?:[./]\w+)*(?:\.py|/)?)`" % "|".join(LAYERS))


def _top_level_names(path: Path) -> set[str]:
    names = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(t.id for t in targets if isinstance(t, ast.Name))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    return names


def _exists(reference: str) -> bool:
    """Whether ``reference`` (``calib/capture/``, ``core/profile.py``, ``render.pipeline.live.play_avatar``)
    names a folder, a module, or a module's top-level name under lenticalib/."""
    if reference.endswith("/"):
        return (PACKAGE / reference).is_dir()
    if reference.endswith(".py"):
        return (PACKAGE / reference).is_file()
    parts = re.split(r"[./]", reference)
    for k in range(len(parts), 0, -1):
        base = PACKAGE.joinpath(*parts[:k])
        module = base / "__init__.py" if base.is_dir() else base.with_suffix(".py")
        if module.is_file():
            rest = parts[k:]
            return not rest or (len(rest) <= 2 and rest[0] in _top_level_names(module))
    return False


def test_every_module_the_page_names_exists():
    references = sorted(set(REFERENCE.findall(_text())))
    assert len(references) > 30, "the page names few modules: the pattern no longer reads it"
    stale = [r for r in references if not _exists(r)]
    assert not stale, f"docs/architecture.md names modules that do not exist: {stale}"
