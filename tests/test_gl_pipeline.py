"""The avatar on OpenGL end to end (Mesa: llvmpipe through EGL, a window under Xvfb): the gl renderer,
the GPU views stage and the gl encoder in one context, against the cpu renderer + fast encoder path.

``render``/``play --renderer gl --encoder gl``: the same rasters and views as the CPU path within
the renderers' agreement; the raster drawn into the panel window equals the one read back offscreen;
a driver without OpenGL 4.3 (Mesa told to report 3.3) falls back, says so in one line, and still
makes the same frames.
"""

import json
import os
import threading
import time

import numpy as np
import pytest

from lenticalib.core.files.imageio import read_image
from lenticalib.core.profile import PanelProfile, save_profile
from lenticalib.render.encoders import encode

from .display_support import SCREEN
from .test_avatar_pipeline import _table, demo  # noqa: F401 (demo: a fixture)

VIEW_SIZE = "160x90"
WIDTH, HEIGHT = SCREEN  # 640 x 360: the panel is the Xvfb screen


@pytest.fixture(scope="module")
def avatar(demo):
    """The small demo avatar of test_avatar_pipeline (6000 Gaussians, fixed seed)."""
    return demo


@pytest.fixture(scope="module")
def panel(tmp_path_factory):
    path = tmp_path_factory.mktemp("panel") / "panel.json"
    save_profile(PanelProfile(views=16, slant=0.19, period=9.7, offset=3.2, reference_view=8, width=WIDTH,
                              height=HEIGHT, subpixel_order="RGB", view_direction=1), path)
    return path


def _render(cli_process, avatar, panel, out, renderer, *extra, env=None):
    encoder = "gl" if renderer == "gl" else "fast"
    result = cli_process("render", avatar, "--profile", panel, "-o", out / "frames", "--frames", "2",
                         "--view-size", VIEW_SIZE, "--views-out", out / "views", "--renderer", renderer,
                         "--encoder", encoder, "--background", "0.1,0.2,0.3", "--edge-desaturation", "0.5",
                         *extra, env=env)
    assert result.returncode == 0, result.stderr
    rasters = np.stack([read_image(out / "frames" / f"frame-{k:05d}.png") for k in range(2)])
    views = np.stack([np.stack([read_image(out / "views" / f"frame-{k:05d}" / f"view-{i:02d}.png")
                                for i in range(16)]) for k in range(2)])
    return result, rasters, views


def _agree(a, b):
    """Fraction of values within one level, and the largest difference."""
    diff = np.abs(a.astype(np.int32) - b.astype(np.int32))
    return (diff <= 1).mean(), diff.max()


@pytest.fixture(scope="module")
def cpu_frames(avatar, panel, tmp_path_factory):
    from .cli_support import run_process

    return _render(run_process, avatar, panel, tmp_path_factory.mktemp("cpu"), "cpu")


def test_render_with_the_gl_renderer_and_encoder_makes_the_cpu_paths_frames(avatar, panel, cpu_frames, tmp_path,
                                                                            cli_process):
    result, rasters, views = _render(cli_process, avatar, panel, tmp_path, "gl")
    assert "warning" not in result.stderr
    assert "renderer gl, encoder gl" in result.stdout
    rows = _table(result.stdout)
    assert rows["render"][0] > 0 and rows["compose"][0] > 0
    cameras = json.loads((tmp_path / "views" / "cameras.json").read_text())
    assert len(cameras["views"]) == 16
    from lenticalib.core.profile import load_profile

    profile = load_profile(panel)
    for k in range(2):  # the written views are what was encoded (the gl encoder: within one level)
        assert _agree(encode(views[k], profile, "reference"), rasters[k])[1] <= 1
    _, cpu_rasters, cpu_views = cpu_frames
    within, _ = _agree(views, cpu_views)
    assert within > 0.999, within
    within, _ = _agree(rasters, cpu_rasters)
    assert within > 0.999, within


def test_play_headless_with_gl_prints_the_stage_table(avatar, panel, cli_process):
    result = cli_process("play", avatar, "--profile", panel, "--headless", "--frames", "3", "--view-size", VIEW_SIZE,
                         "--renderer", "gl", "--encoder", "gl")
    assert result.returncode == 0, result.stderr
    assert "(3 frames" in result.stdout
    rows = _table(result.stdout)
    assert rows["present"] == ["-", "-", "-"]
    assert rows["render"][0] > 0 and rows["compose"][0] > 0


