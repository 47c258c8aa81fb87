"""Every command that writes: nothing it did not write is deleted or replaced.

- an output file path naming a FIFO, a device node, a folder, a dangling link or a link to a
  non-regular file is refused in one line before the work, and the node is left as it was;
- an existing folder holding files the command did not write survives every command that
  writes folders: refused in one line (folders replaced as a whole) or written into, the files
  kept (folders written in place);
- render takes a lossy image suffix neither for an image nor for a folder name.

No real device node is ever an output here: a character device is made in the test folder
(as root, with /dev/null's numbers), and /dev/null is only reached through a link.
"""

import json
import os
import stat
from pathlib import Path

import pytest

from lenticalib.calib.patterns.calibration_patterns import design_patterns
from lenticalib.core.pattern_sets import write_patterns

from .cli_support import one_error_line, refused

REPO = Path(__file__).resolve().parent.parent
FIXTURE = REPO / "fixtures" / "capture-demo"
PROFILE = REPO / "fixtures" / "panel-4k-32.json"
SMALL_PROFILE = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4, "width": 640,
                 "height": 360, "subpixel_order": "RGB"}


def _tree(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (None if p.is_dir() else p.read_bytes()) for p in sorted(folder.rglob("*"))}


def _identity(path: Path) -> tuple:
    st = os.lstat(path)
    return (st.st_mode, st.st_ino, st.st_rdev, os.readlink(path) if path.is_symlink() else None,
            os.lstat("/dev/null").st_mode, os.lstat("/dev/null").st_rdev)


def _make_node(kind: str, path: Path) -> None:
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "device":  # as root a character device of our own; otherwise /dev/null through a link
        if os.geteuid() == 0:
            os.mknod(path, 0o600 | stat.S_IFCHR, os.makedev(1, 3))
        else:
            path.symlink_to("/dev/null")
    elif kind == "link-to-dev-null":
        path.symlink_to("/dev/null")
    elif kind == "link-to-fifo":
        os.mkfifo(path.with_name("pipe"))
        path.symlink_to(path.with_name("pipe"))
    elif kind == "dangling-link":
        path.symlink_to(path.with_name("nowhere"))
    elif kind == "folder":
        path.mkdir()
        (path / "notes.txt").write_text("keep")
    else:
        raise AssertionError(kind)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """Small real inputs: a demo avatar, a visual.json, a small profile."""
    from lenticalib.core.looking_glass.convert import export_visual_json
    from lenticalib.core.profile import load_profile
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig

    folder = tmp_path_factory.mktemp("inputs")
    save_rig(folder / "demo.npz", make_demo_avatar(seed=1, count=2000))
    export_visual_json(load_profile(PROFILE), folder / "visual.json", dpi=280.0)
    (folder / "small.json").write_text(json.dumps(SMALL_PROFILE))
    (folder / "board.jpg").write_bytes(b"a photo of a board")  # found by name; refused before it is read
    return folder


# every command that writes a file: argv with OUT for the output, and the output's name
FILE_COMMANDS = {
    "fit -o": (["fit", FIXTURE, "-o", "OUT"], "profile.json"),
    "profile import-lkg": (["profile", "import-lkg", "IN/visual.json", "--views", 32, "-o", "OUT"], "p.json"),
    "profile export-lkg": (["profile", "export-lkg", PROFILE, "-o", "OUT"], "visual.json"),
    "profile retarget": (["profile", "retarget", PROFILE, "--distance", 900, "-o", "OUT"], "p900.json"),
    "device read": (["device", "read", "emu://blank", "-o", "OUT"], "back.json"),
    "encode": (["encode", "--profile", PROFILE, "--views-dir", "IN", "-o", "OUT"], "raster.png"),
    "render -o PNG": (["render", "IN/demo.npz", "--profile", PROFILE, "-o", "OUT"], "frame.png"),
    "render -o MKV": (["render", "IN/demo.npz", "--profile", PROFILE, "-o", "OUT"], "video.mkv"),
    "crosstalk measure": (["crosstalk", "measure", "IN", "-o", "OUT"], "crosstalk.json"),
    "camera calibrate": (["camera", "calibrate", "IN/board.jpg", "--board", "9x6", "--square", 20, "-o", "OUT"],
                         "camera.cameramodel"),
    "emulate --flash": (["emulate", "--flash", "OUT"], "panel.flash"),
    "patterns --direction": (["patterns", "--direction", "--profile", "IN/small.json", "-o", "DIR"], "direction.png"),
}
NODES = ("fifo", "device", "link-to-dev-null", "link-to-fifo", "dangling-link", "folder")


