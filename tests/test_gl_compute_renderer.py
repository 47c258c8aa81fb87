"""The ``gl-compute`` renderer on Mesa (llvmpipe through EGL): agreement with ``cpu``, tiles, sorts,
batches, the choice of path, the live pipeline.

Measured agreement with ``cpu`` per view, RGB / alpha PSNR: on the scenes of test_renderer_cpu
130-161 dB in float32 (max difference 3e-6; the same stop rule as ``cpu``, so the opaque stacks
that cost the triangles 73 dB agree here), 68-98 dB with the splats staged as float16 (max
difference 0.004).  The tests assert >= 60 dB for both, as for every renderer.
"""

import numpy as np
import pytest

from lenticalib.core.errors import DisplayError, InputError
from lenticalib.core.profile import PanelProfile
from lenticalib.render.cameras.models import make_cameras
from lenticalib.render.renderers import get_renderer
from lenticalib.render.renderers.cpu import render_cpu
from lenticalib.render.renderers.gl_compute import GLComputeRenderer, gl_renderer_for, render_gl_compute
from lenticalib.render.renderers.gl_renderer import GLSplatRenderer
from lenticalib.render.renderers.gl_sort import GLSorter

from .gl_render_support import (NoVertexStorage, OpenGL41, assert_close, assert_refuses_other_view_counts,
                                gl_test_context, render_with, run_under_opengl_41, scene_against_cpu)
from .test_renderer_cpu import CAMERAS, H, SCENES, W, _gaussians, _random_quats, _single, random_scene


@pytest.fixture(scope="module")
def ctx():
    yield from gl_test_context()


def _render(ctx, gaussians, viewmats, ks, width, height, background=None, precision="fp32", stats=None):
    def keep_stats(renderer):
        if stats is not None:
            stats["intersections"] = renderer.intersections

    return render_with(ctx, lambda: GLComputeRenderer(ctx, len(viewmats), width, height, precision=precision),
                       gaussians, viewmats, ks, background, after=keep_stats)


def crowd_scene(n=1500, opacity=(0.05, 0.3), seed=8):
    """Many Gaussians overlapping in the middle of every view: tiles of more than 256 splats."""
    rng = np.random.default_rng(seed)
    return _gaussians(rng.normal(0, 0.08, (n, 3)), _random_quats(rng, n), np.exp(rng.normal(-2.8, 0.4, (n, 3))),
                      rng.uniform(*opacity, n), rng.normal(0, 0.4, (n, 4, 3)))


def test_gl_compute_is_a_registered_renderer_that_runs_here():
    assert get_renderer("gl-compute") is render_gl_compute
    assert render_gl_compute.unavailable() is None


@pytest.mark.parametrize("name", sorted(SCENES))
def test_every_view_agrees_with_the_cpu_renderer(name):
    got, expected = scene_against_cpu(name, "gl-compute")  # "layered": partial tiles
    if name == "layered":  # where pixels stop early the tiles agree with cpu to float rounding
        assert np.abs(got - expected).max() < 1e-4


@pytest.mark.parametrize("name", sorted(SCENES))
def test_splats_staged_as_float16_keep_60_db(ctx, name):
    gaussians = SCENES[name]()
    fp16 = _render(ctx, gaussians, *CAMERAS, W, H, precision="fp16")
    assert_close(fp16, render_cpu(gaussians, *CAMERAS, W, H))
    assert np.abs(fp16 - _render(ctx, gaussians, *CAMERAS, W, H)).max() > 1e-5  # it is another staging


@pytest.mark.parametrize("opacity", [(0.05, 0.3), (0.9, 1.0)], ids=["translucent", "opaque"])
def test_many_overlapping_gaussians_fill_tiles_past_one_staging_batch(ctx, opacity):
    gaussians = crowd_scene(opacity=opacity)
    stats = {}
    got = _render(ctx, gaussians, *CAMERAS, W, H, background=(0.2, 0.1, 0.0), stats=stats)
    expected = render_cpu(gaussians, *CAMERAS, W, H, background=(0.2, 0.1, 0.0))
    assert stats["intersections"] > 4 * 4 * 256  # 4 views, several tiles each above 256 splats
    assert (expected[..., 3] > 0.9).mean() > 0.1
    assert_close(got, expected)


