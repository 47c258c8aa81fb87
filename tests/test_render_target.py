"""Renders say when the avatar is not in view (issue 45, rule 7), and views too large are refused.

The avatar of these tests is 200 Gaussians in a box 0.1 across and one more at x = 20 (avatar
units).  Framed on the bounding box of all the centres the cameras looked at x = 10 and every view
was black, without a word; framed on the robust box (:func:`robust_box`, the one ``avatar
diagnose`` uses) they look at the 200.  ``--target X,Y,Z`` aims them anywhere; a view in which no
Gaussian can show (decided from the projected centres before any render) is one warning line.
The views of a frame are budgeted (N x W x H x 19 bytes against 8 GiB) before anything is
allocated, and the gl renderer also checks the driver's texture and framebuffer limits.
Views of 64x36 pixels, 4 views, the cpu renderer unless said: each render takes well under a second.
"""

from __future__ import annotations


import numpy as np
import pytest

from lenticalib.core.errors import DisplayError, InputError
from lenticalib.core.files.imageio import read_image
from lenticalib.core.profile import PanelProfile, save_profile
from lenticalib.render.diagnose import avatars as diagnose
from lenticalib.render.cameras.models import arc_cameras, make_cameras, robust_box
from lenticalib.render.cameras.view_cameras import empty_views, view_list
from lenticalib.render.avatar.gaussians import SH_C0, Gaussians
from lenticalib.render.avatar.ply import save_ply
from lenticalib.render.renderers.common import MAX_VIEW_BYTES, check_view_memory
from lenticalib.render.renderers.cpu import render_cpu
from lenticalib.render.pipeline.session import AvatarOptions, open_avatar_session

from .cli_support import refused, run_main
from .memory_support import peak_traced

FAR_X = 20.0
VIEW_SIZE = "64x36"
MiB = 1 << 20


def _far_avatar() -> Gaussians:
    rng = np.random.default_rng(0)
    means = np.concatenate([rng.uniform(-0.05, 0.05, (200, 3)), [[FAR_X, 0.0, 0.0]]]).astype(np.float32)
    g = len(means)
    sh = np.zeros((g, 1, 3), np.float32)
    sh[:, 0] = (0.8 - 0.5) / SH_C0
    return Gaussians(means, np.tile([1, 0, 0, 0], (g, 1)).astype(np.float32), np.full((g, 3), 0.01, np.float32),
                     np.full(g, 0.9, np.float32), sh)


def _profile(path, views: int, width: int, height: int):
    save_profile(PanelProfile(views=views, slant=-0.2, period=9.5, offset=1.25, reference_view=0.0, width=width,
                              height=height, subpixel_order="RGB", view_direction=1), path)
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("target")
    save_ply(folder / "far.ply", _far_avatar())
    return {"avatar": folder / "far.ply", "profile": _profile(folder / "p4.json", 4, 320, 180),
            "huge": _profile(folder / "p200.json", 200, 16384, 9216)}


def _render(files, out, *extra):
    out.mkdir()
    code, stdout, err = run_main("render", files["avatar"], "--profile", files["profile"], "-o", out / "r.png",
                                 "--view-size", VIEW_SIZE, "--views-out", out / "v", *extra)
    assert code == 0, err
    views = np.stack([read_image(out / "v" / "frame-00000" / f"view-{i:02d}.png") for i in range(4)])
    return read_image(out / "r.png"), views, err


# ------------------------------------------------------------------ the robust centre, --target

def test_the_cameras_aim_at_the_robust_centre_diagnose_uses():
    g = _far_avatar()
    assert diagnose.robust_box is robust_box  # one implementation
    lo, hi = robust_box(g.means)
    cams = make_cameras("arc", g, 4, view_size=(64, 36))
    np.testing.assert_allclose(cams.params["c0"], (lo + hi) / 2, atol=1e-12)
    assert np.abs(cams.params["c0"]).max() < 0.05 and cams.params["h"] < 0.11  # the far Gaussian pulls neither
    c0, h = np.array(cams.params["c0"]), cams.params["h"]
    np.testing.assert_allclose(cams.params["c"], c0 + [0.0, 0.08 * h, 0.0], atol=1e-12)  # lifted to eye level
    aimed = make_cameras("arc", g, 4, view_size=(64, 36), target=(FAR_X, 0.0, 0.0))
    assert aimed.params["c"] == [FAR_X, 0.0, 0.0]  # the look-at point itself, no lift


