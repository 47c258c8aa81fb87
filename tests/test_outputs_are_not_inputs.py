"""Inputs are never outputs: every subcommand, run with its output naming one of its own inputs.

The subcommands are read from ``lenticalib.cli.build_parser()`` (a command or subcommand added
later without a line here fails :func:`test_every_subcommand_is_accounted_for`).  Each command
that writes has cases that name one of its inputs as its output -- the same path, a symbolic link
to it, a hard link to it (the three cases of issue 45 all three ways), an input folder's file, a
folder to be replaced that holds an input -- and each must end in exit 2 and one error line
saying so, before any work, with every file in the test folder byte-identical and nothing added.
Commands that write no file, and those that by design write what they are given (the profile
editors, the emulator's state, a device), are listed with the reason.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from lenticalib.cli import build_parser

from .cli_support import refused

REPO = Path(__file__).resolve().parent.parent
FIXTURE = REPO / "fixtures" / "capture-demo"
SMALL_PROFILE = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4, "width": 640,
                 "height": 360, "subpixel_order": "RGB"}
PHRASE = "one of this command's inputs"

# commands that write no file
WRITE_NOTHING = {
    "profile show": "prints the profile",
    "profile validate": "prints a verdict",
    "profile compare": "prints the differences",
    "crosstalk check": "prints a verdict",
    "show": "shows images on the panel",
    "play": "drives the panel live",
    "device list": "prints the units found",
    "device info": "prints a unit's identity",
    "device verify": "compares a unit's record with a profile",
}
# commands whose output is, by design, what they are given (so is emulate's --flash image, its own state)
BY_DESIGN = {
    "profile set-direction": "edits the profile it is given, atomically",
    "profile set-physical": "edits the profile it is given, atomically",
    "device flash": "writes the unit's record (an emulator's image); the profile is only read",
}
# commands that take no output path that could name an input
NO_OUTPUT_PATH = {
    "capture": "writes photos only under new names in DIR/captures (an existing one is kept, or moved to "
               "rejected/ with --restart); the patterns beside them are read",
    "camera simulate": "reads no file: the whole folder is its own output, staged",
}


def _subcommands(parser, prefix=()) -> list[str]:
    """Every leaf command of ``parser``, as 'command subcommand'."""
    found = []
    for action in parser._actions:  # argparse keeps no public list of a parser's subparsers
        if isinstance(getattr(action, "choices", None), dict):
            for name, sub in action.choices.items():
                found += _subcommands(sub, (*prefix, name))
    return found or [" ".join(prefix)]


def _tree(folder: Path) -> dict:
    """Every entry under ``folder``: a link's target, a file's bytes, None for a folder."""
    return {str(p.relative_to(folder)): (("link", os.readlink(p)) if p.is_symlink() else
                                         None if p.is_dir() else p.read_bytes())
            for p in sorted(folder.rglob("*"))}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """Small real inputs, copied into each test's folder: a profile, a visual.json, a quilt and
    its views, a demo avatar, a background image, a pattern folder and a scene."""
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.files.imageio import write_image
    from lenticalib.core.looking_glass.convert import export_visual_json
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.core.profile import load_profile
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig
    from lenticalib.sim.scene import random_scene

    folder = tmp_path_factory.mktemp("made")
    (folder / "p.json").write_text(json.dumps(SMALL_PROFILE))
    export_visual_json(load_profile(folder / "p.json"), folder / "visual.json", dpi=280.0)
    rng = np.random.default_rng(0)
    views = rng.integers(0, 256, (8, 36, 64, 3), dtype=np.uint8)
    quilt = np.concatenate([np.concatenate(list(views[r * 4:(r + 1) * 4]), axis=1) for r in (1, 0)], axis=0)
    write_image(folder / "q_qs4x2a1.7778.png", quilt)
    (folder / "views").mkdir()
    for i, view in enumerate(views):
        write_image(folder / "views" / f"view-{i:02d}.png", view)
    write_image(folder / "bg.png", views[0])
    save_rig(folder / "demo.npz", make_demo_avatar(seed=1, count=2000))
    write_patterns(folder / "set", design_patterns(640, 360, 8))
    scene = random_scene(9, width=640, height=360, resolution=(1250, 800))
    (folder / "scene.json").write_text(json.dumps(scene.to_dict()))
    return folder


def _copy(made: Path, tmp: Path, *names: str) -> None:
    for name in names:
        (shutil.copytree if (made / name).is_dir() else shutil.copy2)(made / name, tmp / name)


def _linked(tmp: Path, target: str, how: str, name: str) -> str:
    """The output path for ``how``: the input itself, a symbolic link to it, or a hard link to it."""
    if how == "same":
        return str(tmp / target)
    (os.symlink if how == "symlink" else os.link)(tmp / target, tmp / name)
    return str(tmp / name)


def _emulator(tmp: Path) -> Path:
    return tmp / "emu"


# ---------------------------------------------------------------------------------------------
# the cases: command -> {case id: make(made, tmp) -> argv}; every file the case makes is in tmp
# ---------------------------------------------------------------------------------------------

def _import_lkg(how):
    def make(made, tmp):
        _copy(made, tmp, "visual.json")
        return ["profile", "import-lkg", tmp / "visual.json", "--views", 8, "-o", _linked(tmp, "visual.json", how,
                                                                                          "out.json")]
    return make


def _export_lkg(how):
    def make(made, tmp):
        _copy(made, tmp, "p.json")
        return ["profile", "export-lkg", tmp / "p.json", "--dpi", 280, "-o", _linked(tmp, "p.json", how, "out.json")]
    return make


def _encode_quilt(how):
    def make(made, tmp):
        _copy(made, tmp, "p.json", "q_qs4x2a1.7778.png")
        return ["encode", "--profile", tmp / "p.json", "--quilt", tmp / "q_qs4x2a1.7778.png",
                "-o", _linked(tmp, "q_qs4x2a1.7778.png", how, "raster.png")]
    return make


def _device_read_drive(made, tmp):
    (tmp / "drive" / "LKG_calibration").mkdir(parents=True)
    shutil.copy2(made / "visual.json", tmp / "drive" / "LKG_calibration" / "visual.json")
    return ["device", "read", f"lkg-drive://{tmp / 'drive'}", "--views", 8,
            "-o", tmp / "drive" / "LKG_calibration" / "visual.json"]


def _device_read_lkg_emu(made, tmp):
    from lenticalib.device.emulator.looking_glass import create_unit

    create_unit("unit", (made / "visual.json").read_bytes())
    return ["device", "read", "lkg-emu://unit", "--views", 8, "-o", _emulator(tmp) / "unit.lkg"]


def _device_read_emu(made, tmp):
    from lenticalib.device.emulator.controller import ensure_image

    ensure_image(_emulator(tmp) / "bench.flash")
    return ["device", "read", "emu://bench", "-o", _emulator(tmp) / "bench.flash"]


def _emulate_looking_glass(made, tmp):
    shutil.copy2(made / "visual.json", _emulator(tmp) / "lkg.lkg")
    return ["emulate", "--looking-glass", _emulator(tmp) / "lkg.lkg"]


def _crosstalk_set(tmp):
    (tmp / "xt" / "captures").mkdir(parents=True)
    (tmp / "xt" / "patterns.json").write_text('{"a crosstalk pattern set": true}')
    (tmp / "xt" / "captures" / "b0.jpg").write_bytes(b"a photo")
    return tmp / "xt"


def _fit_set(made, tmp):
    shutil.copytree(FIXTURE, tmp / "cal")
    return tmp / "cal"


def _photos(tmp):
    (tmp / "photos").mkdir()
    for name in ("a.jpg", "b.jpg"):
        (tmp / "photos" / name).write_bytes(b"a photo of the board " + name.encode())
    return tmp / "photos"


def _simulate_link(made, tmp):
    _copy(made, tmp, "set")
    (tmp / "set" / "simulation.json").symlink_to(tmp / "set" / "patterns.json")
    return ["simulate", tmp / "set", "--seed", 1, "--resolution", "1250x800", "--subsamples", 1]


def _simulate_scene(made, tmp):
    _copy(made, tmp, "set")
    shutil.copy2(made / "scene.json", tmp / "set" / "simulation.json")
    return ["simulate", tmp / "set", "--scene", tmp / "set" / "simulation.json"]


CASES = {
    "encode": {
        "quilt": _encode_quilt("same"),
        "quilt by a symbolic link": _encode_quilt("symlink"),
        "quilt by a hard link": _encode_quilt("hardlink"),
        "profile": lambda made, tmp: (_copy(made, tmp, "p.json", "views"),
                                      ["encode", "--profile", tmp / "p.json", "--views-dir", tmp / "views",
                                       "-o", tmp / "p.json"])[1],
        "a view of --views-dir": lambda made, tmp: (_copy(made, tmp, "p.json", "views"),
                                                    ["encode", "--profile", tmp / "p.json", "--views-dir",
                                                     tmp / "views", "-o", tmp / "views" / "view-03.png"])[1],
        "--compensate": lambda made, tmp: (_copy(made, tmp, "p.json", "views"),
                                           (tmp / "crosstalk.png").write_bytes(b"a crosstalk file"),
                                           ["encode", "--profile", tmp / "p.json", "--views-dir", tmp / "views",
                                            "--compensate", tmp / "crosstalk.png",
                                            "-o", tmp / "crosstalk.png"])[2],
    },
    "profile import-lkg": {
        "visual.json": _import_lkg("same"),
        "visual.json by a symbolic link": _import_lkg("symlink"),
        "visual.json by a hard link": _import_lkg("hardlink"),
    },
    "profile export-lkg": {
        "profile": _export_lkg("same"),
        "profile by a symbolic link": _export_lkg("symlink"),
        "profile by a hard link": _export_lkg("hardlink"),
    },
    "profile retarget": {
        "profile": lambda made, tmp: (_copy(made, tmp, "p.json"),
                                      ["profile", "retarget", tmp / "p.json", "--distance", 900,
                                       "-o", tmp / "p.json"])[1],
    },
    "patterns": {
        "--direction profile": lambda made, tmp: (_copy(made, tmp, "p.json"),
                                                  ["patterns", "--direction", "--profile", tmp / "p.json",
                                                   "-o", tmp / "p.json"])[1],
    },
    "simulate": {
        "simulation.json, a link to patterns.json": _simulate_link,
        "--scene as simulation.json": _simulate_scene,
    },
    "fit": {
        "patterns.json": lambda made, tmp: ["fit", _fit_set(made, tmp), "-o", tmp / "cal" / "patterns.json"],
        "a photo": lambda made, tmp: ["fit", _fit_set(made, tmp), "-o", tmp / "cal" / "captures" / "x0-0.jpg"],
        "--report holding the set": lambda made, tmp: ["fit", _fit_set(made, tmp), "-o", tmp / "profile.json",
                                                       "--report", tmp / "cal"],
        "--camera": lambda made, tmp: ((tmp / "c.cameramodel").write_text("a camera model"),
                                       ["fit", _fit_set(made, tmp), "--camera", tmp / "c.cameramodel",
                                        "--pixel-pitch", 0.18, "-o", tmp / "c.cameramodel"])[1],
    },
    "batch fit": {
        "OUT the capture folder": lambda made, tmp: ["batch", "fit", _fit_set(made, tmp), "-o", tmp / "cal"],
        "OUT in the capture folder": lambda made, tmp: ["batch", "fit", _fit_set(made, tmp), "-o",
                                                        tmp / "cal" / "captures"],
        "OUT holding the set as a panel folder": lambda made, tmp: (
            (tmp / "fleet").mkdir(), shutil.copytree(FIXTURE, tmp / "fleet" / "cal"),
            ["batch", "fit", tmp / "fleet" / "cal", "-o", tmp / "fleet"])[2],
    },
    "camera patterns": {
        "profile": lambda made, tmp: (_copy(made, tmp, "p.json"),
                                      ["camera", "patterns", "--profile", tmp / "p.json", "--pixel-pitch", 0.18,
                                       "-o", tmp / "p.json"])[1],
    },
    "camera calibrate": {
        "a photo": lambda made, tmp: ["camera", "calibrate", _photos(tmp) / "a.jpg", tmp / "photos" / "b.jpg",
                                      "--board", "9x6", "--square", 20, "-o", tmp / "photos" / "a.jpg"],
        "a photo in a folder": lambda made, tmp: ["camera", "calibrate", _photos(tmp), "--board", "9x6",
                                                  "--square", 20, "-o", tmp / "photos" / "b.jpg"],
        "--report holding the photos": lambda made, tmp: ["camera", "calibrate", _photos(tmp), "--board", "9x6",
                                                          "--square", 20, "-o", tmp / "c.cameramodel",
                                                          "--report", tmp / "photos"],
    },
    "crosstalk patterns": {
        "profile": lambda made, tmp: (_copy(made, tmp, "p.json"),
                                      ["crosstalk", "patterns", "--profile", tmp / "p.json",
                                       "-o", tmp / "p.json"])[1],
    },
    "crosstalk measure": {
        "patterns.json": lambda made, tmp: ["crosstalk", "measure", _crosstalk_set(tmp),
                                            "-o", tmp / "xt" / "patterns.json"],
        "a photo": lambda made, tmp: ["crosstalk", "measure", _crosstalk_set(tmp),
                                      "-o", tmp / "xt" / "captures" / "b0.jpg"],
        "--profile": lambda made, tmp: (_copy(made, tmp, "p.json"),
                                        ["crosstalk", "measure", _crosstalk_set(tmp), "--profile", tmp / "p.json",
                                         "-o", tmp / "p.json"])[1],
        "--report holding the set": lambda made, tmp: ["crosstalk", "measure", _crosstalk_set(tmp),
                                                       "-o", tmp / "crosstalk.json", "--report", tmp / "xt"],
    },
    "render": {
        "--background": lambda made, tmp: (_copy(made, tmp, "p.json", "demo.npz", "bg.png"),
                                           ["render", tmp / "demo.npz", "--profile", tmp / "p.json",
                                            "--view-size", "64x36", "--background", tmp / "bg.png",
                                            "-o", tmp / "bg.png"])[1],
        "the avatar": lambda made, tmp: (_copy(made, tmp, "p.json", "demo.npz"),
                                         ["render", tmp / "demo.npz", "--profile", tmp / "p.json",
                                          "--view-size", "64x36", "-o", tmp / "demo.npz"])[1],
        "--views-out holding the avatar": lambda made, tmp: (
            (tmp / "in").mkdir(), _copy(made, tmp / "in", "p.json", "demo.npz"),
            ["render", tmp / "in" / "demo.npz", "--profile", tmp / "in" / "p.json", "--view-size", "64x36",
             "-o", tmp / "frame.png", "--views-out", tmp / "in"])[2],
    },
    "avatar diagnose": {
        "--report is the avatar": lambda made, tmp: (_copy(made, tmp, "demo.npz"),
                                                     ["avatar", "diagnose", tmp / "demo.npz",
                                                      "--report", tmp / "demo.npz"])[1],
        "--report holding the avatar": lambda made, tmp: (
            (tmp / "in").mkdir(), _copy(made, tmp / "in", "demo.npz"),
            ["avatar", "diagnose", tmp / "in" / "demo.npz", "--report", tmp / "in"])[2],
    },
    "driver distill": {
        "--controls": lambda made, tmp: ((tmp / "c.csv").write_text("t,a\n0,0\n"),
                                         (tmp / "clip.avi").write_bytes(b"a video"),
                                         ["driver", "distill", "--frames", tmp / "clip.avi", "--controls",
                                          tmp / "c.csv", "-o", tmp / "c.csv"])[2],
    },
    "driver predict": {
        "the student": lambda made, tmp: ((tmp / "s.pt").write_bytes(b"a student"),
                                          (tmp / "clip.avi").write_bytes(b"a video"),
                                          ["driver", "predict", tmp / "s.pt", "--frames", tmp / "clip.avi",
                                           "-o", tmp / "s.pt"])[2],
    },
    "device read": {
        "a drive's visual.json": _device_read_drive,
        "an emulated unit's image": _device_read_lkg_emu,
        "an emulated controller's image": _device_read_emu,
    },
    "emulate": {
        "--looking-glass as the unit's image": _emulate_looking_glass,
    },
}
CASE_IDS = [(command, case) for command, cases in CASES.items() for case in cases]


def test_every_subcommand_is_accounted_for():
    commands = set(_subcommands(build_parser()))
    listed = [set(CASES), set(WRITE_NOTHING), set(BY_DESIGN), set(NO_OUTPUT_PATH)]
    assert not any(a & b for i, a in enumerate(listed) for b in listed[i + 1:]), "a command listed twice"
    assert commands == set().union(*listed), (
        f"not covered: {sorted(commands - set().union(*listed))}; gone: {sorted(set().union(*listed) - commands)}")


@pytest.mark.parametrize("command, case", CASE_IDS, ids=[f"{c}: {k}" for c, k in CASE_IDS])
def test_an_output_never_replaces_an_input(command, case, made, tmp_path, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(_emulator(tmp_path)))
    _emulator(tmp_path).mkdir()
    argv = [str(a) for a in CASES[command][case](made, tmp_path)]
    assert " ".join(argv[:len(command.split())]) == command
    before = _tree(tmp_path)
    line = refused(*argv)
    assert PHRASE in line, line
    assert _tree(tmp_path) == before  # every input byte-identical, nothing written, nothing left


def test_hard_links_across_folders_are_the_same_file(tmp_path):
    """The two branches no command above reaches: an output file that is a hard link to a file of an
    input folder read whole, and a folder to be replaced that holds a hard link to an input file."""
    from lenticalib.core.errors import InputError
    from lenticalib.core.files.outputs import check_output_file, check_output_folder

    (tmp_path / "views").mkdir()
    (tmp_path / "views" / "view-00.png").write_bytes(b"a view")
    os.link(tmp_path / "views" / "view-00.png", tmp_path / "raster.png")
    with pytest.raises(InputError, match=PHRASE):
        check_output_file(tmp_path / "raster.png", "raster", inputs=[tmp_path / "views"])
    (tmp_path / "report").mkdir()
    (tmp_path / "p.json").write_text("a profile")
    os.link(tmp_path / "p.json", tmp_path / "report" / "p.json")
    with pytest.raises(InputError, match=PHRASE):
        check_output_folder(tmp_path / "report", "report", ("*.json",), inputs=[tmp_path / "p.json"])
    check_output_folder(tmp_path / "report", "report", inputs=[tmp_path / "p.json"])  # written in place: kept
    assert (tmp_path / "raster.png").read_bytes() == b"a view" and (tmp_path / "p.json").read_text() == "a profile"