def test_one_gaussian_lands_where_it_projects(ctx):
    viewmats, ks = CAMERAS
    point = np.array([0.05, -0.08, 0.1])
    out = _render(ctx, _single(point, 0.02), viewmats, ks, W, H)
    assert_close(out, render_cpu(_single(point, 0.02), viewmats, ks, W, H))
    for view in range(len(viewmats)):
        cam = viewmats[view, :3, :3] @ point + viewmats[view, :3, 3]
        u, v = (ks[view] @ cam)[:2] / cam[2]
        assert np.unravel_index(out[view, ..., 3].argmax(), (H, W)) == (round(v), round(u))


@pytest.mark.parametrize("n_views, size", [(1, (40, 30)), (32, (48, 27))])
def test_one_and_32_views_of_the_demo_avatar_agree_with_the_cpu_renderer(ctx, n_views, size):
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar

    rig = make_demo_avatar(seed=2, count=3000)
    gaussians = rig.deform(rig.neutral_controls()).to_numpy()
    cameras = make_cameras("arc", gaussians, n_views, view_size=size)
    expected = render_cpu(gaussians, cameras.viewmats, cameras.K, *size)
    assert (expected[..., 3] > 0.5).mean() > 0.05
    assert_close(_render(ctx, gaussians, cameras.viewmats, cameras.K, *size), expected)


def test_splats_go_only_to_the_tiles_their_ellipse_reaches_on_each_tile_row(ctx):
    # fewer pairs than the ellipses' bounding boxes in whole tiles, which hold the same pixels
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.renderers.gl_upload import host_records

    rig = make_demo_avatar(seed=2, count=6000)
    gaussians = rig.deform(rig.neutral_controls()).to_numpy()
    cameras = make_cameras("arc", gaussians, 4, view_size=(320, 180))
    records = np.concatenate(host_records(gaussians, cameras.viewmats, cameras.K, 320, 180)).astype(np.float64)
    mx, my, slope, q, ext_y = records[:, 0], records[:, 1], records[:, 9], records[:, 10], records[:, 11]
    half_x = ext_y * np.sqrt(slope ** 2 + q)
    columns = np.clip(np.ceil((mx + half_x) / 16), 0, 20) - np.clip(np.floor((mx - half_x) / 16), 0, 20)
    rows = np.clip(np.ceil((my + ext_y) / 16), 0, 12) - np.clip(np.floor((my - ext_y) / 16), 0, 12)
    stats = {}
    out = _render(ctx, gaussians, cameras.viewmats, cameras.K, 320, 180, stats=stats)
    assert stats["intersections"] < 0.9 * (columns * rows).sum()  # measured: 93445 against 109647
    assert_close(out, render_cpu(gaussians, cameras.viewmats, cameras.K, 320, 180))


@pytest.mark.parametrize("gaussians", [
    _gaussians(np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 1, 3))),
    _single((0.0, 0.0, -3.0), 0.1),  # behind every camera
], ids=["no Gaussians", "all culled"])
def test_empty_views_hold_the_background(ctx, gaussians):
    out = _render(ctx, gaussians, *CAMERAS, W, H, background=(0.25, 0.5, 0.75))
    np.testing.assert_array_equal(out[..., :3], np.broadcast_to(np.float32([0.25, 0.5, 0.75]), (4, H, W, 3)))
    np.testing.assert_array_equal(out[..., 3], 0)


def test_a_renderer_reused_leaves_nothing_of_the_last_frame(ctx):
    with ctx:
        renderer = GLComputeRenderer(ctx, 4, W, H)
        got = []
        for g in (crowd_scene(), random_scene(0, n=10, seed=6), _single((0.0, 0.0, -3.0), 0.1)):
            renderer.render(g, *CAMERAS)
            got.append(renderer.read())
        renderer.release()
    np.testing.assert_array_equal(got[1], _render(ctx, random_scene(0, n=10, seed=6), *CAMERAS, W, H))
    np.testing.assert_array_equal(got[2], 0)


@pytest.mark.parametrize("limit", ["views", "intersections"])
def test_views_go_in_batches_within_the_drivers_storage_block_size(ctx, monkeypatch, limit):
    gaussians = crowd_scene(n=300)
    ks = CAMERAS[1].copy()
    ks[:, :2] *= 4  # views of 256x192: many tiles
    views = (CAMERAS[0], ks, 256, 192) if limit == "intersections" else (*CAMERAS, W, H)
    expected = _render(ctx, gaussians, *views, background=(0.1, 0.2, 0.3))
    pairs = []
    for view in range(4):
        stats = {}
        _render(ctx, gaussians, CAMERAS[0][view:view + 1], ks[view:view + 1], 256, 192, stats=stats)
        pairs.append(stats["intersections"])
    # "views": the Gaussians and the records of one view (300 x 48 bytes) fit, of two do not; "intersections": the
    # records of all four fit, but not the splat-tile pairs of all four, nor of views 2 and 3
    # (the batch is halved, then halved again), while those of the busiest view do
    size = 300 * 88 if limit == "views" else 4 * max(pairs) + 3  # 88: a Gaussian of SH degree 1 in GAUSS
    if limit == "intersections":
        assert size >= 4 * 300 * 48 and 4 * (pairs[2] + pairs[3]) > size
    monkeypatch.setattr(GLComputeRenderer, "_storage_limit", lambda self: size)
    np.testing.assert_array_equal(_render(ctx, gaussians, *views, background=(0.1, 0.2, 0.3)), expected)


