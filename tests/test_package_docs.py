"""Every package's docstring lists what is in it: each module and subpackage by name.

A package docstring that says what a package holds goes stale as soon as a module is added or
moved; this keeps it true.
"""

import ast
from pathlib import Path

import pytest

import lenticalib

PACKAGE = Path(lenticalib.__file__).parent
PACKAGES = sorted(p.parent for p in PACKAGE.rglob("__init__.py") if "__pycache__" not in p.parts)


def _members(package: Path) -> list[str]:
    modules = [p.stem for p in package.glob("*.py") if p.stem not in ("__init__", "__main__")]
    subpackages = [p.name for p in package.iterdir() if (p / "__init__.py").is_file()]
    return sorted(modules + subpackages)


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: str(p.relative_to(PACKAGE.parent)))
def test_the_package_docstring_names_every_module_in_it(package):
    docstring = ast.get_docstring(ast.parse((package / "__init__.py").read_text())) or ""
    words = set(docstring.replace("`", " ").replace(",", " ").replace("(", " ").replace(")", " ")
                .replace("/", " ").replace(".py", " ").split())
    missing = [name for name in _members(package) if name not in words]
    assert missing == [], f"{package / '__init__.py'}: the docstring does not name {missing}"
