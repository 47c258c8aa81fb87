"""The ``cpu`` renderer: agreement with gsplat's pure-torch forward pass, geometry, refusals.

Agreement: on the scenes below (SH degree 0 and 3, four cameras with off-centre principal points,
anisotropic focal lengths and rotations, stacked opaque layers that stop pixels early, Gaussians
reaching behind the camera and far off the field of view) the renderer matches
:func:`tests.gsplat_reference.render_reference` at 133-142 dB PSNR per view, RGB and alpha (max
abs difference 4e-6: float32 rounding and the kernels' polynomial exp).  The tests assert
>= 60 dB, which one pixel whose alpha sits on the 1/255 threshold and rounds the other way on
another CPU (0.004 in one pixel, about 90 dB) still passes.
"""

import math

import numpy as np
import pytest

from lenticalib.core.errors import BackendUnavailableError, InputError
from lenticalib.render.avatar.gaussians import SH_C0, Gaussians
from lenticalib.render.renderers import available_renderers, get_renderer, render
from lenticalib.render.renderers.cpu import render_cpu

W, H = 64, 48


def _look_at(eye, target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0)):
    """World-to-camera (4, 4), OpenCV camera (x right, y down, z forward), world y up."""
    eye = np.asarray(eye, dtype=np.float64)
    forward = np.asarray(target, dtype=np.float64) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rot = np.stack([right, down, forward])
    vm = np.eye(4)
    vm[:3, :3] = rot
    vm[:3, 3] = -rot @ eye
    return vm


def _k(fx, fy, cx, cy):
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


# four cameras: centred, off-centre principal points, anisotropic focal lengths, a rotated close one
CAMERAS = (
    np.stack([_look_at((0, 0, -2.0)), _look_at((0.8, 0.3, -1.8)), _look_at((-1.0, -0.5, -1.5), (0.1, 0, 0)),
              _look_at((0.2, 0.1, -0.7), (0, 0, 0), up=(0.3, 1.0, 0.0))]),
    np.stack([_k(60, 60, (W - 1) / 2, (H - 1) / 2), _k(70, 65, 20.0, 30.0), _k(50, 50, 40.2, 10.7),
              _k(55, 62, 35.0, 20.0)]),
)