def test_too_many_pairs_for_one_view_are_a_one_line_display_error(ctx, monkeypatch):
    monkeypatch.setattr(GLComputeRenderer, "_storage_limit", lambda self: 300 * 88)
    ks = CAMERAS[1][3:].copy()
    ks[:, :2] *= 4  # about 20000 pairs in a view of 256x192, 80 kB
    with pytest.raises(DisplayError, match=r"one view's \d{5} splat-tile pairs exceed the OpenGL driver's shader "
                                           r"storage block size \(26400 bytes\)") as err:
        _render(ctx, crowd_scene(n=300), CAMERAS[0][3:], ks, 256, 192)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("length, values", [(5000, 1 << 16), (3000, 7)])
def test_the_sort_of_16_bit_keys_is_stable_in_two_passes(ctx, length, values):
    rng = np.random.default_rng(length)
    keys = rng.integers(0, values, length, dtype=np.uint64).astype(np.uint32)
    vals = rng.permutation(1 << 20)[:length].astype(np.uint32)
    with ctx:
        sorter = GLSorter(ctx)
        kbuf, vbuf = ctx.buffer(keys.tobytes()), ctx.buffer(vals.tobytes())
        sorter.sort(kbuf, vbuf, length, 1, bits=16)
        got_k, got_v = np.frombuffer(kbuf.read(), np.uint32), np.frombuffer(vbuf.read(), np.uint32)
        with pytest.raises(InputError, match="must be 16 or 32") as err:
            sorter.sort(kbuf, vbuf, length, 1, bits=24)
        assert err.value.source == "bits"
        for obj in (kbuf, vbuf, sorter):
            obj.release()
    order = np.argsort(keys, kind="stable")
    np.testing.assert_array_equal(got_k, keys[order])
    np.testing.assert_array_equal(got_v, vals[order])


class _GPU(OpenGL41):
    """The test context as a GPU's driver would report it (OpenGL 4.6, not a CPU rasterizer)."""

    version_code = 460

    @property
    def info(self):
        return dict(self._ctx.info, GL_RENDERER="NVIDIA H100 80GB HBM3/PCIe/SSE2")


@pytest.mark.parametrize("wrap, prefer, which, reason", [
    (_GPU, None, "gl-compute", None),
    (lambda c: c, None, "gl triangles", None),  # llvmpipe: the triangles are faster there
    (lambda c: c, "compute", "gl-compute", None),
    (lambda c: c, "triangles", "gl triangles", None),
    (OpenGL41, None, "gl triangles", None),
    (OpenGL41, "compute", "gl triangles",
     "the gl-compute renderer draws triangles (the gl renderer): OpenGL 4.1 has no compute shaders (4.3 needed)"),
    (NoVertexStorage, "compute", "gl-compute", None),  # compute needs no vertex storage buffers
], ids=["gpu", "llvmpipe", "compute asked", "triangles asked", "gl 4.1", "gl 4.1 compute asked", "no vertex ssbo"])
def test_the_path_is_chosen_by_the_driver_and_said(ctx, wrap, prefer, which, reason):
    with ctx:
        renderer, got_which, got_reason = gl_renderer_for(wrap(ctx), 4, W, H, prefer)
        renderer.release()
    assert (got_which, got_reason) == (which, reason)
    assert isinstance(renderer, GLComputeRenderer if which == "gl-compute" else GLSplatRenderer)


def test_refusals_are_one_line_errors(ctx):
    with ctx:
        renderer = GLComputeRenderer(ctx, 2, W, H)
        assert_refuses_other_view_counts(renderer)
        renderer.release()
        for kwargs, source in ((dict(precision="fp8"), "precision"), (dict(n_views=0), "n_views")):
            with pytest.raises(InputError) as err:
                GLComputeRenderer(ctx, **{"n_views": 2, "width": W, "height": H, **kwargs})
            assert err.value.source == source
        with pytest.raises(DisplayError, match=r"cannot run here: OpenGL 4\.1 has no compute shaders") as err:
            GLComputeRenderer(OpenGL41(ctx), 2, W, H)
        assert "\n" not in str(err.value)
        with pytest.raises(InputError) as err:
            gl_renderer_for(ctx, 2, W, H, prefer="tiles")
        assert err.value.source == "prefer"


