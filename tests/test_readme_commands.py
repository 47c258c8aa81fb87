"""Every command of the README runs, in order, as written (issues 47 and 48): a newcomer with no
hardware follows the page and every command ends in exit 0 with no warning they cannot act on.

The commands are read from README.md itself: every line of every ```bash block is one command (a
``# comment`` dropped), each ``&&`` step of it run in turn, ``CMD &`` started in the background.
A README with a command anywhere else (another kind of code block, an indented block, a command in
a sentence's code span) fails, as does a step of a program this test does not know: nothing is
left out silently.  They run in order in one temporary folder that sees the repository's
``fixtures`` and ``tools``; ``lenticalib`` (also ``.venv/bin/lenticalib``) and ``python`` run with
this interpreter.

What differs from the README is in four documented tables, each entry with its reason:

- :data:`PREPARED`: files the README takes as the reader's own (a unit's visual.json, a quilt, an
  avatar), written before the first command;
- :data:`SUBSTITUTIONS`: text replaced in a command: hardware by the emulators and the virtual panel
  the README itself names for running without hardware, and the sizes of the work that runs for
  minutes (panel, camera, Gaussians, frames) by small ones, only through the commands' own flags;
- :data:`DISPLAY`: a window or the panel's monitor replaced by the offscreen presenter;
- :data:`CHECKED`: steps this test cannot run inside a test, each checked another way (the pip
  installs resolved offline against this environment, which ``.ci/run`` installed with them; the
  test suite, which is where this test runs).

A warning is a stderr line holding ``warning`` (lenticalib's or Python's) or a traceback; each
one the README's commands print must be in :data:`ACTIONABLE` (it tells the reader what to do).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .cli_support import REPO

README = REPO / "README.md"
CI_RUN = REPO / ".ci" / "run"
MAX_LINES = 250  # a README a newcomer reads in five minutes (issue 47)
SMALL_PANEL = "--width 1280 --height 720 --views 16"
SUBSTITUTIONS = [  # (README text, replacement, why)
    ("--width 3840 --height 2160 --views 32", SMALL_PANEL,
     "a 1280x720, 16-view panel: photographing and fitting a 4K one takes minutes here"),
    ("--camera gphoto2", "--camera sim --resolution 1280x960 --subsamples 1",
     "no camera or panel: the virtual panel photographed by the virtual camera (the README's 'sim'), at a small size"),
    ("lkg-hid://04d8:ef7e", "lkg-emu://bench", "no unit here: the emulated unit the job's first command saves"),
    ("lenticalib emulate --flash panel.flash", "lenticalib emulate --flash panel.flash {PANEL}",
     "the emulated controller drives the panel calibrated above (smaller than the default: see the first entry)"),
    ("serial:///dev/ttyACM0", "{CONTROLLER}", "no controller here: the URL the emulator started in the job printed"),
    ("make_demo_avatar.py demo.npz", "make_demo_avatar.py demo.npz --count 5000",
     "5000 Gaussians: the demo's 100k take seconds a view to render on two cores"),
    ("--frames 90", "--frames 2", "two frames show the offline render runs; 90 take minutes here"),
]
DISPLAY = {  # subcommand: flags replacing the panel's monitor or --preview's window
    "play": "--display offscreen --frames 1",
    "show": "--display offscreen --interval 0.01",
}
WHY_DISPLAY = "no panel or window in a test: the offscreen presenter runs the same pipeline, one frame"
PIP = "pip install"
CHECKED = {  # a step's start -> how it is checked instead of run
    PIP: "no network in a test: pip resolves the same requirements offline (--dry-run --no-index) against this "
         "environment, which .ci/run installed with them: an extra or a requirement that is not there fails",
    ".venv/bin/python -m pytest": "the test suite this test is part of: the README's command must be .ci/run's",
}
SHELL = ("tools/install_display_deps.sh", "PYENV_VERSION=3.12.1 python3.12 -m venv .venv", "mkdir -p ",
         "source .venv/bin/activate")  # steps run as written by bash
PREPARED = {"visual.json": "a unit's calibration (a Portrait's, the tests' emulated unit)",
            "quilt_qs8x6a0.75.png": "a quilt of 8x6 tiles for a Portrait, small",
            "avatar.ply": "the reader's own 3DGS avatar, a small one"}
ACTIONABLE = {  # a warning the README's commands print -> what it tells the reader to do
    "the calibration record has no room for view_direction": "keep the profile file (device flash of a profile "
                                                             "that knows its direction)",
    "the profile does not say which way its views run": "the commands that find it, named in the warning "
                                                        "(the README's calibration links docs/calibration.md)",
}
COMMAND = re.compile(r"(lenticalib|python3?(\.\d+)?|pip|source|\.venv/bin/\S+|tools/\S+\.(py|sh))( |$)")
TIMEOUT_S = 600


def bash_lines(text: str) -> list[str]:
    """The commands of the ```bash blocks, in order, ``# comments`` dropped."""
    out, block = [], None
    for line in text.splitlines():
        if line.startswith("```"):
            block = line[3:].strip() if block is None else None
            continue
        if block == "bash" and line.strip():
            out.append(re.sub(r"\s+#.*$", "", line.strip()))
    return out