def _random_quats(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _gaussians(means, quats, scales, opacities, sh):
    f = np.float32
    return Gaussians(np.asarray(means, f), np.asarray(quats, f), np.asarray(scales, f),
                     np.asarray(opacities, f), np.asarray(sh, f))


def random_scene(degree, n=250, seed=0):
    rng = np.random.default_rng(seed)
    return _gaussians(rng.normal(0, 0.3, (n, 3)), _random_quats(rng, n), np.exp(rng.normal(-3, 0.7, (n, 3))),
                      rng.uniform(0, 1, n), rng.normal(0, 0.3, (n, (degree + 1) ** 2, 3)))


def layered_scene(seed=1):
    """Large, nearly opaque Gaussians stacked in depth: pixels stop after a few layers."""
    rng = np.random.default_rng(seed)
    n = 40
    means = np.column_stack([rng.uniform(-0.2, 0.2, n), rng.uniform(-0.2, 0.2, n), np.linspace(-0.5, 0.5, n)])
    return _gaussians(means, _random_quats(rng, n), rng.uniform(0.1, 0.3, (n, 3)), rng.uniform(0.9, 1.0, n),
                      rng.normal(0, 0.5, (n, 4, 3)))


def near_scene(seed=2):
    """Gaussians around the first camera (at z = -2): reaching behind it, beside it, behind the near plane."""
    rng = np.random.default_rng(seed)
    means = [(0.0, 0.0, -1.9), (0.15, -0.1, -1.95), (0.5, 0.0, -1.8), (-0.6, 0.4, -1.85),  # close, big
             (0.0, 0.0, -2.005),  # between the camera and its near plane: culled
             (0.0, 0.0, -2.5),  # behind the camera: culled
             (0.0, 0.0, 0.0), (0.1, 0.05, 0.2)]
    n = len(means)
    scales = np.array([[0.2, 0.2, 0.2], [0.05, 0.3, 0.1], [0.3, 0.1, 0.2], [0.2, 0.2, 0.5],
                       [0.3, 0.3, 0.3], [1.0, 1.0, 1.0], [0.2, 0.1, 0.1], [0.1, 0.2, 0.1]])
    return _gaussians(means, _random_quats(rng, n), scales, rng.uniform(0.3, 0.9, n), rng.normal(0, 0.4, (n, 9, 3)))


def _psnr(a, b):
    mse = float(np.mean((a.astype(np.float64) - b) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(1.0 / mse)


SCENES = {"random_sh0": lambda: random_scene(0), "random_sh3": lambda: random_scene(3, seed=3),
          "layered": layered_scene, "near": near_scene}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_agrees_with_gsplats_torch_reference(name):
    from .gsplat_reference import render_reference

    gaussians = SCENES[name]()
    viewmats, ks = CAMERAS
    background = (0.1, 0.2, 0.3) if name != "near" else None
    width, height = (W, H) if name != "layered" else (50, 37)  # partial tiles
    expected = render_reference(gaussians, viewmats, ks, width, height, background)
    got = render_cpu(gaussians, viewmats, ks, width, height, background=background)
    assert got.shape == expected.shape and got.dtype == np.float32
    assert expected[..., 3].max() > 0.5  # the scene is seen
    for view in range(len(viewmats)):
        assert _psnr(got[view, ..., :3], expected[view, ..., :3]) >= 60, f"view {view} RGB"
        assert _psnr(got[view, ..., 3], expected[view, ..., 3]) >= 60, f"view {view} alpha"


def test_layered_scene_stops_pixels_early():
    # the scene must exercise the T <= 1e-4 stop, or the agreement test above would not cover it
    out = render_cpu(layered_scene(), *CAMERAS, 50, 37)
    assert ((out[..., 3] > 0.999).mean(axis=(1, 2)) > 0.2).all()


def _single(point, sigma, opacity=0.8, colour=(1.0, 0.5, 0.25)):
    sh = ((np.asarray(colour) - 0.5) / SH_C0)[None, None, :]
    return _gaussians([point], [[1, 0, 0, 0]], [[sigma] * 3], [opacity], sh)


@pytest.mark.parametrize("view", range(4))
def test_an_isotropic_gaussian_peaks_where_k_and_the_viewmat_project_it(view):
    viewmats, ks = CAMERAS
    point = np.array([0.05, -0.08, 0.1])
    cam = viewmats[view, :3, :3] @ point + viewmats[view, :3, 3]
    u, v = (ks[view] @ cam)[:2] / cam[2]  # OpenCV pixel coordinates
    sigma = 2.0 * cam[2] / ks[view, 0, 0]  # about 2 px
    alpha = render_cpu(_single(point, sigma), viewmats[view:view + 1], ks[view:view + 1], W, H)[0, ..., 3]
    ys, xs = np.mgrid[:H, :W]
    total = alpha.sum()
    centroid = ((alpha * xs).sum() / total, (alpha * ys).sum() / total)
    assert np.hypot(centroid[0] - u, centroid[1] - v) < 0.02
    assert np.unravel_index(alpha.argmax(), alpha.shape) == (round(v), round(u))


def test_a_single_gaussian_has_its_colour_and_opacity_at_the_peak():
    viewmats, ks = CAMERAS
    out = render_cpu(_single((0.0, 0.0, 0.0), 0.1), viewmats[:1], ks[:1], W, H)[0]
    # camera 0 sees the centre at (31.5, 23.5), 2 units away: 2D variance (60 * 0.1 / 2)^2 + 0.3 (eps2d)
    # on both axes; pixel (32, 24) is (0.5, 0.5) away
    variance = (60 * 0.1 / 2.0) ** 2 + 0.3
    alpha = 0.8 * math.exp(-0.5 * (0.5 ** 2 + 0.5 ** 2) / variance)
    np.testing.assert_allclose(out[24, 32, 3], alpha, rtol=1e-5)
    np.testing.assert_allclose(out[24, 32, :3], np.array([1.0, 0.5, 0.25]) * alpha, rtol=1e-5)


def test_background_is_composited_under_the_premultiplied_colour():
    gaussians = random_scene(3, n=60)
    plain = render_cpu(gaussians, *CAMERAS, W, H)
    over = render_cpu(gaussians, *CAMERAS, W, H, background=(0.2, 0.4, 0.6))
    np.testing.assert_array_equal(over[..., 3], plain[..., 3])
    np.testing.assert_allclose(over[..., :3], plain[..., :3] + (1 - plain[..., 3:]) * [0.2, 0.4, 0.6], atol=1e-6)


@pytest.mark.parametrize("gaussians", [
    _gaussians(np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 1, 3))),
    _single((0.0, 0.0, -3.0), 0.1),  # behind every camera
], ids=["no Gaussians", "all culled"])
def test_an_empty_scene_renders_the_background(gaussians):
    out = render_cpu(gaussians, *CAMERAS, W, H, background=(0.25, 0.5, 0.75))
    assert out.shape == (4, H, W, 4)
    np.testing.assert_array_equal(out[..., :3], np.broadcast_to([0.25, 0.5, 0.75], (4, H, W, 3)))
    np.testing.assert_array_equal(out[..., 3], 0)


def test_torch_gaussians_render_like_numpy_ones():
    import torch
    gaussians = random_scene(1, n=50)
    assert isinstance(gaussians.to_torch().means, torch.Tensor)
    np.testing.assert_array_equal(render_cpu(gaussians.to_torch(), *CAMERAS, W, H),
                                  render_cpu(gaussians, *CAMERAS, W, H))


def _bad(**change):
    viewmats, ks = CAMERAS
    args = dict(gaussians=random_scene(0, n=5), viewmats=viewmats, Ks=ks, width=W, height=H, background=None)
    args.update(change)
    return args


def _shear():
    vm = CAMERAS[0].copy()
    vm[1, 0, 1] += 0.1
    return vm


def _skewed():
    ks = CAMERAS[1].copy()
    ks[2, 0, 1] = 0.5
    return ks


@pytest.mark.parametrize("change, source", [
    (dict(viewmats=np.eye(4)), "viewmats"),
    (dict(viewmats=np.zeros((0, 4, 4)), Ks=np.zeros((0, 3, 3))), "viewmats"),
    (dict(Ks=CAMERAS[1][:3]), "Ks"),
    (dict(Ks=np.zeros((4, 4, 4))), "Ks"),
    (dict(viewmats=_shear()), "viewmats"),
    (dict(Ks=_skewed()), "Ks"),
    (dict(Ks=CAMERAS[1] * np.nan), "Ks"),
    (dict(width=0), "width"),
    (dict(height=-3), "height"),
    (dict(width=64.0), "width"),
    (dict(height=True), "height"),
    (dict(background=(1.0, 0.0)), "background"),
    (dict(gaussians=_gaussians(np.zeros((2, 3)), np.zeros((2, 4)), np.ones((2, 3)), np.ones(2), np.zeros((2, 1, 3)))),
     "gaussians"),  # zero-length quaternions
    (dict(gaussians=_gaussians(np.zeros((2, 3)), np.ones((2, 4)), np.ones((2, 3)), np.ones(2), np.zeros((2, 5, 3)))),
     "gaussians"),  # K = 5 SH coefficients
    (dict(gaussians="avatar.ply"), "gaussians"),
])
def test_bad_inputs_are_one_line_input_errors(change, source):
    with pytest.raises(InputError) as err:
        render_cpu(**_bad(**change))
    assert err.value.source == source
    assert "\n" not in str(err.value)


def test_the_registry_knows_the_renderers_and_refuses_others():
    assert available_renderers() == ["cpu", "gl", "gl-compute", "gsplat"]
    assert get_renderer("cpu") is render_cpu
    with pytest.raises(InputError, match="unknown renderer 'opengl'") as err:
        get_renderer("opengl")
    assert err.value.source == "renderer"
    np.testing.assert_array_equal(render(random_scene(0, n=20), *CAMERAS, W, H, renderer="cpu"),
                                  render_cpu(random_scene(0, n=20), *CAMERAS, W, H))


def test_the_gsplat_renderer_says_it_needs_a_cuda_gpu():
    import torch

    if torch.cuda.is_available():  # the GPU machine: the batched call must run and stay on the GPU
        out = render(random_scene(0, n=5), *CAMERAS, W, H, renderer="gsplat")
        assert out.is_cuda and tuple(out.shape) == (len(CAMERAS[0]), H, W, 4)
        return
    with pytest.raises(BackendUnavailableError, match="CUDA GPU") as err:
        render(random_scene(0, n=5), *CAMERAS, W, H, renderer="gsplat")
    assert err.value.source == "renderer"


def test_non_finite_gaussians_are_refused_and_huge_ones_do_not_break_the_kernels():
    g = random_scene(0, n=5)
    g.means[2, 1] = np.nan
    with pytest.raises(InputError, match="means has non-finite values"):
        render_cpu(g, *CAMERAS, W, H)
    g = random_scene(0, n=5)
    g.scales[1] = 1e18  # projected variance beyond float32: culled
    g.scales[3] = 1e6  # covers every pixel of every view
    g.means[4] = (1e25, 0.0, 0.0)  # far off every view
    out = render_cpu(g, *CAMERAS, W, H)
    assert np.isfinite(out).all()
