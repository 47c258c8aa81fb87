"""The package's shape: imports point only down the layers, and nothing sits beside the layers.

The rule is the ``[tool.importlinter]`` contracts in ``pyproject.toml`` (calib, render and device
use only core; sim may use core, calib and render; cli on top; core uses none of them); this
test runs them with import-linter, so the test command fails on an import that breaks them,
one made inside a function included.
"""

from __future__ import annotations

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
