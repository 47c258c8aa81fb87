import json
import subprocess
import sys

import numpy as np
import pytest

from lenticalib.core.files.imageio import read_image, write_image
from lenticalib.render.compose.views import QuiltGrid, load_view_folder, make_quilt, parse_quilt_name, split_quilt

from .cli_support import one_error_line, run_main

PROFILE = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4,
           "width": 96, "height": 54, "subpixel_order": "BGR"}


@pytest.fixture
def profile_path(tmp_path):
    path = tmp_path / "panel.json"
    path.write_text(json.dumps(PROFILE))
    return path


def _views(n=8, h=27, w=48, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (n, h, w, 3), dtype=np.uint8)


def test_quilt_layout_round_trip_and_name():
    views = _views()
    quilt = make_quilt(views, QuiltGrid(4, 2))
    assert quilt.shape == (54, 192, 3)
    np.testing.assert_array_equal(quilt[27:, :48], views[0])  # view 0 bottom-left
    np.testing.assert_array_equal(quilt[:27, 144:], views[7])  # last view top-right
    np.testing.assert_array_equal(split_quilt(quilt, QuiltGrid(4, 2)), views)
    assert parse_quilt_name("shot_qs8x6a0.75.png") == QuiltGrid(8, 6, 0.75)
    assert parse_quilt_name("plain.png") is None


def test_encode_quilt_and_folder_give_the_same_raster(tmp_path, profile_path, cli):
    views = _views()
    quilt_path = tmp_path / "scene_qs4x2a1.7778.png"
    write_image(quilt_path, make_quilt(views, QuiltGrid(4, 2)))
    folder = tmp_path / "views"
    folder.mkdir()
    for i in range(8):
        write_image(folder / f"view{i}.png", views[i])  # view10 would sort after view9
    code, out, err = cli("encode", "--profile", profile_path, "--quilt", quilt_path, "-o", tmp_path / "a.png", "--json")
    assert code == 0, err
    assert json.loads(out)["width"] == 96
    code, _, err = cli("encode", "--profile", profile_path, "--views-dir", folder, "-o", tmp_path / "b.png")
    assert code == 0, err
    a, b = read_image(tmp_path / "a.png"), read_image(tmp_path / "b.png")
    assert a.shape == (54, 96, 3) and a.dtype == np.uint8
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(load_view_folder(folder, 8), views)


def test_sixteen_bit_views_give_a_sixteen_bit_raster(tmp_path, profile_path, cli):
    quilt = make_quilt(_views().astype(np.uint16) * 257, QuiltGrid(4, 2))
    write_image(tmp_path / "q_qs4x2a1.78.png", quilt)
    code, _, err = cli("encode", "--profile", profile_path, "--quilt", tmp_path / "q_qs4x2a1.78.png",
                       "-o", tmp_path / "o.png")
    assert code == 0, err
    assert read_image(tmp_path / "o.png").dtype == np.uint16


def _expect_error(argv, *fragments):
    code, out, err = run_main(*argv)
    assert code == 2
    line = one_error_line(err)
    for fragment in fragments:
        assert fragment in line, line


def test_bad_inputs_end_in_one_clear_line(tmp_path, profile_path):
    out = tmp_path / "o.png"
    folder = tmp_path / "v"
    folder.mkdir()
    views = _views()
    # wrong number of views
    for i in range(7):
        write_image(folder / f"{i}.png", views[i])
    _expect_error(["encode", "--profile", profile_path, "--views-dir", folder, "-o", out],
                  "found 7 images, the profile has 8 views", str(folder))
    # views of different sizes
    write_image(folder / "7.png", views[0][:20])
    _expect_error(["encode", "--profile", profile_path, "--views-dir", folder, "-o", out],
                  "7.png", "all views must have one size")
    # unreadable image
    (folder / "7.png").write_bytes(b"not a png")
    _expect_error(["encode", "--profile", profile_path, "--views-dir", folder, "-o", out],
                  "7.png", "not a readable image")
    # missing image / folder
    _expect_error(["encode", "--profile", profile_path, "--quilt", tmp_path / "none_qs4x2a1.78.png", "-o", out],
                  "none_qs4x2a1.78.png", "no such file")
    _expect_error(["encode", "--profile", profile_path, "--views-dir", tmp_path / "nowhere", "-o", out], "no such folder")
    # quilt that does not divide into its grid
    write_image(tmp_path / "q_qs4x2a1.78.png", make_quilt(views, QuiltGrid(4, 2))[:, :190])
    _expect_error(["encode", "--profile", profile_path, "--quilt", tmp_path / "q_qs4x2a1.78.png", "-o", out],
                  "does not divide into 4x2 tiles")
    # quilt without a grid
    write_image(tmp_path / "plain.png", make_quilt(views, QuiltGrid(4, 2)))
    _expect_error(["encode", "--profile", profile_path, "--quilt", tmp_path / "plain.png", "-o", out],
                  "quilt grid unknown", "--grid")
    # a profile with a bad field
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**PROFILE, "period": -2}))
    _expect_error(["encode", "--profile", bad, "--quilt", tmp_path / "plain.png", "--grid", "4x2", "-o", out],
                  str(bad), "field 'period'")
    # a profile of another panel size than the views were made for
    portrait = tmp_path / "portrait.json"
    portrait.write_text(json.dumps({**PROFILE, "width": 54, "height": 96}))
    _expect_error(["encode", "--profile", portrait, "--quilt", tmp_path / "plain.png", "--grid", "4x2", "-o", out],
                  "do not fit the 54x96 panel")
    write_image(tmp_path / "p_qs4x2a0.75.png", make_quilt(views, QuiltGrid(4, 2)))
    _expect_error(["encode", "--profile", profile_path, "--quilt", tmp_path / "p_qs4x2a0.75.png", "-o", out],
                  "quilt was made for aspect 0.75")
    # float views cannot go to PNG
    assert not out.exists()


def test_profile_show_validate(profile_path, tmp_path, cli):
    code, out, _ = cli("profile", "validate", profile_path)
    assert code == 0 and "valid" in out
    code, out, _ = cli("profile", "show", profile_path, "--json")
    assert json.loads(out)["format_version"] == 1
    _expect_error(["profile", "show", tmp_path / "absent.json"], "no such file")


def test_help_is_instant_and_imports_nothing_heavy():
    code = ("import sys, lenticalib.cli as c; c.build_parser(); "
            "print(any(m in sys.modules for m in ('numpy', 'cv2', 'numba')))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "False"
