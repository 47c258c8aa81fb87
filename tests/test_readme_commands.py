"""The README's commands, run in order as written (issue 48): a newcomer with no hardware follows
each section and every command ends in exit 0 with no warning they cannot act on.

The commands are read from README.md itself: the indented code blocks of the sections a newcomer
runs (:data:`SECTIONS`; the set-up is what the test environment already is), each line one
command, ``# comments`` and ``[optional parts]`` dropped, ``lenticalib`` and ``.venv/bin/...``
run with this interpreter, ``CMD &`` started in the background.  They run in order in one
temporary folder holding a copy of ``fixtures/panel-4k-32.json`` and the repository's ``tools``.

What differs from the README is in three documented tables, each entry with its reason:

- :data:`PREPARED`: files a section takes as given (the reader's own avatar, a unit's visual.json,
  the profile an earlier section makes), written before the section runs;
- :data:`SUBSTITUTIONS`: text replaced in a section's commands: hardware by the emulators the
  README names for running without hardware, a display by ``--headless``, and the sizes of the
  work that runs for minutes (frames, minutes of training, camera resolution) by small ones,
  only through the commands' own flags;
- :data:`SKIPPED`: commands that need what no emulator gives (a second photographed capture set).

A warning is a stderr line holding ``warning`` (lenticalib's or Python's) or a traceback; each
one the README's commands print must be in :data:`ACTIONABLE` (it tells the reader what to do).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .cli_support import REPO

README = REPO / "README.md"
SECTIONS = ("Use a Looking Glass", "Panel controllers (device layer)", "Calibrate the camera",
            "Profiles for any viewing distance", "Drive an avatar", "Check an avatar for the panel",
            "Drive the avatar from a camera")
NO_DISPLAY = "no panel or display in a test: --headless runs the same pipeline and presents nothing, one frame"
SUBSTITUTIONS = {  # section: [(README text, replacement, why)]
    "Use a Looking Glass": [
        ("lkg-hid://04d8:ef7e", "lkg-emu://bench", "no unit here: the emulated unit the section names "
                                                   "('lenticalib emulate --looking-glass visual.json --name bench')"),
        ("--profile lkg.json", "--profile lkg.json --headless --frames 1", NO_DISPLAY)],
    "Panel controllers (device layer)": [
        ("serial:///dev/pts/3", "{EMULATOR_URL}", "the URL the emulator started by the first command prints")],
    "Calibrate the camera": [
        ("lenticalib show board/board.png", "lenticalib simulate board --resolution 1600x1200 --seed 1",
         "no panel or camera: the virtual camera photographs the board into board/captures (README: 'lenticalib "
         "simulate DIR ... (a camera patterns folder: its board)'), at a small size")],
    "Drive an avatar": [("--preview", "--headless --frames 1", NO_DISPLAY)],
    "Drive the avatar from a camera": [
        ("make_driver_demo.py driver-demo", "make_driver_demo.py driver-demo --frames 64 --test-frames 8",
         "the demo's 7800 frames take about 7 minutes to render"),
        ("--minutes 15", "--minutes 0.05 --epochs 1", "15 minutes of training; one short epoch shows it runs"),
        ("--preview", "--headless --frames 1", NO_DISPLAY)],
}
SKIPPED = {  # README command (start) -> why it cannot run here
    "lenticalib fit cal -o profile.json --camera camera.cameramodel": "needs two capture sets photographed from two "
    "distances ('cal' and 'cal-far'); 'Calibrating a panel' runs the fit with no hardware",
}
# the data-sheet route of "Profiles for any viewing distance" is given in its text, not in a code
# block: the test runs it as the README writes it, with the data sheet's numbers for its MM
DATA_SHEET = re.compile(r"`(lenticalib profile set-physical P [^`]*)`")
DATA_SHEET_VALUES = {"--pixel-pitch": "0.1796", "--gap": "2.0", "--design-distance": "750", "--lens-pitch": "0.98",
                     "--view-cone": "40"}
ACTIONABLE = {  # a warning the README's commands print -> what it tells the reader to do
    "the calibration record has no room for view_direction": "keep the profile file (device flash of a profile "
                                                             "that knows its direction)",
}
TIMEOUT_S = 900


def readme_sections() -> dict[str, str]:
    """{level-2 heading: its text (subsections included)} of README.md."""
    sections, name = {}, None
    for line in README.read_text().splitlines():
        if line.startswith("## "):
            name = line[3:].strip()
            sections[name] = ""
        elif name is not None:
            sections[name] += line + "\n"
    return sections


def code_lines(text: str) -> list[str]:
    """The commands of a section's indented code blocks (4 spaces after a blank line), comments and
    ``[optional]`` parts dropped."""
    out, in_block, previous_blank = [], False, True
    for line in text.splitlines():
        if line.startswith("    ") and (in_block or previous_blank):
            in_block = True
            command = re.sub(r"\s+#.*$", "", line.strip())
            command = re.sub(r"\s*\[[^\]]*\]", "", command)
            if command:
                out.append(command)
        elif line.strip():
            in_block = False
        previous_blank = not line.strip()
    return out


def _argv(command: str) -> list[str]:
    words = shlex.split(command)
    if words[0] in ("lenticalib", ".venv/bin/lenticalib"):
        return [sys.executable, "-m", "lenticalib", *words[1:]]
    if words[0] in ("python", ".venv/bin/python"):
        return [sys.executable, *words[1:]]
    raise AssertionError(f"README command of an unknown program: {command}")


def _warnings(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines()
            if ("warning" in line.lower() or "Traceback" in line) and not any(k in line for k in ACTIONABLE)]


def _prepare(section: str, work: Path) -> None:
    """PREPARED: what a section takes as given."""
    if section == "Use a Looking Glass":  # a unit's visual.json (a Portrait's, as the tests' emulated unit)
        from .looking_glass_support import CELLS, visual_bytes

        (work / "visual.json").write_bytes(visual_bytes(CELLS))
        subprocess.run([sys.executable, "-m", "lenticalib", "emulate", "--looking-glass", "visual.json", "--name",
                        "bench"], cwd=work, env=_env(work), check=True, capture_output=True)
        _small_avatar(work / "avatar.ply")  # the reader's own avatar
    elif section == "Calibrate the camera":  # the profile 'Calibrating a panel' fits: the bundled one
        shutil.copy(work / "fixtures" / "panel-4k-32.json", work / "profile.json")


PREPARED = {"Use a Looking Glass": "visual.json of a unit, emulated as lkg-emu://bench (the section's no-hardware "
                                   "route); avatar.ply, the reader's avatar (a small one)",
            "Calibrate the camera": "profile.json, which 'Calibrating a panel' fits (the bundled profile)"}


def _small_avatar(path: Path) -> None:
    import numpy as np

    from lenticalib.render.avatar.gaussians import Gaussians
    from lenticalib.render.avatar.ply import save_ply

    rng = np.random.default_rng(5)
    n = 400
    save_ply(path, Gaussians(rng.normal(0, 0.05, (n, 3)).astype(np.float32), np.tile(np.float32([1, 0, 0, 0]), (n, 1)),
                             np.full((n, 3), 0.01, np.float32), np.full(n, 0.8, np.float32),
                             np.full((n, 1, 3), 0.5, np.float32)))


def _env(work: Path) -> dict:
    env = dict(os.environ)
    env.update(LENTICALIB_EMULATOR_DIR=str(work / "emu"), XDG_STATE_HOME=str(work / "state"))
    return env


def _commands(sections: dict) -> list[tuple[str, str]]:
    """(section, command) in README order, substituted; SKIPPED ones left out."""
    out = []
    for section in SECTIONS:
        text = sections[section]
        lines = code_lines(text)
        assert lines, f"README section {section!r} has no commands"
        if section == "Profiles for any viewing distance":
            sheet = DATA_SHEET.search(text)
            assert sheet, "the data-sheet route (profile set-physical) is gone from the README"
            command = sheet.group(1).replace(" P ", " profile.json ", 1)
            for flag, value in DATA_SHEET_VALUES.items():
                command = command.replace(f"{flag} MM", f"{flag} {value}").replace(f"{flag} DEG", f"{flag} {value}")
            lines.insert(0, command)
        for line in lines:
            if any(line.startswith(s) for s in SKIPPED):
                continue
            for old, new, _ in SUBSTITUTIONS.get(section, []):
                line = line.replace(old, new)
            out.append((section, line))
    return out


def test_the_tables_name_only_readme_text():
    """Every substitution and skip names text the README's commands hold (none is stale)."""
    sections = readme_sections()
    for section in SECTIONS:
        assert section in sections, f"README section {section!r} is gone"
        lines = code_lines(sections[section])
        for old, _, _ in SUBSTITUTIONS.get(section, []):
            assert any(old in line for line in lines), (section, old)
    every = [line for s in SECTIONS for line in code_lines(sections[s])]
    for start in SKIPPED:
        assert any(line.startswith(start) for line in every), start