def commands_outside_bash_blocks(text: str) -> list[str]:
    """Commands a reader would run that are not in a ```bash block: other fenced blocks, indented
    blocks, and sentences' code spans that start like a command."""
    found, block, previous_blank = [], None, True
    for line in text.splitlines():
        if line.startswith("```"):
            block = line[3:].strip() if block is None else None
            if block not in (None, "bash"):
                found.append(line)
            continue
        if block is not None:
            continue
        if line.startswith("    ") and line.strip() and previous_blank:
            found.append(line)
        found += [span for span in re.findall(r"`([^`]+)`", line) if COMMAND.match(span)]
        previous_blank = not line.strip()
    return found


def ci_command() -> str:
    """The command .ci/run runs (its last line)."""
    return CI_RUN.read_text().strip().splitlines()[-1]


def plan(step: str) -> tuple[str, list[str] | str]:
    """How one README step runs: ("lenticalib"|"python"|"pip"|"shell"|"checked", argv or text).
    A step of no known kind fails."""
    for start in SHELL:
        if step.startswith(start):
            return "shell", step
    words = shlex.split(step)
    program = words[0]
    if program in ("lenticalib", ".venv/bin/lenticalib"):
        return "lenticalib", [sys.executable, "-m", "lenticalib", *words[1:]]
    if program in ("python", ".venv/bin/python") and words[1:3] != ["-m", "pytest"]:
        return "python", [sys.executable, *words[1:]]
    if program in ("pip", ".venv/bin/pip") and words[1] == "install":
        return "pip", [sys.executable, "-m", "pip", "install", "--dry-run", "--no-index", "--no-build-isolation",
                       *words[2:]]
    if step.startswith(".venv/bin/python -m pytest"):
        return "checked", step
    raise AssertionError(f"README step of a program this test does not run: {step!r}")


def substituted(command: str) -> str:
    for old, new, _ in SUBSTITUTIONS:
        command = command.replace(old, new)
    words = command.split()
    if len(words) > 1 and words[0] in ("lenticalib", ".venv/bin/lenticalib") and words[1] in DISPLAY:
        command = command.replace(" --preview", "").rstrip(" &") + " " + DISPLAY[words[1]]
    return command


def test_the_readme_is_short_and_every_command_is_in_a_bash_block_this_test_runs():
    text = README.read_text()
    assert len(text.splitlines()) < MAX_LINES, f"README.md has {len(text.splitlines())} lines"
    assert commands_outside_bash_blocks(text) == [], "commands the test does not run: put them in a ```bash block"
    lines = bash_lines(text)
    assert len(lines) >= 2 + 4 * 3, lines  # two set-up commands, four jobs of three to five commands
    for line in lines:
        for step in line.rstrip(" &").split(" && "):
            kind, _ = plan(step)  # fails for a step of no known kind
            if kind in ("pip", "checked"):  # not run as written: each has its reason
                assert any(key in step for key in CHECKED), step
    for old, _, why in SUBSTITUTIONS:
        assert any(old in line for line in lines), f"stale substitution {old!r} ({why})"


def test_the_set_up_commands_are_ci_runs():
    """The second set-up command is what .ci/run runs; the first installs the same way, without the test extra."""
    lines = bash_lines(README.read_text())
    assert lines[1] == ci_command()
    ci_install = [s for s in ci_command().split(" && ") if "pip install" in s or " -m venv " in s]
    first_install = [s for s in lines[0].split(" && ") if "pip install" in s or " -m venv " in s]
    assert first_install == [s.replace(" -q", "").replace("'.[test]'", ".") for s in ci_install]


