"""The presenter and ``lenticalib show`` on a virtual display (Xvfb): byte-exact, refusals, keys."""

import subprocess
import sys
import time

import numpy as np
import pytest

from lenticalib.core.errors import DisplayError, ImageError
from lenticalib.render.gpu.monitors import Monitor, choose_monitor, list_monitors
from lenticalib.render.present.window import WindowPresenter
from lenticalib.render.present.offscreen import OffscreenPresenter

from .display_support import SCREEN

W, H = SCREEN  # the xvfb fixture's screen


def _raster(seed, size=(W, H), dtype=np.uint8):
    rng = np.random.default_rng(seed)
    return rng.integers(0, np.iinfo(dtype).max + 1, (size[1], size[0], 3), dtype=dtype)


def _write_png(path, raster):
    import cv2

    assert cv2.imwrite(str(path), np.ascontiguousarray(raster[:, :, ::-1]))


def test_a_raster_reaches_the_screen_byte_for_byte(on_xvfb):
    monitors = list_monitors()
    assert [(m.width, m.height) for m in monitors] == [(W, H)]
    with WindowPresenter(choose_monitor(monitors, size=(W, H))) as presenter:
        assert presenter.size == (W, H)
        for seed in (1, 2):  # two frames: both pixel buffers
            raster = _raster(seed)
            timing = presenter.show(raster)
            assert timing.upload_ms >= 0 and timing.present_ms >= 0
            assert np.array_equal(on_xvfb.screenshot(), raster)  # what X shows
            assert np.array_equal(presenter.read_back(), raster)  # what GL draws
        # every value of every channel, including the extremes, in stripes one subpixel wide
        stripes = np.zeros((H, W, 3), np.uint8)
        stripes[:, :, 0] = np.arange(W)[None, :] % 256
        stripes[:, :, 1] = 255 - stripes[:, :, 0]
        stripes[:, :, 2] = (np.arange(H)[:, None] * 7) % 256
        presenter.show(stripes)
        assert np.array_equal(on_xvfb.screenshot(), stripes)
        assert len(presenter.timings) == 3


def test_a_raster_of_another_size_or_depth_is_refused_not_scaled(on_xvfb):
    with WindowPresenter(list_monitors()[0]) as presenter:
        presenter.show(_raster(3))
        with pytest.raises(ImageError, match=r"is 320x180 pixels, the display is 640x360 \(rasters are never scaled"):
            presenter.show(_raster(4, (320, 180)), source="small.png")
        with pytest.raises(ImageError, match="16-bit but the display shows 8 bits"):
            presenter.show(_raster(5, dtype=np.uint16))
        with pytest.raises(ImageError, match="not an RGB image"):
            presenter.show(np.zeros((H, W), np.uint8))
        assert np.array_equal(on_xvfb.screenshot(), _raster(3))  # the refused ones never reached the screen


def test_offscreen_presenter_is_byte_exact_too(on_xvfb):
    # 200 wide: the rows' bytes in an RGBA texture 150 wide; 202 wide: an RGB texture (not a multiple of 4)
    for size in ((200, 120), (202, 120)):
        with OffscreenPresenter(size) as presenter:
            for seed in (6, 7):
                raster = _raster(seed, size)
                presenter.show(raster)
                assert np.array_equal(presenter.read_back(), raster), size


MONITORS = [Monitor(0, "DELL U2720Q", 0, 0, 2560, 1440, 60),
            Monitor(1, "LentiPanel 4K", 2560, 0, 3840, 2160, 60),
            Monitor(2, "HP Z27", 6400, 0, 3840, 2160, 60, scale=(1.5, 1.5))]


def test_monitor_choice_by_index_position_name_and_size():
    assert choose_monitor(MONITORS, "1").name == "LentiPanel 4K"
    assert choose_monitor(MONITORS, "@6400,0").name == "HP Z27"
    assert choose_monitor(MONITORS, "lentipanel").index == 1
    assert choose_monitor(MONITORS, "dell").index == 0
    assert choose_monitor(MONITORS[:2], size=(3840, 2160)).index == 1
    assert choose_monitor(MONITORS).index == 0  # nothing asked: the primary
    with pytest.raises(DisplayError, match=r"2 monitors show 3840x2160.*`display`"):
        choose_monitor(MONITORS, size=(3840, 2160))
    with pytest.raises(DisplayError, match=r"no monitor shows 1920x1080.*LentiPanel 4K 3840x2160"):
        choose_monitor(MONITORS, size=(1920, 1080))
    with pytest.raises(DisplayError, match=r"^display: no monitor matches 'Samsung'"):
        choose_monitor(MONITORS, "Samsung")
    twins = [MONITORS[1], Monitor(3, "LentiPanel 4K B", 0, 2160, 3840, 2160)]
    with pytest.raises(DisplayError, match=r"^display: 2 monitors match 'lentipanel'"):
        choose_monitor(twins, "lentipanel")
    assert choose_monitor(twins, "lentipanel 4k").index == 1  # an exact name wins over a part of another
    with pytest.raises(DisplayError, match="is not @X,Y"):
        choose_monitor(MONITORS, "@left")
    with pytest.raises(DisplayError, match="no monitor matches '7'"):
        choose_monitor(MONITORS, "7")
    assert "desktop scale 1.5x1.5" in MONITORS[2].describe()


