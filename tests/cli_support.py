"""Running ``lenticalib`` from the tests: in this process or as a real process.

:func:`run_main` calls :func:`lenticalib.cli.main` and returns ``(exit status, stdout, stderr)``:
a ``SystemExit`` (argparse's usage errors, ``--help``, ``--version``) becomes its status, and any
other exception escaping ``main`` -- what a user would see as a traceback -- fails the test.
:func:`run_process` runs ``python -m lenticalib`` for tests that need a real process (a display,
an emulator, signals, the interpreter's start-up).  ``conftest.py`` offers both as fixtures
(``cli`` and ``cli_process``); module- and session-scoped fixtures call the functions directly.
"""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
ERROR_PREFIX = "lenticalib: error: "


def run_main(*argv) -> tuple[int, str, str]:
    """``lenticalib ARGV`` in this process: (exit status, stdout, stderr); arguments go through ``str``."""
    from lenticalib.cli import main

    args = [str(a) for a in argv]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(args)
        except SystemExit as exc:  # argparse
            code = exc.code
        except Exception as exc:  # noqa: BLE001 -- anything but a clean exit is a bug
            pytest.fail(f"lenticalib {' '.join(args)} raised {type(exc).__name__}: {exc} "
                        f"(a traceback instead of one error line); stderr: {err.getvalue()!r}")
    return code, out.getvalue(), err.getvalue()


def run_process(*argv, env: dict | None = None, timeout: float = 600) -> subprocess.CompletedProcess:
    """``python -m lenticalib ARGV`` as a process in the repository root; stdout and stderr captured
    as text.  ``env`` sets variables over this process's environment (a value ``None`` unsets one)."""
    full_env = dict(os.environ)
    for name, value in (env or {}).items():
        if value is None:
            full_env.pop(name, None)
        else:
            full_env[name] = value
    return subprocess.run([sys.executable, "-m", "lenticalib", *map(str, argv)], capture_output=True, text=True,
                          cwd=REPO, env=full_env, timeout=timeout)


def one_error_line(err: str, source: object = None) -> str:
    """The one line of ``err``, which must start with ``lenticalib: error: `` (and ``SOURCE: `` after
    it when ``source`` is given); no traceback."""
    lines = err.strip().splitlines()
    assert len(lines) == 1, f"expected exactly one line on stderr, got {len(lines)}: {err!r}"
    prefix = ERROR_PREFIX if source is None else f"{ERROR_PREFIX}{source}: "
    assert lines[0].startswith(prefix), lines[0]
    assert "Traceback" not in err
    return lines[0]


def refused(*argv, source: object = None) -> str:
    """``lenticalib ARGV`` in this process must exit 2 with one error line (naming ``source`` first
    when given) and nothing else on stderr; the line is returned."""
    code, out, err = run_main(*argv)
    assert code == 2, (argv, code, out, err)
    return one_error_line(err, source)


def raises_one_line(fn, cls=None) -> str:
    """The text of the error ``fn()`` raises, which must be a ``cls`` (default: InputError) and one
    line: what the CLI would print after ``lenticalib: error: ``."""
    import pytest

    from lenticalib.core.errors import InputError

    with pytest.raises(cls or InputError) as info:
        fn()
    text = str(info.value)
    assert "\n" not in text, text
    return text