def test_torch_gaussians_and_a_background_render_like_numpy_ones():
    gaussians = random_scene(1, n=50)
    plain = render_gl_compute(gaussians, *CAMERAS, W, H)
    np.testing.assert_array_equal(render_gl_compute(gaussians.to_torch(), *CAMERAS, W, H), plain)
    over = render_gl_compute(gaussians, *CAMERAS, W, H, background=(0.2, 0.4, 0.6))
    np.testing.assert_array_equal(over[..., 3], plain[..., 3])
    np.testing.assert_allclose(over[..., :3], plain[..., :3] + (1 - plain[..., 3:]) * [0.2, 0.4, 0.6], atol=1e-6)


def test_the_live_pipeline_renders_with_compute_into_the_views_the_encoder_reads(ctx):
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.pipeline.gl_frame import GLFrame

    rig = make_demo_avatar(seed=2, count=3000)
    gaussians = rig.deform(rig.neutral_controls()).to_numpy()
    cameras = make_cameras("arc", gaussians, 4, view_size=(64, 36))
    profile = PanelProfile(views=4, slant=0.19, period=9.7, offset=3.2, reference_view=2, width=128, height=72,
                           subpixel_order="RGB", view_direction=1)
    frames = {}
    with ctx:
        for prefer in ("compute", "triangles"):
            frame = GLFrame(profile, cameras, ctx=ctx, background=(0.1, 0.2, 0.3), prefer=prefer)
            frame.run(gaussians)
            frames[prefer] = (frame.renderer_kind, frame.notes, frame.views(), frame.raster()[0])
            frame.release()
    assert frames["compute"][:2] == ("gl-compute", []) and frames["triangles"][:2] == ("gl triangles", [])
    for got, other in zip(frames["compute"][2:], frames["triangles"][2:]):
        assert np.abs(got.astype(int) - other).max() <= 1 and got.std() > 10


def test_on_a_real_opengl_41_context_the_triangles_run_and_say_so(tmp_path):
    done = run_under_opengl_41(f"""
from lenticalib.render.renderers.gl_compute import render_gl_compute
np.save({str(tmp_path / "out.npy")!r}, render_gl_compute(random_scene(3, n=80), *CAMERAS, W, H))
""")
    assert ("the gl-compute renderer draws triangles (the gl renderer): OpenGL 4.1 has no compute shaders"
            in done.stderr)
    assert_close(np.load(tmp_path / "out.npy"), render_cpu(random_scene(3, n=80), *CAMERAS, W, H))


def test_the_avatar_loop_renders_gl_compute_in_its_gl_frame_never_reading_it_back(tmp_path, monkeypatch):
    # and --renderer gl, on llvmpipe, with the triangles
    from lenticalib.render.avatar.sources import load_avatar
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.pipeline.avatar_pipeline import AvatarPipeline
    from lenticalib.render.avatar.rig_file import save_rig

    save_rig(tmp_path / "demo.npz", make_demo_avatar(seed=1, count=3000))
    avatar = load_avatar(tmp_path / "demo.npz")
    profile = PanelProfile(views=4, slant=0.19, period=9.7, offset=3.2, reference_view=2, width=128, height=72,
                           subpixel_order="RGB", view_direction=1)
    cameras = make_cameras("arc", avatar.bounding_box(), 4, view_size=(64, 36))
    calls = []
    original = GLComputeRenderer.render
    monkeypatch.setattr(GLComputeRenderer, "render", lambda self, *a, **k: calls.append(1) or original(self, *a, **k))
    monkeypatch.setattr(GLComputeRenderer, "read", lambda self: pytest.fail("the float views were read back"))
    rasters = {}
    for renderer in ("gl-compute", "gl"):
        pipeline = AvatarPipeline(avatar, profile, cameras, renderer=renderer, encoder="gl")
        assert pipeline.draws_on_gpu
        rasters[renderer] = pipeline.frame(None)[0]
        pipeline.close()
        assert pipeline.notes == [] and len(calls) == 1  # gl: the triangles, on llvmpipe
    assert np.abs(rasters["gl-compute"].astype(int) - rasters["gl"]).max() <= 1 and rasters["gl"].std() > 10
