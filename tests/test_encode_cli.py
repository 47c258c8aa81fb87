"""User errors of ``encode`` and ``profile``: one line naming the file and what to do, before any work."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

import lenticalib.core.files.outputs
import lenticalib.render.encoders
from lenticalib.core.files.imageio import read_image, write_image
from lenticalib.render.compose.views import QuiltGrid, make_quilt

from .cli_support import one_error_line, run_main

REPO = Path(__file__).resolve().parent.parent
PROFILE = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4,
           "width": 96, "height": 54, "subpixel_order": "BGR"}
VISUAL = {"pitch": {"value": 50.0}, "slope": {"value": -7.0}, "center": {"value": 0.3},
          "DPI": {"value": 300.0}, "screenW": {"value": 1536}, "screenH": {"value": 2048}}


@pytest.fixture
def files(tmp_path):
    """A profile, a matching quilt (with and without a grid suffix) and a visual.json."""
    (tmp_path / "panel.json").write_text(json.dumps(PROFILE))
    views = np.random.default_rng(0).integers(0, 256, (8, 27, 48, 3), dtype=np.uint8)
    quilt = make_quilt(views, QuiltGrid(4, 2))
    write_image(tmp_path / "q_qs4x2a1.78.png", quilt)
    write_image(tmp_path / "plain.png", quilt)
    (tmp_path / "visual.json").write_text(json.dumps(VISUAL))
    return tmp_path


def _error_line(argv):
    code, out, err = run_main(*argv)
    assert code == 2, (code, out, err)
    assert out == ""
    return one_error_line(err)


@pytest.fixture
def no_encoding(monkeypatch):
    """Fail the test if any encoder runs: refusals must come before the work."""
    def forbidden(*args, **kwargs):
        raise AssertionError("encoded although the command had to be refused first")
    monkeypatch.setattr(lenticalib.render.encoders, "encode", forbidden)


def test_missing_quilt_says_it_does_not_exist_not_grid_unknown(files):
    line = _error_line(["encode", "--profile", files / "panel.json", "--quilt", files / "nothere.png",
                                "-o", files / "o.png"])
    assert "nothere.png: no such file" in line and "grid" not in line


def test_text_file_as_quilt_is_not_a_readable_image(files):
    (files / "notes.txt").write_text("hello\n")
    line = _error_line(["encode", "--profile", files / "panel.json", "--quilt", files / "notes.txt",
                                "-o", files / "o.png"])
    assert "notes.txt: not a readable image" in line and "grid" not in line


def test_png_given_as_profile_is_not_a_json_profile(files):
    png = files / "plain.png"
    line = _error_line(["encode", "--profile", png, "--quilt", files / "q_qs4x2a1.78.png",
                                "-o", files / "o.png"])
    assert f"{png}: is a PNG image, not a JSON profile" in line and "codec" not in line
    line = _error_line(["profile", "show", png])
    assert "is a PNG image, not a JSON profile" in line
    line = _error_line(["profile", "import-lkg", png, "--views", "45", "-o", files / "p.json"])
    assert "is a PNG image, not a JSON visual.json" in line
    assert not (files / "p.json").exists()


def test_non_utf8_empty_and_folder_profiles(files, cli):
    latin = files / "latin.json"
    latin.write_bytes(json.dumps({**PROFILE, "name": "caf\u00e9"}, ensure_ascii=False).encode("latin-1"))
    line = _error_line(["profile", "show", latin])
    assert "not UTF-8 text" in line and "save the profile as UTF-8 JSON" in line and "codec" not in line
    empty = files / "empty.json"
    empty.write_bytes(b"")
    assert "is empty, not a JSON profile" in _error_line(["profile", "validate", empty])
    assert "is a folder, not a profile file" in _error_line(["profile", "show", files])
    bom = files / "bom.json"  # a byte-order mark (Windows editors) is fine
    bom.write_bytes(b"\xef\xbb\xbf" + json.dumps(PROFILE).encode())
    assert cli("profile", "validate", bom)[0] == 0


def test_hints_name_the_argument_the_user_typed(files):
    absent = files / "absent.json"
    line = _error_line(["profile", "show", absent])
    assert "(check the path given as PROFILE)" in line and "--profile" not in line
    line = _error_line(["profile", "compare", files / "panel.json", absent])
    assert "(check the path given as B)" in line
    line = _error_line(["profile", "export-lkg", absent, "--dpi", "100", "-o", files / "v.json"])
    assert "(check the path given as PROFILE)" in line
    line = _error_line(["encode", "--profile", absent, "--quilt", files / "q_qs4x2a1.78.png",
                                "-o", files / "o.png"])
    assert "(check the path given as --profile)" in line


def test_opencv_does_not_write_its_own_warnings(files, cli_process):
    truncated = files / "cut_qs4x2a1.78.png"
    truncated.write_bytes((files / "q_qs4x2a1.78.png").read_bytes()[:600])
    result = cli_process("encode", "--profile", files / "panel.json", "--quilt", truncated, "-o", files / "o.png",
                         env={"PYTHONPATH": str(REPO)})
    assert result.returncode == 2
    assert result.stderr.splitlines() == [f"lenticalib: error: {truncated}: not a readable image "
                                          "(corrupt or unsupported format) (use PNG, TIFF or JPEG)"]


def test_bad_image_files(files):
    encode = ["encode", "--profile", files / "panel.json", "-o", files / "o.png"]
    (files / "empty_qs4x2a1.78.png").write_bytes(b"")
    assert "is empty (0 bytes), not an image" in _error_line(encode + ["--quilt", files / "empty_qs4x2a1.78.png"])
    (files / "dir_qs4x2a1.78.png").mkdir()
    assert "is a folder, not an image" in _error_line(encode + ["--quilt", files / "dir_qs4x2a1.78.png"])
    line = _error_line(encode + ["--views-dir", files / "plain.png"])
    assert "is a file, not a folder of views" in line and "--quilt" in line
    # a 16-bit quilt with the wrong grid: the grid message, after the file was read
    deep = make_quilt(np.full((6, 10, 16, 3), 4000, np.uint16), QuiltGrid(3, 2))
    write_image(files / "deep_qs3x2a1.6.png", deep)
    assert "3x2 = 6 tiles, the profile has 8 views" in _error_line(encode + ["--quilt", files / "deep_qs3x2a1.6.png"])
    line = _error_line(encode + ["--quilt", files / "deep_qs3x2a1.6.png", "--grid", "3x3"])
    assert "3x3 = 9 tiles" in line


def test_encode_output_path_is_refused_before_encoding(files, monkeypatch, no_encoding):
    encode = ["encode", "--profile", files / "panel.json", "--quilt", files / "q_qs4x2a1.78.png", "-o"]
    line = _error_line(encode + [files / "missing" / "o.png"])
    assert "the folder for the panel raster does not exist" in line
    assert not (files / "missing").exists()  # never created
    line = _error_line(encode + [files])
    assert f"{files}: is a folder, not a file name for the panel raster" in line
    assert "cannot write .jpg" in _error_line(encode + [files / "o.jpg"])
    line = _error_line(encode + [files / "o.png", "--encoder", "nope"])
    assert "encoder: unknown encoder 'nope'" in line
    locked = files / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    real_access = os.access  # root passes any mode bits: report the folder as a user would see it
    monkeypatch.setattr(lenticalib.core.files.outputs.os, "access",
                        lambda p, mode: False if Path(p) == locked and mode & os.W_OK else real_access(p, mode))
    line = _error_line(encode + [locked / "o.png"])
    assert f"{locked}: folder is not writable" in line
    assert list(locked.iterdir()) == []


def test_float_views_into_png_are_refused_before_encoding(files, no_encoding):
    folder = files / "float"
    folder.mkdir()
    for i in range(8):
        np.save(folder / f"v{i}.npy", np.zeros((27, 48, 3), np.float32))
    line = _error_line(["encode", "--profile", files / "panel.json", "--views-dir", folder, "-o", files / "o.png"])
    assert ".png cannot hold float32 pixels" in line


def test_lkg_output_paths_are_refused_before_the_work(files):
    line = _error_line(["profile", "export-lkg", files / "panel.json", "--dpi", "100",
                                "-o", files / "missing" / "v.json"])
    assert "the folder for the visual.json does not exist" in line
    line = _error_line(["profile", "export-lkg", files / "panel.json", "--dpi", "100", "-o", files])
    assert "is a folder, not a file name for the visual.json" in line
    # the output is checked before the visual.json is even read
    line = _error_line(["profile", "import-lkg", files / "absent.json", "--views", "45",
                                "-o", files / "missing" / "p.json"])
    assert "the folder for the profile does not exist" in line
    line = _error_line(["profile", "import-lkg", files / "visual.json", "--views", "45", "-o", files])
    assert "is a folder, not a file name for the profile" in line
    assert not (files / "missing").exists()


def test_import_lkg_prints_a_readable_summary(files, cli):
    out_path = files / "p.json"
    code, out, err = cli("profile", "import-lkg", files / "visual.json", "--views", "45", "-o", out_path)
    assert code == 0, err
    assert out.startswith(f"wrote {out_path} from {files / 'visual.json'} (45 views):\n")
    assert "{" not in out
    assert "         period  18.182746 subpixels" in out.splitlines()
    assert "            views  45" not in out and "          views  45" in out.splitlines()
    code, out, err = cli("profile", "import-lkg", files / "visual.json", "--views", "45", "-o", out_path, "--json")
    assert code == 0, err
    assert json.loads(out)["output"] == str(out_path)


def test_encode_still_writes_a_raster(files, cli):
    assert cli("encode", "--profile", files / "panel.json", "--quilt", files / "q_qs4x2a1.78.png",
               "-o", files / "o.png")[0] == 0
    assert read_image(files / "o.png").shape == (54, 96, 3)
