"""The ``gl`` renderer on Mesa (llvmpipe through EGL): agreement with the ``cpu`` renderer, geometry,
the GPU sort, the CPU-sort fallback, refusals.

Measured agreement with ``cpu`` per view, RGB / alpha PSNR, the same with either sort (float32
projection on the GPU, or the cpu renderer's own float64 projection and order on the host): on
the scenes of test_renderer_cpu 73-152 dB -- near 137-152, random SH 0 and 3 76-147 (single
pixels whose alpha sits on the 1/255 cut-off, and opaque stacks), layered 73-87 (opaque stacks:
the cpu renderer stops pixels early, blending cannot; see gl_renderer's docstring); on the demo
avatar (6000 Gaussians, 3 views of 120x68) 87-90 dB RGB, 80 dB alpha.  The tests assert >= 60 dB.
The two sorts agree with each other at >= 129 dB (max difference 3e-6; asserted: 80 dB, which a
pixel whose alpha rounds across 1/255 the other way still passes).  Small Gaussians land within
0.006 px of where they project (the test asserts 0.3 px).
"""

import numpy as np
import pytest

from lenticalib.core.errors import DisplayError, InputError
from lenticalib.render.renderers import available_renderers, get_renderer
from lenticalib.render.renderers import gl_renderer
from lenticalib.render.renderers.cpu import render_cpu
from lenticalib.render.renderers.gl_renderer import GLSplatRenderer, render_gl
from lenticalib.render.renderers.gl_sort import GLSorter

from .gl_render_support import (NoVertexStorage, OpenGL41, assert_close, assert_refuses_other_view_counts,
                                gl_test_context, render_with, run_under_opengl_41, scene_against_cpu)
from .test_renderer_cpu import CAMERAS, H, SCENES, W, _bad, _gaussians, _single, random_scene


@pytest.fixture(scope="module")
def ctx():
    yield from gl_test_context()


def _render(ctx, gaussians, viewmats, ks, width, height, background=None, sort=None):
    return render_with(ctx, lambda: GLSplatRenderer(ctx, len(viewmats), width, height, sort=sort),
                       gaussians, viewmats, ks, background)


def test_gl_is_a_registered_renderer_that_runs_here():
    assert "gl" in available_renderers()
    assert get_renderer("gl") is render_gl
    assert render_gl.unavailable() is None


@pytest.mark.parametrize("name", sorted(SCENES))
def test_gl_agrees_with_the_cpu_renderer(name):
    scene_against_cpu(name, "gl")


@pytest.mark.parametrize("name", sorted(SCENES))
def test_the_cpu_sort_agrees_with_the_cpu_renderer_and_the_gpu_sort(ctx, name):
    gaussians = SCENES[name]()
    expected = render_cpu(gaussians, *CAMERAS, W, H)
    host = _render(ctx, gaussians, *CAMERAS, W, H, sort="cpu")
    assert_close(host, expected)
    assert_close(host, _render(ctx, gaussians, *CAMERAS, W, H, sort="gpu"), min_psnr=80.0)


@pytest.mark.parametrize("sort", ["gpu", "cpu"])  # cpu: 18000 records, 18 rows of the record texture
def test_gl_agrees_with_the_cpu_renderer_on_the_demo_avatar(ctx, sort):
    from lenticalib.render.cameras.models import make_cameras
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar

    rig = make_demo_avatar(seed=2, count=6000)
    gaussians = rig.deform(rig.neutral_controls()).to_numpy()
    cameras = make_cameras("arc", gaussians, 3, view_size=(120, 68))
    expected = render_cpu(gaussians, cameras.viewmats, cameras.K, 120, 68)
    assert (expected[..., 3] > 0.5).mean() > 0.05
    assert_close(_render(ctx, gaussians, cameras.viewmats, cameras.K, 120, 68, sort=sort), expected)