@pytest.mark.parametrize("kind", NODES)
@pytest.mark.parametrize("command", FILE_COMMANDS)
def test_an_output_file_never_replaces_a_node(command, kind, tmp_path, inputs, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))
    argv, name = FILE_COMMANDS[command]
    folder = tmp_path / "out"
    folder.mkdir()
    out = folder / name
    _make_node(kind, out)
    before = {p.name: _identity(p) for p in folder.iterdir()}
    argv = [str(a).replace("OUT", str(out)).replace("DIR", str(folder)).replace("IN", str(inputs)) for a in argv]
    line = refused(*argv)
    assert str(out) in line, line
    assert {p.name: _identity(p) for p in folder.iterdir()} == before  # nothing replaced, nothing added
    if kind == "folder":
        assert _tree(out) == {"notes.txt": b"keep"}


def test_an_output_file_through_a_link_replaces_the_target_file(tmp_path, cli):
    (tmp_path / "real").mkdir()
    real = tmp_path / "real" / "visual.json"
    real.write_text("an earlier export")
    real.chmod(0o664)
    link = tmp_path / "visual.json"
    link.symlink_to(real)
    code, _, err = cli("profile", "export-lkg", PROFILE, "--dpi", 280, "-o", link)
    assert code == 0, err
    assert link.is_symlink() and os.readlink(link) == str(real)
    assert json.loads(real.read_text()) and real.stat().st_mode & 0o777 == 0o664


def test_an_unwritable_folder_is_named_not_writable():
    line = refused("device", "read", "emu://blank", "-o", "/proc/lenticalib-test.json")
    assert line.startswith("lenticalib: error: /proc: folder is not writable"), line


def test_render_takes_no_lossy_image_or_video_suffix(tmp_path, inputs):
    for name in ("x.jpg", "x.JPEG", "x.webp", "x.mp4", "x.avi"):
        line = refused("render", inputs / "demo.npz", "--profile", PROFILE, "-o", tmp_path / name)
        assert f"render does not write .{name.split('.')[1].lower()} files" in line, line
    line = refused("render", inputs / "demo.npz", "--profile", PROFILE, "-o", tmp_path / "f", "--views-out",
                   tmp_path / "f")  # one folder replacing the other at the end
    assert "--output" in line, line
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------------------------
# a folder holding files the command did not write survives every command that writes folders
# ---------------------------------------------------------------------------------------------

def _foreign(folder: Path, deep: bool = False) -> Path:
    """``folder`` holding a file no command writes (inside a frame folder when ``deep``)."""
    where = folder / "frame-00000" if deep else folder
    where.mkdir(parents=True, exist_ok=True)
    (where / "thesis.tex").write_text("my work")
    return folder


REPLACED_FOLDERS = {  # folders written whole: an existing one with foreign files is refused before the work
    "render -o DIR": ["render", "IN/demo.npz", "--profile", PROFILE, "-o", "DIR"],
    "render --views-out DIR": ["render", "IN/demo.npz", "--profile", PROFILE, "-o", "TMP/f.png", "--views-out", "DIR"],
    "render --views-out DIR (deep)": ["render", "IN/demo.npz", "--profile", PROFILE, "-o", "TMP/f.png",
                                      "--views-out", "DIR"],
    "fit --report": ["fit", FIXTURE, "-o", "TMP/p.json", "--report", "DIR"],
    "crosstalk measure --report": ["crosstalk", "measure", "IN", "-o", "TMP/c.json", "--report", "DIR"],
    "camera calibrate --report": ["camera", "calibrate", "IN/board.jpg", "--board", "9x6", "--square", "20",
                                  "-o", "TMP/c.cameramodel", "--report", "DIR"],
    "camera patterns": ["camera", "patterns", "-o", "DIR", "--panel", "640x360", "--pixel-pitch", "0.3"],
    "camera patterns (deep)": ["camera", "patterns", "-o", "DIR", "--panel", "640x360", "--pixel-pitch", "0.3"],
    "camera simulate": ["camera", "simulate", "DIR", "--photos", 3, "--resolution", "640x480"],
}


