"""The ``gl`` encoder on Mesa (llvmpipe through EGL, or a window under Xvfb): routing identical to
``view_map`` on every subpixel, values within one level of ``reference``, drawn into any framebuffer."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lenticalib.core.errors import DisplayError, ImageError
from lenticalib.core.layout import LKG_CELL_PATTERNS, SubpixelLayout, pattern_for_mode
from lenticalib.core.profile import PanelProfile
from lenticalib.core.routing import view_map
from lenticalib.render.encoders import available_encoders, encode, get_encoder
from lenticalib.render.encoders.gl_encoder import GLEncoder
from lenticalib.render.gpu.monitors import list_monitors
from lenticalib.render.present.window import WindowPresenter
from lenticalib.render.present.offscreen import MemoryPresenter, OffscreenPresenter

from .display_support import SCREEN
from .strategies import profiles, tie_profiles
from .test_encoders import bundled_4k


def _expected(profile):
    xs = 3 * np.arange(profile.width)[:, None] + np.asarray(profile.rho)[None, :]
    return view_map(profile)[:, xs.reshape(-1)].reshape(profile.height, profile.width, 3).astype(np.int64)


def _numbered(n, hv, wv):
    return np.broadcast_to(np.arange(1, n + 1, dtype=np.uint8)[:, None, None, None], (n, hv, wv, 3)).copy()


def _check(profile, hv, wv, seed=0):
    chosen = encode(_numbered(profile.views, hv, wv), profile, "gl", allow_stretch=True).astype(np.int64) - 1
    np.testing.assert_array_equal(chosen, _expected(profile))
    views = np.random.default_rng(seed).integers(0, 256, (profile.views, hv, wv, 3), dtype=np.uint8)
    ref = encode(views, profile, "reference", allow_stretch=True).astype(np.int32)
    assert np.abs(encode(views, profile, "gl", allow_stretch=True).astype(np.int32) - ref).max() <= 1


def test_gl_is_a_registered_encoder_that_runs_here():
    assert "gl" in available_encoders()
    assert get_encoder("gl").unavailable() is None


@pytest.mark.slow
def test_gl_matches_the_reference_on_the_bundled_4k_profile():
    profile, _, expected, views, ref = bundled_4k()
    numbered = _numbered(profile.views, *views.shape[1:3])
    np.testing.assert_array_equal(encode(numbered, profile, "gl").astype(np.int64) - 1, expected)  # ties included
    diff = np.abs(encode(views, profile, "gl").astype(np.int32) - ref)
    assert diff.max() <= 1 and (diff == 0).mean() > 0.99


@given(st.one_of(profiles(), tie_profiles()), st.integers(1, 40), st.integers(1, 40), st.booleans(), st.booleans(),
       st.booleans())
@settings(max_examples=25, deadline=None)
def test_gl_routes_canonically_on_drawn_profiles(profile, hv, wv, reverse, flip_x, flip_y):
    _check(profile.replace(views_reversed=reverse, flip_image_x=flip_x, flip_image_y=flip_y), hv, wv)


@pytest.mark.parametrize("mode", sorted(LKG_CELL_PATTERNS))
def test_gl_routes_every_cell_pattern(mode):
    cells = (((-0.25, -0.31), (-0.25, 0.28), (0.25, 0.0)), ((0.25, -0.31), (0.25, 0.28), (-0.25, 0.0)),
             ((0.1, 0.2), (-0.3, 0.0), (0.3, -0.2)), ((-0.1, 0.4), (0.0, -0.4), (0.2, 0.1)))
    layout = SubpixelLayout(cells=cells, pattern=pattern_for_mode(mode, 4 if mode else 2, 13))
    profile = PanelProfile(views=32, slant=-0.1835, period=40.3, offset=5.1, reference_view=16, width=97, height=13,
                           subpixel_order="RGB", subpixel_layout=layout, views_reversed=bool(mode % 2))
    _check(profile, 7, 51, seed=mode)


def test_gl_draws_into_the_presenters_framebuffer_with_no_raster_in_host_memory():
    w, h = 160, 96
    profile = PanelProfile(views=8, slant=0.19, period=7.4, offset=1.5, reference_view=4, width=w, height=h,
                           subpixel_order="BGR")
    views = np.random.default_rng(3).integers(0, 256, (8, h // 4, w // 4, 3), dtype=np.uint8)
    expected = encode(views, profile, "gl")
    assert np.abs(expected.astype(np.int32) - encode(views, profile, "reference").astype(np.int32)).max() <= 1
    with OffscreenPresenter((w, h)) as presenter:
        encoder = GLEncoder(profile, views.shape[1:3], ctx=presenter.ctx)
        encoder.upload_views(views)
        timing = presenter.show_drawn(encoder.draw)
        assert timing.upload_ms == 0 and presenter.shown is None
        np.testing.assert_array_equal(presenter.read_back(), expected)
        encoder.release()
    with MemoryPresenter((w, h)) as memory, pytest.raises(DisplayError, match="no OpenGL framebuffer"):
        memory.show_drawn(lambda framebuffer: None)


def test_gl_refuses_what_it_cannot_do_in_one_line():
    profile = PanelProfile(views=8, slant=0.19, period=7.4, offset=1.5, reference_view=4, width=96, height=54)
    with pytest.raises(ImageError, match="the gl encoder takes 8-bit views, these are uint16"):
        encode(np.zeros((8, 27, 48, 3), np.uint16), profile, "gl")
    with pytest.raises(DisplayError, match=r"no offscreen OpenGL 3\.3 context \(nonexistent backend") as caught:
        GLEncoder(profile, (27, 48), backend="nonexistent")
    assert "\n" not in str(caught.value)


def test_encode_cli_with_the_gl_encoder(tmp_path, cli):
    import json

    from lenticalib.core.files.imageio import read_image, write_image
    from lenticalib.render.compose.views import QuiltGrid, make_quilt

    profile = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4,
               "width": 96, "height": 54, "subpixel_order": "BGR"}
    (tmp_path / "panel.json").write_text(json.dumps(profile))
    views = np.random.default_rng(0).integers(0, 256, (8, 27, 48, 3), dtype=np.uint8)
    write_image(tmp_path / "q_qs4x2a1.78.png", make_quilt(views, QuiltGrid(4, 2)))
    for name in ("gl", "reference"):
        code = cli("encode", "--profile", tmp_path / "panel.json", "--quilt", tmp_path / "q_qs4x2a1.78.png",
                   "--encoder", name, "-o", tmp_path / f"{name}.png")[0]
        assert code == 0
    gl, ref = (read_image(tmp_path / f"{name}.png").astype(np.int32) for name in ("gl", "reference"))
    assert gl.shape == (54, 96, 3) and np.abs(gl - ref).max() <= 1


def test_a_window_opens_and_draws_the_gl_raster_after_the_gl_encoder_ran(on_xvfb):
    # creating the encoder's EGL context left it current on the thread, and a thread with a current
    # EGL context cannot make a GLX context current: the next window ended the process (X BadAccess)
    w, h = SCREEN
    profile = PanelProfile(views=8, slant=0.19, period=7.4, offset=1.5, reference_view=4, width=w, height=h,
                           subpixel_order="BGR")
    views = np.random.default_rng(4).integers(0, 256, (8, h // 4, w // 4, 3), dtype=np.uint8)
    expected = encode(views, profile, "gl")
    with WindowPresenter(list_monitors()[0]) as presenter:
        presenter.show(expected)
        np.testing.assert_array_equal(presenter.read_back(), expected)
        encoder = GLEncoder(profile, views.shape[1:3], ctx=presenter.ctx)  # the window's own context
        encoder.upload_views(views)
        presenter.show_drawn(encoder.draw)
        np.testing.assert_array_equal(on_xvfb.screenshot(), expected)  # what X shows
        np.testing.assert_array_equal(presenter.read_back(), expected)
        encoder.release()