def test_small_gaussians_land_where_they_project(ctx):
    # one small isotropic Gaussian per view at a random sub-pixel position: the alpha centroid is
    # the projected mean (OpenCV pixel centres at integers), within 0.3 px (measured: < 0.006 px)
    viewmats, ks = CAMERAS
    rng = np.random.default_rng(7)
    errors = []
    for _ in range(3):
        for view in range(len(viewmats)):
            u, v = rng.uniform(12, W - 12), rng.uniform(12, H - 12)
            depth = rng.uniform(1.0, 3.0)
            cam = np.array([(u - ks[view, 0, 2]) / ks[view, 0, 0], (v - ks[view, 1, 2]) / ks[view, 1, 1], 1.0]) * depth
            point = viewmats[view, :3, :3].T @ (cam - viewmats[view, :3, 3])
            sigma = 1.2 * depth / ks[view, 0, 0]  # about 1.2 px
            alpha = _render(ctx, _single(point, sigma), viewmats[view:view + 1], ks[view:view + 1], W, H)[0, ..., 3]
            ys, xs = np.mgrid[:H, :W]
            total = alpha.sum()
            errors.append(np.hypot((alpha * xs).sum() / total - u, (alpha * ys).sum() / total - v))
            assert np.unravel_index(alpha.argmax(), alpha.shape) == (round(v), round(u))
    assert max(errors) < 0.3


@pytest.mark.parametrize("length, runs, values", [(1, 3, 1), (7, 2, 3), (1024, 5, 40), (2500, 3, 1 << 32),
                                                  (3000, 2, 1 << 20)])
def test_the_gpu_sort_is_a_stable_sort_by_key(ctx, length, runs, values):
    # keys with ties (few values), spanning several chunks of the radix sort's passes, and culled ones
    rng = np.random.default_rng(length)
    keys = rng.integers(0, values, (runs, length), dtype=np.uint64).astype(np.uint32)
    keys[:, rng.random(length) < 0.2] = 0xFFFFFFFF
    if values == 1 << 20:
        keys = (keys << np.uint32(12)) | np.uint32(0x3F000000)  # float-like keys: low digits 0, high ones shared
    vals = rng.permutation(1 << 24)[:runs * length].astype(np.uint32).reshape(runs, length)  # distinct, any order
    with ctx:
        sorter = GLSorter(ctx)
        kbuf, vbuf = ctx.buffer(keys.tobytes()), ctx.buffer(vals.tobytes())
        sorter.sort(kbuf, vbuf, length, runs)
        got_k = np.frombuffer(kbuf.read(), np.uint32).reshape(runs, length)
        got_v = np.frombuffer(vbuf.read(), np.uint32).reshape(runs, length)
        for obj in (kbuf, vbuf):
            obj.release()
        sorter.release()
    order = np.argsort(keys, axis=1, kind="stable")
    np.testing.assert_array_equal(got_k, np.take_along_axis(keys, order, axis=1))
    np.testing.assert_array_equal(got_v, np.take_along_axis(vals, order, axis=1))


@pytest.mark.parametrize("sort", ["gpu", "cpu"])
def test_background_is_composited_under_the_premultiplied_colour(ctx, sort):
    gaussians = random_scene(3, n=60)
    plain = _render(ctx, gaussians, *CAMERAS, W, H, sort=sort)
    over = _render(ctx, gaussians, *CAMERAS, W, H, background=(0.2, 0.4, 0.6), sort=sort)
    assert (plain[..., 3] > 0.3).mean() > 0.05
    np.testing.assert_array_equal(over[..., 3], plain[..., 3])
    np.testing.assert_allclose(over[..., :3], plain[..., :3] + (1 - plain[..., 3:]) * [0.2, 0.4, 0.6], atol=1e-6)