def test_the_far_gaussian_avatar_renders_the_avatar_and_target_aims_the_cameras(files, tmp_path):
    raster, views, err = _render(files, tmp_path / "default")
    assert "warning" not in err, err
    assert raster.max() > 100 and all(view.max() > 100 for view in views)  # not black: the 200 are in view
    raster, views, err = _render(files, tmp_path / "far", "--target", f"{FAR_X},0,0")
    assert "warning" not in err, err
    assert raster.max() > 100 and all(view.max() > 100 for view in views)  # the far Gaussian, alone
    assert all((view.sum(axis=2) > 0).mean() < 0.25 and view[16:20, 30:34].min() > 100 for view in views)  # centred


def test_views_with_nothing_in_them_are_one_warning_line_naming_them(files, tmp_path):
    raster, views, err = _render(files, tmp_path / "nothing", "--target", "0,5,0")
    assert raster.max() == 0 and views.max() == 0
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("lenticalib: warning: views 0-3 of 4 show nothing of the avatar") and \
        "--target X,Y,Z" in lines[0] and "(they look at 0, 5, 0)" in lines[0], lines[0]


def test_play_warns_once_before_the_first_frame(files):
    code, out, err = run_main("play", files["avatar"], "--profile", files["profile"], "--headless", "--frames", "2",
                              "--view-size", VIEW_SIZE, "--target=-3,0,0")
    assert code == 0, err
    assert err.count("lenticalib: warning:") == 1 and "views 0-3 of 4 show nothing" in err, err
    # decided when the session opens, before any frame (the live loop does not pay for it)
    session = open_avatar_session(files["avatar"], files["profile"],
                                  AvatarOptions(view_size=(64, 36), target=(-3.0, 0.0, 0.0)))
    assert len(session.pipeline.notes) == 1 and "views 0-3 of 4" in session.pipeline.notes[0]
    session.pipeline.close()


def test_empty_views_from_the_projected_centres_and_their_footprints():
    cams = arc_cameras((-0.1, -0.1, -0.1), (0.1, 0.1, 0.1), 5, view_size=(64, 36))
    look = np.array(cams.params["c"])
    assert empty_views(cams, look[None]) == []
    near_camera_0 = cams.centres[0] + 0.05 * (look - cams.centres[0])  # in front of camera 0 only
    assert empty_views(cams, near_camera_0[None]) == [1, 2, 3, 4]
    assert empty_views(cams, cams.centres[:1] - 0.05 * (look - cams.centres[0])) == [0, 1, 2, 3, 4]  # behind it
    # a point 4 px left of view 2's first pixel centre shows when its footprint reaches 5 px
    k, m = cams.K[2], cams.viewmats[2]
    depth = 1.0
    pixel = np.array([-4.0, (36 - 1) / 2, 1.0]) * depth
    point = m[:3, :3].T @ (np.linalg.inv(k) @ pixel - m[:3, 3])
    assert 2 in empty_views(cams, point[None])
    assert 2 not in empty_views(cams, point[None], [5.0 * depth / k[0, 0]])
    assert empty_views(cams, np.zeros((0, 3))) == [0, 1, 2, 3, 4]
    assert view_list([0, 1, 2, 5]) == "views 0-2, 5" and view_list([4]) == "view 4"


@pytest.mark.parametrize("value", ["1,2", "1,2,3,4", "a,b,c", "nan,0,0", "0,inf,0", "1e999,0,0", "", " , , ",
                                   "1" * 5000])
