"""Raster sizes (lenticalib.core.sizes): the one WxH parser, its limits, the one raster-size check,
and every place a size comes in using them."""

import re
from pathlib import Path

import numpy as np
import pytest

import lenticalib
from lenticalib.cli import main
from lenticalib.core.errors import ImageError, InputError, ProfileError
from lenticalib.core.files.imageio import MAX_IMAGE_PIXELS, read_image, write_image
from lenticalib.core.sizes import (MAX_SIDE, MIN_CAMERA_SIDE, MIN_PANEL_SIDE, check_raster, check_sides,
                                   parse_size)
from .cli_support import raises_one_line as one_line



def test_the_limits_admit_8k_and_looking_glass_panels_and_match_the_image_reader():
    assert MAX_SIDE == 16384 and MAX_IMAGE_PIXELS == MAX_SIDE * MAX_SIDE
    for size in ("7680x4320", "4320x7680", "1440x2560", "3840x2160", "16384x16384"):  # 8K, LG 65", LG Go
        assert parse_size(size, "--panel", MIN_PANEL_SIDE) == tuple(int(v) for v in size.split("x"))
    assert MIN_PANEL_SIDE == 64 and MIN_CAMERA_SIDE == 240


@pytest.mark.parametrize("text, expected", [
    ("3840x2160", (3840, 2160)), (" 1920 X 1080 ", (1920, 1080)), ("1x1", (1, 1)), ((640, 480), (640, 480)),
    ([64, 64], (64, 64)), ((np.int64(5), 6), (5, 6)),
])
def test_sizes_parse(text, expected):
    size = parse_size(text, "--size")
    assert size == expected and all(type(v) is int for v in size)


@pytest.mark.parametrize("text, words", [
    ("4k", "--size: must be WIDTHxHEIGHT in pixels, e.g. 3840x2160, got '4k' (use 1..16384 pixels per side)"),
    ("", "--size: must be WIDTHxHEIGHT in pixels"),
    ("3840x", "must be WIDTHxHEIGHT"), ("-1x2", "must be WIDTHxHEIGHT"), ("1x2x3", "must be WIDTHxHEIGHT"),
    ("1.5x2", "must be WIDTHxHEIGHT"), ((1, 2, 3), "must be WIDTHxHEIGHT"), (None, "must be WIDTHxHEIGHT"),
    ("16385x100", "--size: 16385x100 is out of range (use 1..16384 pixels per side)"),
    ("0x100", "--size: 0x100 is out of range"), ("99999999999x1", "must be WIDTHxHEIGHT"),
    (("a", 2), "--size: 'a' is not a whole number of pixels"), ((True, 2), "True is not a whole number"),
    ((2.5, 2), "2.5 is not a whole number"),
])
def test_bad_sizes_are_one_line_naming_the_source_and_the_range(text, words):
    text = one_line(lambda: parse_size(text, "--size"))
    assert text.startswith("--size: ") and words in text and "1..16384 pixels per side" in text, text


def test_the_lower_limit_is_the_callers():
    assert one_line(lambda: parse_size("63x100", "--panel", MIN_PANEL_SIDE)) == (
        "--panel: 63x100 is out of range (use 64..16384 pixels per side)")
    assert parse_size("64x64", "--panel", MIN_PANEL_SIDE) == (64, 64)
    assert check_sides(16384, 1, "width") == (16384, 1)
    assert "16385x1 is out of range" in one_line(lambda: check_sides(16385, 1, "width"))


# ------------------------------------------------------------------ every WxH entry point uses them


def test_every_size_option_parses_through_the_one_parser():
    from lenticalib.sim.capture_backend import parse_resolution as sim_camera
    from lenticalib.cli.shared.avatar_options import _size as view_size
    from lenticalib.cli.capture import _resolution as capture_resolution
    from lenticalib.device.emulator.config import parse_size as emulator_panel

    for parse, source in ((view_size, "--view-size"), (capture_resolution, "--resolution"),
                          (sim_camera, "camera sim")):  # the library names its argument, the CLI its flag
        assert parse("4000x3000") == (4000, 3000)
        for bad in ("16385x3000", "4k"):
            text = one_line(lambda: parse(bad))
            assert text.startswith(f"{source}: ") and "..16384 pixels per side" in text, text
    assert emulator_panel("7680x4320") == (7680, 4320)
    with pytest.raises(ValueError, match=r"^16385x100 is out of range \(use 1..16384 pixels per side\)$"):
        emulator_panel("16385x100")
    with pytest.raises(ValueError, match="^must be WIDTHxHEIGHT in pixels"):
        emulator_panel("4k")


