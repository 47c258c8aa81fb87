"""The sensor's clipped noise read from a camera JPEG's coarse detail (lenticalib.calib.crosstalk.dark.block_noise)
on black photos of a simulated camera: a Bayer sensor whose noise is clipped at 0, demosaiced,
encoded to 8-bit sRGB and written as a 4:2:0 JPEG, with a known sigma and light under the clipping."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.stats import norm

from lenticalib.calib.crosstalk import dark, tone_models
from lenticalib.core.colour import srgb_decode, srgb_encode


def _jpeg_black(light, sigma: float, seed: int = 11, size=(640, 480), quality: int = 85) -> np.ndarray:
    """float (h, w, 3): the linear light of a camera JPEG of a black whose light is ``light`` (a number
    or an (h, w) map), with sensor noise ``sigma`` clipped at 0 at each RGGB site, demosaiced (OpenCV's
    edge-aware), encoded as 8-bit sRGB, compressed at ``quality`` with 4:2:0 chroma and decoded."""
    w, h = size
    rng = np.random.default_rng(seed)
    sensor = np.clip(np.broadcast_to(light, (h, w)) + rng.normal(0.0, sigma, (h, w)), 0.0, 1.0)
    rgb = cv2.demosaicing(np.round(sensor * 65535).astype(np.uint16), cv2.COLOR_BayerRGGB2RGB_EA) / 65535.0
    codes = np.clip(np.rint(255 * srgb_encode(rgb)), 0, 255).astype(np.uint8)
    ok, data = cv2.imencode(".jpg", codes[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, quality])
    assert ok
    decoded = cv2.imdecode(data, cv2.IMREAD_COLOR)[:, :, ::-1]
    return srgb_decode(decoded / 255.0)


def _clipped_mean(light: float, sigma: float) -> float:
    t = light / sigma
    return sigma * (t * norm.cdf(t) + norm.pdf(t))


@pytest.mark.parametrize("light", [0.0, 0.004, 0.012])
def test_a_jpeg_s_blocks_give_the_sensor_s_sigma_where_its_pixels_at_zero_read_it_short(light):
    """Black at 0, 2/3 and 2 sigma: the sigma from the blocks' spread within the range the
    measurement carries (``SIGMA_RANGE``: the sensor's over the read 0.54-1.6; OpenCV's edge-aware
    demosaicing leaves red's and blue's blocks smoother than their sites, most where half of them
    are at 0), green's within 20 %, and the clipping's light (mean less light), the channels' mean,
    within the range the tone curve carries (``BIAS_RANGE``), never negative; the share of pixels
    at 0, read on every pixel as a JPEG gives no sites, takes sigma at most 0.75 of the truth
    (demosaicing and compression leave fewer pixels at 0)."""
    sigma = 0.006
    black = _jpeg_black(light, sigma)
    found = dark.block_noise(black)
    assert found is not None
    low, high = dark.SIGMA_RANGE
    assert np.all((sigma / found.sigma >= low) & (sigma / found.sigma <= high)), found.sigma
    assert found.sigma[1] == pytest.approx(sigma, rel=0.2)
    true_bias = _clipped_mean(light, sigma) - light
    assert np.all(found.bias() >= 0)
    low, high = tone_models.BIAS_RANGE  # the light the tone curve's relations take off black
    assert low <= true_bias / float(np.mean(found.bias())) <= high, (found.bias(), true_bias)
    at_zero = dark.clipping_noise(black, black <= 0, sites=False)
    if at_zero is not None:  # a black clipped rarely shows too few zeros to read at all
        assert np.all(at_zero.sigma < 0.75 * sigma)


def test_a_black_far_above_its_noise_has_no_clipping_light_and_a_slow_glare_does_not_count():
    """Black at 8 sigma with a glare rising across the photo by 4 sigma: the clipping's light is
    nearly 0 (under 2 % of sigma) and the slow change is not taken for noise (sigma within
    ``SIGMA_RANGE``, green's within 20 %, as on a flat black)."""
    sigma = 0.003
    x = np.linspace(0.0, 1.0, 640)[None, :] * np.ones((480, 1))
    black = _jpeg_black(0.024 + 4 * sigma * x, sigma, seed=4)
    found = dark.block_noise(black)
    low, high = dark.SIGMA_RANGE
    assert np.all((sigma / found.sigma >= low) & (sigma / found.sigma <= high)), found.sigma
    assert found.sigma[1] == pytest.approx(sigma, rel=0.2)
    assert np.all(np.abs(found.bias()) < 0.02 * sigma)


def test_the_measurement_s_dark_clipping_takes_a_jpeg_s_sigma_from_its_blocks():
    """dark.clipping_noise on a JPEG's black (no sensor sites show): the blocks' sigma, not the
    share of pixels at 0's; with too few blocks (a tiny photo) nothing is read from them."""
    sigma = 0.006
    black = _jpeg_black(0.002, sigma)
    noise = dark.clipping_noise(black, black <= 0)
    assert noise is not None and all(tuple(s) == dark.ALL_PHASES for s in noise.sites)
    np.testing.assert_allclose(noise.sigma, dark.block_noise(black).sigma)
    assert dark.block_read_sigma(noise) == pytest.approx(float(np.mean(noise.sigma)))
    assert dark.block_noise(black[:48, :64]) is None


def test_reclipping_an_image_moves_each_pixel_by_its_area_s_change_not_by_its_own():
    """A noisy image unclipped with a sigma, reclipped with 1.5 times it: its mean moves as the area
    means reclipped do (within 2 % of the change; the clipped mean's curvature taken on each noisy
    pixel moved it 17 % further); places far above the noise keep their pixels."""
    sigma, rng = 0.004, np.random.default_rng(2)
    smooth = np.full((120, 160), 3 * 0.003)  # three channels' light, 0.75 sigma each
    noisy = (smooth + rng.normal(0.0, 3 * sigma, smooth.shape)).astype(np.float32)
    moved = dark.reclipped(noisy, sigma, 1.5)
    expected = float(dark.reclipped(smooth[:1, 0], sigma, 1.5)[0]) - smooth[0, 0]
    assert float(np.mean(moved - noisy)) == pytest.approx(expected, rel=0.02)
    bright = np.full((40, 40), 0.5, np.float32) + rng.normal(0.0, 0.01, (40, 40)).astype(np.float32)
    np.testing.assert_array_equal(dark.reclipped(bright, sigma, 1.5), bright)