@pytest.mark.parametrize("sort", ["gpu", "cpu"])
@pytest.mark.parametrize("gaussians", [
    _gaussians(np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 1, 3))),
    _single((0.0, 0.0, -3.0), 0.1),  # behind every camera
], ids=["no Gaussians", "all culled"])
def test_an_empty_scene_renders_the_background(ctx, gaussians, sort):
    out = _render(ctx, gaussians, *CAMERAS, W, H, background=(0.25, 0.5, 0.75), sort=sort)
    assert out.shape == (4, H, W, 4)
    np.testing.assert_array_equal(out[..., :3], np.broadcast_to(np.float32([0.25, 0.5, 0.75]), (4, H, W, 3)))
    np.testing.assert_array_equal(out[..., 3], 0)


def test_huge_and_far_gaussians_render_like_the_cpu_renderers():
    # a variance beyond float32 (culled), one covering every pixel of every view (drawn as the
    # whole view), one far off every view: as render_cpu, finite
    g = random_scene(0, n=5)
    g.scales[1] = 1e18
    g.scales[3] = 1e6
    g.means[4] = (1e25, 0.0, 0.0)
    out = render_gl(g, *CAMERAS, W, H)
    assert np.isfinite(out).all() and (out[..., 3] > 0).all()
    assert_close(out, render_cpu(g, *CAMERAS, W, H))


@pytest.mark.parametrize("views_per_batch", [1, 3])
def test_views_are_rendered_in_batches_within_the_drivers_storage_block_size(ctx, monkeypatch, views_per_batch):
    gaussians = random_scene(0, n=300)  # 52 bytes a Gaussian in the GAUSS buffer, 48 a record per view
    expected = _render(ctx, gaussians, *CAMERAS, W, H, background=(0.1, 0.2, 0.3))
    limit = max(300 * 52, 300 * 48 * views_per_batch + 47)
    monkeypatch.setattr(GLSplatRenderer, "_storage_limit", lambda self: limit)
    np.testing.assert_array_equal(_render(ctx, gaussians, *CAMERAS, W, H, background=(0.1, 0.2, 0.3)), expected)


def test_gaussians_beyond_the_drivers_storage_block_size_are_a_one_line_display_error(ctx, monkeypatch):
    monkeypatch.setattr(GLSplatRenderer, "_storage_limit", lambda self: 299 * 48)
    with pytest.raises(DisplayError, match=r"300 Gaussians exceed the OpenGL driver's shader storage block size "
                                           r"\(14352 bytes\)") as err:
        _render(ctx, random_scene(0, n=300), *CAMERAS, W, H)
    assert "\n" not in str(err.value) and "cpu renderer" in str(err.value)


def test_a_renderer_reused_for_more_then_fewer_gaussians_renders_each_like_a_new_one(ctx):
    scenes = [random_scene(0, n=30, seed=4), random_scene(3, n=700, seed=5), random_scene(1, n=10, seed=6)]
    with ctx:
        renderer = GLSplatRenderer(ctx, 4, W, H)
        got = []
        for g in scenes:
            renderer.render(g, *CAMERAS)
            got.append(renderer.read())
        renderer.release()
    for g, out in zip(scenes, got):
        np.testing.assert_array_equal(out, _render(ctx, g, *CAMERAS, W, H))


def test_torch_gaussians_render_like_numpy_ones():
    gaussians = random_scene(1, n=50)
    np.testing.assert_array_equal(render_gl(gaussians.to_torch(), *CAMERAS, W, H), render_gl(gaussians, *CAMERAS, W, H))


def test_the_views_texture_holds_the_image_not_flipped(ctx):
    # a Gaussian above the centre (world y up) is in the top rows of the image; texel row = image row
    viewmats, ks = CAMERAS
    gaussians = _single((0.0, 0.3, 0.0), 0.03)
    with ctx:
        renderer = GLSplatRenderer(ctx, 1, W, H)
        renderer.render(gaussians, viewmats[:1], ks[:1])
        texels = np.frombuffer(renderer.views.read(), np.float32).reshape(H, W, 4)
        renderer.release()
    expected = render_cpu(gaussians, viewmats[:1], ks[:1], W, H)[0]
    peak = np.unravel_index(texels[..., 3].argmax(), (H, W))
    assert peak == np.unravel_index(expected[..., 3].argmax(), (H, W)) and peak[0] < H // 2 - 5
    assert_close(texels[None], expected[None])