@pytest.mark.parametrize("command", REPLACED_FOLDERS)
def test_a_folder_with_foreign_files_is_refused_not_wiped(command, tmp_path, inputs):
    folder = tmp_path / "Documents"
    if "(deep)" in command:
        _foreign(folder, deep=True)
        if command.startswith("camera patterns"):  # a foreign file inside the print/ folder it writes
            (folder / "frame-00000").rename(folder / "print")
        else:
            (folder / "frame-00000" / "view-00.png").write_bytes(b"an earlier view")
    else:
        _foreign(folder)
    before = _tree(tmp_path)
    argv = [str(a).replace("DIR", str(folder)).replace("TMP", str(tmp_path)).replace("IN", str(inputs))
            for a in REPLACED_FOLDERS[command]]
    line = refused(*argv)
    assert line.startswith(f"lenticalib: error: {folder}: holds ") and "thesis.tex" in line, line
    assert _tree(tmp_path) == before


def test_patterns_and_crosstalk_patterns_write_into_a_folder_and_keep_its_files(tmp_path, cli, inputs):
    for argv in (["patterns", "--width", 64, "--height", 64, "--views", 2, "-o", "DIR"],
                 ["crosstalk", "patterns", "--profile", inputs / "small.json", "-o", "DIR"],
                 ["patterns", "--direction", "--profile", inputs / "small.json", "-o", "DIR"]):
        folder = _foreign(tmp_path / argv[0] / argv[1])
        code, _, err = cli(*(str(a).replace("DIR", str(folder)) for a in argv))
        assert code == 0, err
        assert (folder / "thesis.tex").read_text() == "my work" and len(list(folder.iterdir())) > 1


@pytest.mark.slow
def test_simulate_keeps_the_files_of_the_pattern_folder(tmp_path, cli):
    folder = tmp_path / "set"
    write_patterns(folder, design_patterns(640, 360, 8))
    _foreign(folder)
    (folder / "captures").mkdir()
    (folder / "simulation.json").write_text('{"status": "complete"}\n')  # an earlier simulation
    (folder / "captures" / "my-note.txt").write_text("keep")
    code, _, err = cli("simulate", folder, "--seed", 2, "--resolution", "1250x800", "--subsamples", 1)
    assert code == 0, err
    assert (folder / "thesis.tex").read_text() == "my work"
    assert (folder / "captures" / "my-note.txt").read_text() == "keep"


def test_pattern_files_never_replace_a_user_s_file_or_other_patterns_manifest(tmp_path, cli, inputs):
    """A file of a pattern's name beside no lenticalib manifest is the user's, and a calibration
    folder's manifest under crosstalk patterns would leave its patterns without it: both refused, the
    folder as it was.  Patterns written again over patterns of their own kind are fine."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "white.png").write_bytes(b"my photo")
    code, _, err = cli("crosstalk", "patterns", "--profile", inputs / "small.json", "-o", mine)
    assert code == 2, err
    assert one_error_line(err).startswith(f"lenticalib: error: {mine}: holds 'white.png'"), err
    assert [p.name for p in mine.iterdir()] == ["white.png"] and (mine / "white.png").read_bytes() == b"my photo"
    calibration = tmp_path / "cal"
    code, _, err = cli("patterns", "--width", 64, "--height", 64, "--views", 2, "-o", calibration)
    assert code == 0, err
    before = _tree(calibration)
    code, _, err = cli("crosstalk", "patterns", "--profile", inputs / "small.json", "-o", calibration)
    assert code == 2, err
    assert one_error_line(err).startswith(f"lenticalib: error: {calibration / 'patterns.json'}: holds other patterns")
    assert _tree(calibration) == before
    again = tmp_path / "xt"
    for _ in range(2):
        code, _, err = cli("crosstalk", "patterns", "--profile", inputs / "small.json", "-o", again)
        assert code == 0, err