def test_play_on_the_panel_draws_the_gl_raster_into_the_window(avatar, panel, tmp_path, on_xvfb):
    from lenticalib.render.pipeline.live import play_avatar
    from lenticalib.render.pipeline.offline import render_avatar
    from lenticalib.render.pipeline.session import AvatarOptions

    from lenticalib.render.avatar.ply import save_ply
    from lenticalib.render.avatar.sources import load_avatar

    still = tmp_path / "still.ply"  # a static avatar: every frame is the same
    save_ply(still, load_avatar(avatar).pose(None, "cpu"))
    options = AvatarOptions(renderer="gl", encoder="gl", view_size=(160, 90))
    render_avatar(still, panel, tmp_path / "expected.png", options=options)
    expected = read_image(tmp_path / "expected.png")
    shots = []

    def look_then_quit():  # while play runs: wait for frames on the screen, take what X shows, press q
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            shot = on_xvfb.screenshot()
            if shot.any():
                time.sleep(0.5)  # a static avatar: every frame is the same
                shots.append(on_xvfb.screenshot())
                break
            time.sleep(0.2)
        on_xvfb.key("q")

    watcher = threading.Thread(target=look_then_quit)
    watcher.start()
    run = play_avatar(still, panel, options=options, output="panel", frames=500)
    watcher.join()
    assert run.presenter_kind == "window" and 1 <= run.times.frames < 500
    assert min(run.times.times["present"]) >= 0.0 and min(run.times.times["compose"]) > 0.0
    assert shots, "nothing appeared on the screen"
    np.testing.assert_array_equal(shots[0], expected)


def test_without_opengl_43_the_gl_path_falls_back_and_says_so(avatar, panel, cpu_frames, tmp_path, cli_process):
    env = dict(os.environ, MESA_GL_VERSION_OVERRIDE="3.3", MESA_GLSL_VERSION_OVERRIDE="330")
    result, rasters, views = _render(cli_process, avatar, panel, tmp_path, "gl", env=env)
    warnings = [line for line in result.stderr.splitlines() if "warning" in line]
    assert any("sort" in line and "4.3" in line for line in warnings), result.stderr
    assert any("views stage runs on the host" in line for line in warnings), result.stderr
    _, cpu_rasters, cpu_views = cpu_frames
    assert _agree(views, cpu_views)[0] > 0.999
    assert _agree(rasters, cpu_rasters)[0] > 0.999


def test_no_opengl_at_all_is_one_line_naming_the_fallback(avatar, panel, tmp_path, cli_process):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["__EGL_VENDOR_LIBRARY_FILENAMES"] = str(tmp_path / "no-such-vendor.json")  # EGL finds no driver
    for flags, named in ((("--renderer", "gl"), "renderer 'gl' cannot run here"),
                         (("--encoder", "gl"), "encoder 'gl' cannot run here")):
        result = cli_process("render", avatar, "--profile", panel, "-o", tmp_path / "x.png", "--view-size", VIEW_SIZE,
                             *flags, env=env)
        assert result.returncode == 2
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and named in lines[0] and "no offscreen OpenGL" in lines[0], result.stderr
        assert "can run here: cpu" in lines[0] or "can run here: fast" in lines[0]
        assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("where", ["offscreen", "window"])
def test_torch_can_load_its_compiler_after_an_opengl_context(where, xvfb):
    # Mesa's llvmpipe and triton (torch's compiler) each bring an LLVM: triton imported after a
    # context existed crashed the process (segmentation fault) until contexts load triton first
    import subprocess
    import sys

    opening = ("from lenticalib.render.gpu.gl_context import headless_context\nctx = headless_context()\n"
               "with ctx:\n    print(ctx.info['GL_RENDERER'])\n") if where == "offscreen" else (
        "from lenticalib.render.gpu.monitors import list_monitors\nfrom lenticalib.render.present.window import WindowPresenter\n"
        "presenter = WindowPresenter(list_monitors()[0])\npresenter.open()\nprint(presenter.ctx.info['GL_RENDERER'])\n")
    script = opening + "import torch._dynamo\nprint('loaded')\n"
    done = subprocess.run([sys.executable, "-c", script], env=xvfb.env(), capture_output=True, text=True,
                          timeout=120, cwd=os.getcwd())
    assert done.returncode == 0 and "loaded" in done.stdout, (done.returncode, done.stderr[-1500:])