def _env(work: Path) -> dict:
    env = dict(os.environ)
    env.update(LENTICALIB_EMULATOR_DIR=str(work / "emu"), XDG_STATE_HOME=str(work / "state"),
               XDG_RUNTIME_DIR=str(work / "run"), PYTHONPATH=os.pathsep.join(
                   [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))
    return env


def _prepare(work: Path) -> None:
    """PREPARED: the reader's own files."""
    import cv2
    import numpy as np

    from lenticalib.render.avatar.gaussians import Gaussians
    from lenticalib.render.avatar.ply import save_ply

    from .looking_glass_support import CELLS, visual_bytes

    (work / "visual.json").write_bytes(visual_bytes(CELLS))
    tiles = np.zeros((6 * 56, 8 * 42, 3), np.uint8)
    for k in range(48):  # tile k from the bottom-left, row by row, a colour of its own
        row, col = divmod(k, 8)
        tiles[(5 - row) * 56:(6 - row) * 56, col * 42:(col + 1) * 42] = (5 * k, 100, 200 - 4 * k)
    cv2.imwrite(str(work / "quilt_qs8x6a0.75.png"), tiles)
    rng = np.random.default_rng(5)
    n = 400
    save_ply(work / "avatar.ply", Gaussians(
        rng.normal(0, 0.05, (n, 3)).astype(np.float32), np.tile(np.float32([1, 0, 0, 0]), (n, 1)),
        np.full((n, 3), 0.01, np.float32), np.full(n, 0.8, np.float32), np.full((n, 1, 3), 0.5, np.float32)))


def _panel_flags(work: Path) -> str:
    """The emulated controller's panel: the one the README's calibration fitted (profile.json)."""
    profile = json.loads((work / "profile.json").read_text())
    return (f"--panel {profile['width']}x{profile['height']} --view-counts {profile['views']} "
            f"--subpixel-order {profile['subpixel_order']}")


def _warnings(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines()
            if ("warning" in line.lower() or "Traceback" in line) and not any(k in line for k in ACTIONABLE)]


@pytest.mark.slow
def test_every_readme_command_runs_in_order_with_no_warning_a_newcomer_cannot_act_on(tmp_path):
    work = tmp_path / "newcomer"
    (work / "run").mkdir(parents=True, mode=0o700)
    for name in ("fixtures", "tools"):
        os.symlink(REPO / name, work / name)
    _prepare(work)
    env, background, state, ran = _env(work), [], {}, []
    try:
        for line in bash_lines(README.read_text()):
            line = substituted(line)
            for step in line.split(" && "):
                if "{PANEL}" in step:
                    step = step.replace("{PANEL}", _panel_flags(work))
                if "{CONTROLLER}" in step:
                    assert "controller" in state, f"{step}: no emulator was started before it"
                    step = step.replace("{CONTROLLER}", state["controller"])
                kind, how = plan(step.rstrip(" &"))
                start = time.perf_counter()
                if kind == "checked":
                    assert line == ci_command(), line
                    ran.append(step)
                    continue
                if step.endswith("&"):
                    proc = subprocess.Popen(how, cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                            text=True, start_new_session=True)
                    background.append(proc)
                    state["controller"] = proc.stdout.readline().strip()  # "serial:///dev/pts/N"
                    assert state["controller"].startswith("serial://"), (step, state["controller"], proc.poll())
                    ran.append(step)
                    continue
                if kind == "shell":
                    argv, cwd = ["bash", "-c", how], work
                else:  # pip: '.' is the repository
                    argv, cwd = how, (REPO if kind == "pip" else work)
                result = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
                print(f"{time.perf_counter() - start:6.1f} s  {step}")  # shown with -s
                assert result.returncode == 0, f"{step}\n{result.stdout[-2000:]}\n{result.stderr[-3000:]}"
                # pip included: "does not provide the extra 'avatar'" is a warning with exit 0
                assert not _warnings(result.stderr), f"{step}\n{result.stderr[-3000:]}"
                ran.append(step)
    finally:
        for proc in background:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(timeout=30)
    steps = [s for line in bash_lines(README.read_text()) for s in line.split(" && ")]
    assert len(ran) == len(steps), "a README step did not run"
