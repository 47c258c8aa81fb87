"""The GPU views stage (background, edge desaturation, 8-bit codes, crosstalk pre-compensation) on
Mesa, against the host path it replaces; and ``encode --compensate`` with the gl encoder."""

import json

import numpy as np
import pytest

from lenticalib.core.errors import DisplayError
from lenticalib.core.profile import PanelProfile
from lenticalib.render.compose.compensation import Compensator
from lenticalib.render.encoders import compensates_on_device, encode
from lenticalib.render.gpu.gl_context import headless_context
from lenticalib.render.compose.gl_views import GLViewStage
from lenticalib.render.compose.host_views import desaturate_edges, to_uint8


def _rendered(n, h, w, seed):
    """(n, h, w, 4) float32 premultiplied RGBA with transparent, opaque and partial pixels."""
    rng = np.random.default_rng(seed)
    alpha = rng.random((n, h, w, 1), dtype=np.float32)
    alpha[:, :3] = 0.0
    alpha[:, 3:6] = 1.0
    rgba = np.concatenate([rng.random((n, h, w, 3), dtype=np.float32) * alpha, alpha], axis=-1)
    return np.ascontiguousarray(rgba, dtype=np.float32)


def _compensator(n, lift=0.02, iterations=2):
    idx = np.arange(n)
    ring = np.abs((idx[:, None] - idx[None, :] + n // 2) % n - n // 2)
    return Compensator.from_matrix(0.78 * np.eye(n) + 0.09 * (ring == 1) + 0.02 * (ring == 2), black_lift=lift,
                                   iterations=iterations)


def _host(rgba, background, desaturation, compensator):
    """What AvatarPipeline does on the host for the cpu renderer."""
    x = rgba.copy()
    if background is not None:
        x[..., :3] += (1.0 - x[..., 3:4]) * (background if background.ndim == 1 else background[None])
    rgb = desaturate_edges(x, desaturation) if desaturation > 0 else x
    views = to_uint8(np.ascontiguousarray(rgb))
    return compensator.apply(views) if compensator is not None else views


@pytest.fixture(scope="module")
def ctx():
    context = headless_context(require=430)
    yield context
    context.release()


@pytest.mark.parametrize("background", ["none", "colour", "image"])
@pytest.mark.parametrize("desaturation", [0.0, 0.7])
@pytest.mark.parametrize("compensate", [False, True])
def test_the_gpu_views_stage_matches_the_host_path(ctx, background, desaturation, compensate):
    n, h, w = 7, 19, 33
    rgba = _rendered(n, h, w, seed=len(background) + int(10 * desaturation) + compensate)
    rng = np.random.default_rng(5)
    bg = {"none": None, "colour": np.array([0.1, 0.45, 0.8], np.float32),
          "image": rng.random((h, w, 3), dtype=np.float32)}[background]
    compensator = _compensator(n) if compensate else None
    expected = _host(rgba, bg, desaturation, compensator)
    with ctx:
        source = ctx.texture_array((w, h, n), 4, rgba.tobytes(), dtype="f4")
        stage = GLViewStage(ctx, n, w, h, background=bg, edge_desaturation=desaturation, compensator=compensator)
        stage.run(source)
        got = stage.read()
        stage.release()
        source.release()
    diff = np.abs(got.astype(np.int32) - expected)
    assert diff.max() <= (1 if compensate else 0)
    assert (diff == 0).mean() > 0.999


def test_the_views_stage_needs_compute_shaders_and_says_so():
    class OldDriver:
        version_code = 410

    with pytest.raises(DisplayError, match=r"needs OpenGL 4\.3 compute shaders, the driver has 4\.1") as caught:
        GLViewStage(OldDriver(), 8, 16, 9)
    assert "on the host instead" in str(caught.value)


def test_gl_compensates_on_the_gpu_within_one_level_of_the_host():
    assert compensates_on_device("gl") and not compensates_on_device("fast")
    n = 8
    profile = PanelProfile(views=n, slant=0.19, period=7.4, offset=1.5, reference_view=4, width=96, height=54,
                           subpixel_order="BGR")
    views = np.random.default_rng(2).integers(0, 256, (n, 27, 48, 3), dtype=np.uint8)
    compensator = _compensator(n, lift=0.05, iterations=3)
    host = encode(compensator.apply(views), profile, "reference").astype(np.int32)
    gpu = encode(views, profile, "gl", compensator=compensator).astype(np.int32)
    plain = encode(views, profile, "gl").astype(np.int32)
    assert np.abs(gpu - host).max() <= 1
    assert np.abs(plain - host).max() > 10  # the compensation did something
    fast = encode(views, profile, "fast", compensator=compensator).astype(np.int32)  # on the host
    assert np.abs(fast - host).max() <= 1


def test_encode_cli_compensates_on_the_gpu_with_the_gl_encoder(tmp_path, cli):
    from lenticalib.core.files.imageio import read_image, write_image

    n = 8
    profile = {"views": n, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4,
               "width": 96, "height": 54, "subpixel_order": "BGR"}
    (tmp_path / "panel.json").write_text(json.dumps(profile))
    views = np.random.default_rng(0).integers(0, 256, (n, 27, 48, 3), dtype=np.uint8)
    folder = tmp_path / "views"
    folder.mkdir()
    for i, view in enumerate(views):
        write_image(folder / f"view-{i:02d}.png", view)
    matrix = _compensator(n).mixing[(np.arange(n)[None, :] - np.arange(n)[:, None]) % n]
    (tmp_path / "crosstalk.json").write_text(json.dumps({"format": "lenticalib.crosstalk", "format_version": 1,
                                                         "views": n, "matrix": matrix.tolist()}))
    outputs = {}
    for name in ("gl", "fast"):
        code, out, err = cli("encode", "--profile", tmp_path / "panel.json", "--views-dir", folder, "--encoder", name,
                             "--compensate", tmp_path / "crosstalk.json", "-o", tmp_path / f"{name}.png", "--json")
        assert code == 0, err
        outputs[name] = json.loads(out)
    assert outputs["gl"]["compensated_on"] == "gpu" and outputs["fast"]["compensated_on"] == "host"
    gl, fast = (read_image(tmp_path / f"{name}.png").astype(np.int32) for name in ("gl", "fast"))
    assert np.abs(gl - fast).max() <= 1