@pytest.mark.parametrize("change, source", [
    (dict(viewmats=np.eye(4)), "viewmats"),
    (dict(Ks=CAMERAS[1][:3]), "Ks"),
    (dict(Ks=CAMERAS[1] * np.nan), "Ks"),
    (dict(width=0), "width"),
    (dict(height=True), "height"),
    (dict(background=(1.0, 0.0)), "background"),
    (dict(gaussians=_gaussians(np.zeros((2, 3)), np.zeros((2, 4)), np.ones((2, 3)), np.ones(2), np.zeros((2, 1, 3)))),
     "gaussians"),  # zero-length quaternions
    (dict(gaussians=_gaussians(np.full((2, 3), np.inf), np.ones((2, 4)), np.ones((2, 3)), np.ones(2),
                               np.zeros((2, 1, 3)))), "gaussians"),
    (dict(gaussians="avatar.ply"), "gaussians"),
])
def test_bad_inputs_are_one_line_input_errors(change, source):
    with pytest.raises(InputError) as err:
        render_gl(**_bad(**change))
    assert err.value.source == source
    assert "\n" not in str(err.value)


def test_a_renderer_refuses_other_view_counts_and_unknown_sorts(ctx):
    with ctx:
        renderer = GLSplatRenderer(ctx, 2, W, H)
        assert_refuses_other_view_counts(renderer)
        renderer.release()
        with pytest.raises(InputError, match="must be 'gpu', 'cpu' or None") as err:
            GLSplatRenderer(ctx, 2, W, H, sort="radix")
        assert err.value.source == "sort"
        with pytest.raises(InputError) as err:
            GLSplatRenderer(ctx, 0, W, H)
        assert err.value.source == "n_views"