def _wait_for_screen(display, raster, timeout=20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if np.array_equal(display.screenshot(), raster):
            return True
        time.sleep(0.2)
    return False


def test_show_steps_through_a_folder_with_the_keys(xvfb, tmp_path):
    slides = [_raster(10 + k) for k in range(3)]
    for k, raster in enumerate(slides):
        _write_png(tmp_path / f"s{k}.png", raster)
    process = subprocess.Popen([sys.executable, "-m", "lenticalib", "show", str(tmp_path)], env=xvfb.env(),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_for_screen(xvfb, slides[0])
        xvfb.key("space")
        assert _wait_for_screen(xvfb, slides[1])
        xvfb.key("Left")
        assert _wait_for_screen(xvfb, slides[0])
        xvfb.key("Right", "Down")
        assert _wait_for_screen(xvfb, slides[2])
        xvfb.key("Escape")
        out, err = process.communicate(timeout=20)
    finally:
        process.kill()
    assert process.returncode == 0, err
    assert "showed 5 raster(s) of 640x360" in out


def test_show_advances_by_itself_with_an_interval(xvfb, tmp_path, cli_process):
    for k in range(2):
        _write_png(tmp_path / f"s{k}.png", _raster(20 + k))
    result = cli_process("show", str(tmp_path), "--interval", "0.3", env=xvfb.variables(), timeout=60)
    assert result.returncode == 0, result.stderr
    assert "showed 2 raster(s)" in result.stdout


def test_show_a_pattern_set_without_its_pngs_draws_them_from_the_manifest(tmp_path):
    from lenticalib.calib.patterns.calibration_patterns import design_patterns, render_pattern
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.core.slides import slides_from_path

    pattern_set = design_patterns(W, H, 8)
    write_patterns(tmp_path, pattern_set)
    (tmp_path / "x2-1.png").unlink()
    slides, size = slides_from_path(tmp_path)
    assert size == (W, H) and [s.name for s in slides] == pattern_set.names
    x21 = next(s for s in slides if s.name == "x2-1")
    assert np.array_equal(x21.load(), render_pattern(pattern_set.group("x2")[1], W, H))


def test_every_bad_input_ends_in_one_line(xvfb, tmp_path, cli_process):
    good = tmp_path / "good.png"
    _write_png(good, _raster(30))
    small = tmp_path / "small.png"
    _write_png(small, _raster(31, (320, 180)))
    (tmp_path / "empty").mkdir()
    no_display = {"DISPLAY": None, "WAYLAND_DISPLAY": None}
    cases = [
        (["show", str(good)], no_display, "there is no display to show on"),
        (["show", str(good), "--display", "7"], xvfb.variables(), "--display: no monitor matches '7'"),
        (["show", str(tmp_path / "empty")], xvfb.variables(), "holds no images"),
        (["show", str(tmp_path / "missing.png")], xvfb.variables(), "no such file or folder"),
        (["show", str(small)], xvfb.variables(), "no monitor shows 320x180"),
        (["show", str(small), "--display", "0"], xvfb.variables(), "is 320x180 pixels, the display is 640x360"),
        (["show", str(good), "--display", "offscreen"], xvfb.variables(), "--interval"),
        (["show"], xvfb.variables(), "give an image or a folder"),
    ]
    for args, env, message in cases:
        result = cli_process(*args, env=env, timeout=60)
        assert result.returncode == 2, (args, result.stdout, result.stderr)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], (args, result.stderr)
        assert "Traceback" not in result.stderr


def test_list_displays(xvfb, cli_process):
    result = cli_process("show", "--list-displays", env=xvfb.variables(), timeout=60)
    assert result.returncode == 0, result.stderr
    assert "0: screen 640x360" in result.stdout


def test_a_raster_on_a_device_the_driver_cannot_share_goes_through_host_memory(on_xvfb, monkeypatch):
    # a driver that cannot share its buffers with CUDA (Mesa here): the raster still arrives byte for byte,
    # and the fallback is said once
    import torch

    from lenticalib.render.gpu import cuda_gl

    def refuse(self, buffer):
        raise DisplayError("CUDA-OpenGL interop: cuGraphicsGLRegisterBuffer failed (CUDA error 219)")

    monkeypatch.setattr(cuda_gl.RegisteredBuffer, "__init__", refuse)
    with OffscreenPresenter((200, 120)) as presenter:
        for seed in (8, 9):
            raster = _raster(seed, (200, 120))
            presenter.show_device(torch.from_numpy(raster))
            assert np.array_equal(presenter.read_back(), raster)
        assert presenter.notes == ["the raster goes to OpenGL through host memory (CUDA-OpenGL interop: "
                                   "cuGraphicsGLRegisterBuffer failed (CUDA error 219))"]
        with pytest.raises(ImageError, match="is 100x60 pixels"):
            presenter.show_device(torch.from_numpy(_raster(10, (100, 60))))