def test_bad_target_values_are_refused_in_one_line_before_the_avatar_is_read(tmp_path, files, value):
    line = refused("render", tmp_path / "no-such-avatar.ply", "--profile", files["profile"], "-o",
                   tmp_path / "r.png", f"--target={value}", source="--target")
    assert "three finite numbers" in line and len(line) < 300, line
    line = refused("play", tmp_path / "no-such-avatar.ply", "--profile", files["profile"], "--headless",
                   f"--target={value}", source="--target")
    with pytest.raises(InputError) as err:  # the library checks it too
        make_cameras("arc", _far_avatar(), 4, target=(0.0, float("nan"), 0.0))
    assert err.value.source == "target" and "avatar's frame and units" in str(err.value)


def test_help_states_the_targets_frame_and_units(capsys):
    code, out, _ = run_main("render", "--help")
    assert code == 0
    text = " ".join(out.split())
    assert "--target X,Y,Z" in text and "avatar's frame and units (metres" in text


# ------------------------------------------------------------------ the views' memory


@pytest.mark.parametrize("renderer", ["cpu", "gl"])
def test_views_too_large_for_memory_are_refused_in_one_line_before_allocation(files, tmp_path, renderer):
    lines = []
    peak = peak_traced(lambda: lines.append(refused(
        "render", files["avatar"], "--profile", files["huge"], "-o", tmp_path / "r.png", "--view-size", "16384x9216",
        "--renderer", renderer, source="--view-size")))
    assert "200 views of 16384x9216 pixels take 534.4 GiB" in lines[0] and "--view-size" in lines[0].split("(")[-1]
    assert peak < 64 * MiB, peak
    refused("play", files["avatar"], "--profile", files["huge"], "--headless", "--view-size", "16384x9216",
            "--renderer", renderer, source="--view-size")


def test_the_renderers_refuse_views_too_large_before_allocation():
    g = _far_avatar()
    cams = arc_cameras((-0.1, -0.1, -0.1), (0.1, 0.1, 0.1), 200, view_size=(16384, 9216))
    errors = []

    def attempt():
        with pytest.raises(InputError) as err:
            render_cpu(g, cams.viewmats, cams.K, 16384, 9216)
        errors.append(err.value)

    assert peak_traced(attempt) < 16 * MiB
    assert errors[0].source == "view_size" and "534.4 GiB" in errors[0].message
    assert check_view_memory(4, 64, 36) == 4 * 64 * 36 * 19
    side = int((MAX_VIEW_BYTES // 19) ** 0.5)
    check_view_memory(1, side, side)  # at the cap: fine
    with pytest.raises(InputError):
        check_view_memory(1, side + 1, side + 1)


def test_the_gl_renderer_refuses_views_too_large_and_past_the_drivers_framebuffer(monkeypatch):
    from lenticalib.render.gpu.gl_context import headless_context
    from lenticalib.render.renderers import gl_renderer
    from lenticalib.render.renderers.gl_renderer import GLSplatRenderer, render_gl

    g = _far_avatar()
    cams = arc_cameras((-0.1, -0.1, -0.1), (0.1, 0.1, 0.1), 200, view_size=(16384, 9216))
    with pytest.raises(InputError, match="534.4 GiB"):
        render_gl(g, cams.viewmats, cams.K, 16384, 9216)
    ctx = headless_context(require=330)
    try:
        with ctx:
            with pytest.raises(InputError, match="534.4 GiB"):
                GLSplatRenderer(ctx, 200, 16384, 9216)
            limits = {"GL_MAX_FRAMEBUFFER_WIDTH": 16384, "GL_MAX_FRAMEBUFFER_HEIGHT": 16384,
                      "GL_MAX_FRAMEBUFFER_LAYERS": 8, "GL_MAX_VIEWPORT_DIMS": 16384}
            monkeypatch.setattr(gl_renderer, "_framebuffer_limits", lambda context: limits)
            with pytest.raises(DisplayError) as err:
                GLSplatRenderer(ctx, 9, 64, 36)
            assert "GL_MAX_FRAMEBUFFER_LAYERS is 8, 9 views of 64x36" in str(err.value)
            assert "\n" not in str(err.value) and "`view_size`" in str(err.value)
            GLSplatRenderer(ctx, 8, 64, 36).release()  # at the limit: fine
    finally:
        ctx.release()