def test_texture_limits_too_small_are_one_line_display_errors(ctx, monkeypatch):
    scene = random_scene(0, n=300)
    expected = _render(ctx, scene, *CAMERAS[:2], 16, 12, sort="cpu")
    with ctx:
        monkeypatch.setattr(GLSplatRenderer, "_texture_limits", lambda self: (4096, 16))
        with pytest.raises(DisplayError, match="texture arrays of up to 16 layers, 32 views") as err:
            GLSplatRenderer(ctx, 32, W, H)
        assert "\n" not in str(err.value) and "cpu renderer" in str(err.value)
        monkeypatch.setattr(GLSplatRenderer, "_texture_limits", lambda self: (960, 2048))
        with pytest.raises(DisplayError, match="textures up to 960 pixels, the views are 1920x1080") as err:
            GLSplatRenderer(ctx, 4, 1920, 1080)
        assert "\n" not in str(err.value)
        GLSplatRenderer(ctx, 4, 960, 540).release()  # at the limit: fine
    # the CPU sort's records (12 floats, 3 texels each) in a texture of at most 64 x 64 texels:
    # 21 records a row, 64 rows
    monkeypatch.setattr(GLSplatRenderer, "_texture_limits", lambda self: (64, 2048))
    np.testing.assert_array_equal(_render(ctx, scene, *CAMERAS[:2], 16, 12, sort="cpu"), expected)
    with pytest.raises(DisplayError, match="splats exceed the OpenGL driver's texture size \\(64 pixels\\)") as err:
        _render(ctx, random_scene(0, n=1500), *CAMERAS, W // 2, H // 2, sort="cpu")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("sort", ["gpu", "cpu"])
def test_without_the_vertex_layer_extension_a_geometry_shader_picks_the_layers(ctx, monkeypatch, sort):
    gaussians = random_scene(3, n=80)
    expected = _render(ctx, gaussians, *CAMERAS, W, H, background=(0.1, 0.2, 0.3), sort=sort)
    monkeypatch.setattr(gl_renderer, "_vertex_layer", lambda context: False)
    np.testing.assert_array_equal(_render(ctx, gaussians, *CAMERAS, W, H, background=(0.1, 0.2, 0.3), sort=sort),
                                  expected)


def test_shaders_a_driver_refuses_are_a_one_line_display_error(ctx, monkeypatch):
    from lenticalib.render.renderers import gl_shaders

    broken = gl_shaders.SPLAT_FRAGMENT.replace("exp(-sigma)", "exp(-sigma, 2)")
    monkeypatch.setattr(gl_shaders, "SPLAT_FRAGMENT", broken)
    with ctx, pytest.raises(DisplayError, match="the OpenGL driver refused the gl renderer's shaders: .*exp") as err:
        GLSplatRenderer(ctx, 4, W, H)
    assert "\n" not in str(err.value) and "cpu renderer" in str(err.value)


def test_without_opengl_43_the_cpu_sort_is_used_and_said(ctx):
    old = OpenGL41(ctx)
    gaussians = random_scene(3, n=80)
    with ctx:
        with pytest.raises(DisplayError,
                           match=r"the gpu sort cannot run here: OpenGL 4\.1 has no compute shaders \(4\.3 needed\)") as err:
            GLSplatRenderer(old, 4, W, H, sort="gpu")
        assert "sort='cpu'" in str(err.value) and "\n" not in str(err.value)
        renderer = GLSplatRenderer(old, 4, W, H)
        assert renderer.sort_kind == "cpu"
        assert "OpenGL 4.1 has no compute shaders" in renderer.fallback_reason
        assert "\n" not in renderer.fallback_reason
        renderer.render(gaussians, *CAMERAS)
        out = renderer.read()
        renderer.release()
        native = GLSplatRenderer(ctx, 4, W, H)
        assert native.sort_kind == "gpu" and native.fallback_reason is None
        native.release()
    np.testing.assert_array_equal(out, _render(ctx, gaussians, *CAMERAS, W, H, sort="cpu"))


def test_a_driver_without_vertex_storage_buffers_gets_the_cpu_sort_and_says_so(ctx):
    gaussians = random_scene(3, n=80)
    with ctx:
        renderer = GLSplatRenderer(NoVertexStorage(ctx), 4, W, H)
        assert renderer.sort_kind == "cpu"
        assert renderer.fallback_reason == ("the gl renderer projects and sorts on the CPU: the driver allows 0 "
                                            "storage buffers in a vertex shader (2 needed)")
        renderer.render(gaussians, *CAMERAS)
        out = renderer.read()
        renderer.release()
    np.testing.assert_array_equal(out, _render(ctx, gaussians, *CAMERAS, W, H, sort="cpu"))


def test_on_a_real_opengl_41_context_render_gl_sorts_on_the_cpu_and_says_so(tmp_path):
    done = run_under_opengl_41(f"""
from lenticalib.render.renderers.gl_renderer import render_gl, _RENDERERS
out = render_gl(random_scene(3, n=80), *CAMERAS, W, H, background=(0.1, 0.2, 0.3))
with _RENDERERS.contexts[0]:
    print("version", _RENDERERS.contexts[0].version_code)
np.save({str(tmp_path / "out.npy")!r}, out)
""")
    assert "version 410" in done.stdout
    assert ("the gl renderer projects and sorts on the CPU: OpenGL 4.1 has no compute shaders (4.3 needed)"
            in done.stderr)
    expected = render_cpu(random_scene(3, n=80), *CAMERAS, W, H, background=(0.1, 0.2, 0.3))
    assert_close(np.load(tmp_path / "out.npy"), expected)