@pytest.mark.parametrize("argv, words", [
    (["camera", "patterns", "-o", "{tmp}/b", "--panel", "16385x2160", "--pixel-pitch", "0.2"],
     "--panel: 16385x2160 is out of range (use 64..16384 pixels per side)"),
    (["camera", "simulate", "{tmp}/s", "--resolution", "16385x1200"],
     "--resolution: 16385x1200 is out of range (use 240..16384 pixels per side)"),
    (["patterns", "-o", "{tmp}/p", "--width", "16385", "--height", "64", "--views", "8"],
     "--width: 16385 pixels is out of range (give the panel raster size in pixels, 64..16384)"),
    (["simulate", "{tmp}/c", "--resolution", "4k"], "--resolution: must be WIDTHxHEIGHT in pixels"),
])
def test_size_options_of_the_cli_are_one_line(tmp_path, capsys, argv, words):
    code = main([a.replace("{tmp}", str(tmp_path)) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and words in err[0], err


def test_profiles_and_visual_json_have_the_same_largest_side():
    from lenticalib.core.looking_glass.convert import profile_from_visual
    from lenticalib.core.profile import profile_from_dict

    constants = {"views": 8, "slant": 0.2, "period": 12.0, "offset": 0.0, "reference_view": 0.0,
                 "width": MAX_SIDE, "height": 64, "subpixel_order": "RGB"}
    assert profile_from_dict(constants).width == MAX_SIDE
    text = one_line(lambda: profile_from_dict({**constants, "width": MAX_SIDE + 1}), ProfileError)
    assert "field 'width': must be between 1 and 16384 pixels" in text
    visual = {"pitch": 50.0, "slope": -7.0, "center": 0.1, "DPI": 300.0, "screenW": MAX_SIDE + 1, "screenH": 64}
    assert "field 'screenW': must be a whole number of pixels between 1 and 16384" in one_line(
        lambda: profile_from_visual(visual, 8), ProfileError)


# ------------------------------------------------------------------ the raster-size check


def test_check_raster_accepts_the_panels_raster_and_names_what_does_not_fit():
    raster = np.zeros((48, 64, 3), np.uint8)[:, ::-1]
    out = check_raster(raster, 64, 48, "r.png")
    assert out.flags.c_contiguous and np.array_equal(out, raster)
    assert one_line(lambda: check_raster(np.zeros((48, 65, 3), np.uint8), 64, 48, "r.png", "the panel"),
                    ImageError) == "r.png: is 65x48 pixels, the panel is 64x48 (give a 64x48 image)"
    for bad in (np.zeros((48, 64, 3), np.uint16), np.zeros((48, 64), np.uint8), np.zeros((48, 64, 4), np.uint8),
                [[0]]):
        assert one_line(lambda: check_raster(bad, 64, 48, "r.png", hint="write it again"), ImageError).startswith(
            "r.png: a raster must be 8-bit RGB (H, W, 3)")


def test_the_simulator_and_the_image_reader_use_the_one_check(tmp_path):
    from lenticalib.sim.panel_light import check_raster as sim_check
    from lenticalib.sim.scene import random_scene

    scene = random_scene(2, width=64, height=64, resolution=(320, 240), subsamples=1)
    text = one_line(lambda: sim_check(np.zeros((64, 65, 3), np.uint8), scene, "pattern.png"), ImageError)
    assert text.startswith("pattern.png: is 65x64 pixels, the simulated panel is 64x64")
    path = tmp_path / "r.png"
    write_image(path, np.zeros((64, 65, 3), np.uint8))
    assert one_line(lambda: read_image(path, expected_size=(64, 64), what="the simulated panel"),
                    ImageError).startswith(f"{path}: is 65x64 pixels, the simulated panel is 64x64")


def test_quilt_grids_and_board_corners_parse_through_the_one_parser():
    from lenticalib.calib.intrinsics.board import parse_squares
    from lenticalib.core.errors import ImageError
    from lenticalib.render.compose.views import QuiltGrid, parse_grid

    assert parse_grid(" 8 x 4 ") == QuiltGrid(8, 4)
    with pytest.raises(ImageError, match=r"^--grid: must be COLSxROWS in tiles, e.g. 8x4, got '8by4'"):
        parse_grid("8by4", "--grid")
    with pytest.raises(ImageError, match=r"^--grid: 0x4 is out of range \(use 1\.\.254 tiles per side\)"):
        parse_grid("0x4", "--grid")
    assert parse_squares("15X8") == (15, 8)
    with pytest.raises(InputError, match=r"^--squares: 2x8 is out of range \(use 3\.\.200 inner corners per side\)"):
        parse_squares("2x8", "--squares")


def test_no_other_module_parses_an_AxB_text():
    """Every ``AxB`` is read by core/sizes.parse_pair: no other regex or split on an ``x``."""
    package = Path(lenticalib.__file__).parent
    pattern = re.compile(r"\[xX\]|\.split\(\s*['\"]x['\"]\s*\)|\.partition\(\s*['\"]x['\"]\s*\)")
    found = [f"{p.relative_to(package)}:{n}" for p in package.rglob("*.py") if p.name != "sizes.py"
             for n, line in enumerate(p.read_text().splitlines(), 1) if pattern.search(line)]
    assert found == []


def test_one_check_raster_serves_the_display_and_the_cameras_shown_raster():
    wide = np.zeros((48, 64, 3), np.uint16)
    assert check_raster(wide, 64, 48, "r", "the display", max_bits=10).dtype == np.uint16
    assert one_line(lambda: check_raster(wide, 64, 48, "r", "the display", max_bits=8), ImageError) == (
        "r: is 16-bit but the display shows 8 bits per channel (show an 8-bit raster, or set the display to "
        "10-bit colour)")
    assert one_line(lambda: check_raster(np.zeros((3, 5, 3), np.uint8), 64, 48, "r", "the display", max_bits=8),
                    ImageError).startswith("r: is 5x3 pixels, the display is 64x48")
    assert check_raster(np.zeros((3, 5, 3), np.uint8), None, None, "shown", error=InputError).shape == (3, 5, 3)
    text = one_line(lambda: check_raster(np.zeros((3, 5), np.uint8), None, None, "shown", error=InputError),
                    InputError)
    assert text == "shown: a raster must be 8-bit RGB (H, W, 3), got uint8 (3, 5)"
    with pytest.raises(InputError) as caught:  # the camera's error class, not an image file's
        check_raster(np.zeros((3, 5), np.uint8), None, None, "shown", error=InputError)
    assert type(caught.value) is InputError


def test_there_is_one_check_raster():
    """core/sizes owns the check; the simulator's is a one-line delegate for its scene's panel."""
    root = Path(lenticalib.__file__).parent
    owners = sorted(p.relative_to(root).as_posix() for p in root.rglob("*.py") if "def check_raster(" in p.read_text())
    assert owners == ["core/sizes.py", "sim/panel_light.py"]
