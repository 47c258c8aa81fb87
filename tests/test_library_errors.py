"""Library errors name what the library knows (an argument, a field, a file); only the CLI speaks of flags.

Every string in a ``raise ...Error(...)`` outside ``lenticalib/cli`` (the message, ``source=``,
``hint=``) is read with ``ast``, and every whole ``"--flag"`` handed on as an argument or a default
(a source for a helper to raise with); a ``--flag`` in one fails the test, listing where.  A hint may
still tell the user to run a command (``'lenticalib fit DIR --camera M'``) or another program
(``'gphoto2 --auto-detect'``): those commands are taken out before looking.  The CLI maps the
library's names to its flags (:mod:`lenticalib.cli.shared.flags`).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import lenticalib

PACKAGE = Path(lenticalib.__file__).parent
FLAG = re.compile(r"(?<![\w-])--[a-z][\w-]*")
WHOLE_FLAG = re.compile(r"--[a-z][\w-]*(?: [\w-]+)?")
COMMAND = re.compile(r"\b(?:lenticalib|gphoto2|pip)\s[^'()]*")  # a command to run, with its own flags


def flags_in(text: str) -> list[str]:
    """The ``--flag`` words in ``text``, outside the commands it tells the user to run."""
    return FLAG.findall(COMMAND.sub("", text))


def _strings(node: ast.AST):
    for sub in ast.walk(node):
        if isinstance(sub, ast.Constant) and isinstance(sub.value, str):
            yield sub.value


def flagged_raises(source: str, filename: str = "<string>") -> list[str]:
    """``file:line: --flag`` for each flag in the strings of an error made in ``source``: a call of
    ``...Error(...)`` (raised, returned or kept), or any call's ``source=`` or ``hint=``."""
    found = []
    for node in ast.walk(ast.parse(source, filename)):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
        parts = [k.value for k in node.keywords if k.arg in ("source", "hint")]
        if name.endswith("Error"):
            parts = [*node.args, *(k.value for k in node.keywords)]
        for text in (s for part in parts for s in _strings(part)):
            found += [f"{filename}:{node.lineno}: {flag}" for flag in flags_in(text)]
    return found


def flag_arguments(source: str, filename: str = "<string>") -> list[str]:
    """``file:line: --flag`` for each whole ``--flag`` string given as a call's argument (a source
    handed to a helper: ``_number(fov, "--fov")``), a parameter's default or a name's value.

    A flag of another program passes where the call also holds it in a list (the command line
    it runs: ``self._run(["--auto-detect"], "--auto-detect")``).
    """
    found = []

    def check(node, line):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and WHOLE_FLAG.fullmatch(node.value):
            found.append(f"{filename}:{line}: {node.value}")

    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, ast.Call):
            listed = {s for arg in node.args if isinstance(arg, ast.List) for s in _strings(arg)}
            for arg in [*node.args, *(k.value for k in node.keywords)]:
                if not (isinstance(arg, ast.Constant) and arg.value in listed):
                    check(arg, node.lineno)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for default in [*node.args.defaults, *node.args.kw_defaults]:
                check(default, node.lineno)
        elif isinstance(node, ast.Assign):
            check(node.value, node.lineno)
    return found


def library_files() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "cli" not in p.relative_to(PACKAGE).parts)


def test_the_scan_sees_a_flag_in_a_message_source_and_hint():
    code = ("def f(x):\n"
            "    raise InputError(f'bad {x}', source='--views', hint='use --views 8')\n"
            "    raise errors.ProfileError('pass --dpi ' f'{x}')\n"
            "    raise InputError('bad', source='views', hint=\"run 'lenticalib fit DIR --camera M'\")\n"
            "    raise InputError('bad', source='camera', hint=\"as 'gphoto2 --auto-detect' lists it\")\n"
            "    return bad(x, hint='or use --force')\n")
    assert flagged_raises(code) == ["<string>:2: --views", "<string>:2: --views", "<string>:3: --dpi",
                                    "<string>:6: --force"]


def test_the_scan_sees_a_flag_handed_on_as_a_source():
    code = ("def f(x, source='--compensate'):\n"
            "    fov = _number(x, '--fov', 'give degrees')\n"
            "    label = '--dpi'\n"
            "    return run(['--auto-detect'], '--auto-detect'), fov, label\n")
    assert sorted(flag_arguments(code)) == ["<string>:1: --compensate", "<string>:2: --fov", "<string>:3: --dpi"]


def test_the_cli_says_its_flags_for_the_library_names():
    from lenticalib.cli.shared.flags import with_flags
    from lenticalib.core.errors import InputError

    flags = {"camera": "--camera", "display": "--display", "view_size": "--view-size"}
    error = with_flags(InputError("option 'timeout' must be positive", source="camera sim",
                                  hint="e.g. `camera` sim:7 on the `display` of view_size"), flags)
    assert str(error) == ("--camera sim: option 'timeout' must be positive (e.g. --camera sim:7 on the --display "
                          "of --view-size)")
    assert with_flags(InputError("bad", source="cameras x"), flags).source == "cameras x"  # a whole word only


def test_library_errors_name_no_command_line_flags():
    files = library_files()
    found = [hit for path in files for scan in (flagged_raises, flag_arguments)
             for hit in scan(path.read_text(encoding="utf-8"), str(path.relative_to(PACKAGE.parent)))]
    assert len(files) > 100
    assert not found, "library errors that name CLI flags:\n" + "\n".join(found)