@pytest.mark.slow
def test_the_readme_commands_run_in_order_with_no_warning_a_newcomer_cannot_act_on(tmp_path):
    work = tmp_path / "newcomer"
    (work / "fixtures").mkdir(parents=True)
    shutil.copy(REPO / "fixtures" / "panel-4k-32.json", work / "fixtures")
    os.symlink(REPO / "tools", work / "tools")
    background, emulator_url, done = [], None, set()
    try:
        for section, command in _commands(readme_sections()):
            if section not in done:
                _prepare(section, work)
                done.add(section)
            if emulator_url is not None:
                command = command.replace("{EMULATOR_URL}", emulator_url)
            if command.endswith("&"):
                proc = subprocess.Popen(_argv(command[:-1]), cwd=work, env=_env(work), stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, text=True, start_new_session=True)
                background.append(proc)
                emulator_url = proc.stdout.readline().strip()  # "serial:///dev/pts/N"
                assert emulator_url.startswith("serial://"), (command, emulator_url, proc.poll())
                continue
            start = time.perf_counter()
            result = subprocess.run(_argv(command), cwd=work, env=_env(work), capture_output=True, text=True,
                                    timeout=TIMEOUT_S)
            print(f"{time.perf_counter() - start:6.1f} s  [{section}] {command}")  # shown with -s
            assert result.returncode == 0, f"[{section}] {command}\n{result.stdout[-2000:]}\n{result.stderr[-3000:]}"
            assert not _warnings(result.stderr), f"[{section}] {command}\n{result.stderr[-3000:]}"
    finally:
        for proc in background:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(timeout=30)
