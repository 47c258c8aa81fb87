"""Photos clipped at zero (lenticalib.calib.crosstalk.dark): sigma measured on a black photo, the bias undone,
for photos clipped pixel by pixel (a JPEG) and for RAW-converter output clipped before demosaicing."""

import cv2
import numpy as np
import pytest

from lenticalib.calib.crosstalk import dark

ALL_SITES = dark.ALL_PHASES


def _photo(seed, light, sigma, shape=(480, 640)):
    """A clipped noisy photo of ``light`` (h, w) in every channel, noise sigma per channel."""
    rng = np.random.default_rng(seed)
    noisy = light[..., None] + rng.normal(0.0, 1.0, shape + (3,)) * np.asarray(sigma)[None, None, :]
    return np.maximum(noisy, 0.0).astype(np.float32)


def _raw_photo(seed, light, sigma):
    """What a RAW converter writes for ``light`` (h, w) on an RGGB sensor: noise of ``sigma``, the
    black level subtracted and clipped at 0 on the mosaic, then OpenCV's edge-aware demosaicing."""
    rng = np.random.default_rng(seed)
    mosaic = light + rng.normal(0.0, sigma, light.shape)
    raw16 = np.clip(mosaic * 65535.0 + 0.5, 0.0, 65535.0).astype(np.uint16)
    rgb = cv2.demosaicing(raw16, cv2.COLOR_BayerRGGB2RGB_EA)
    return rgb.astype(np.float32) / np.float32(65535.0)


def _noise(sigma):
    return dark.ClippingNoise(np.asarray(sigma, float), (ALL_SITES,) * len(sigma))


def test_the_noise_is_measured_on_a_clipped_black_photo():
    y, x = np.mgrid[0:480, 0:640]
    light = 0.002 + 0.004 * x / 640  # a faint gradient (glare), 0.4 to 1.2 sigma of the red channel
    sigma = (0.005, 0.004, 0.006)
    black = _photo(1, light, sigma)
    found = dark.clipping_noise(black, black == 0)
    assert np.allclose(found.sigma, sigma, rtol=0.05), found
    assert found.sites == (ALL_SITES,) * 3  # clipped pixel by pixel: no filter structure


def test_a_photo_that_is_not_clipped_needs_no_correction():
    black = _photo(2, np.full((480, 640), 0.05), (0.003, 0.003, 0.003))
    assert dark.clipping_noise(black, black == 0) is None


def test_the_mean_of_faint_light_is_restored():
    # a faint fringe, 0 to 2 sigma, under noise: clipped, its mean comes out high where it is darkest
    sigma = np.array([0.005, 0.005, 0.005])
    y, x = np.mgrid[0:480, 0:640]
    light = 0.005 * (1.0 + np.cos(2 * np.pi * x / 320.0))  # 0 .. 0.010
    photo = _photo(3, light, sigma)
    fixed = dark.unclip(photo, _noise(sigma))
    for lo, hi in ((150, 170), (470, 490), (0, 10), (310, 330)):  # the darkest columns, and the brightest
        truth = float(light[:, lo:hi].mean())
        before = float(photo[:, lo:hi].mean()) - truth
        after = float(fixed[:, lo:hi].mean()) - truth
        assert abs(after) < max(0.15 * abs(before), 1e-4), (lo, before, after)
    dark_columns = slice(150, 170)
    assert float(photo[:, dark_columns].mean()) - float(light[:, dark_columns].mean()) > 0.0015  # the bias is there


def test_bright_areas_are_left_as_they_are():
    sigma = np.array([0.004, 0.004, 0.004])
    photo = _photo(4, np.full((200, 200), 0.2), sigma, shape=(200, 200))
    assert np.array_equal(dark.unclip(photo, _noise(sigma)), photo)


def test_a_raw_converter_s_photo_is_measured_on_the_filter_s_own_sites():
    """Clipped on the mosaic, then demosaiced: the interpolated pixels are seldom 0 and (edge-aware)
    biased low, so a clipped normal fitted to every pixel takes sigma far too small.  The own sites
    (red (0, 0), green (0, 1) and (1, 0), blue (1, 1) on RGGB) are found, sigma on them is right,
    and a faint light (0 to 1 sigma) is restored where the all-pixel model leaves a bias."""
    sigma = 0.004
    h, w = 960, 640
    black = _raw_photo(5, np.full((h, w), 0.0005), sigma)
    found = dark.clipping_noise(black, black == 0)
    assert found.sites == (((0, 0),), ((0, 1), (1, 0)), ((1, 1),)), found.sites
    assert np.allclose(found.sigma, sigma, rtol=0.06), found.sigma
    pixelwise = dark.clipping_noise(black, black == 0, sites=False)  # the model of a JPEG, on every pixel
    assert pixelwise.sites == (ALL_SITES,) * 3 and np.all(pixelwise.sigma < 0.8 * sigma), pixelwise.sigma

    y, x = np.mgrid[0:h, 0:w]
    light = 0.002 * (1.0 + np.cos(2 * np.pi * x / 320.0))  # 0 .. 1 sigma
    photo = _raw_photo(6, light, sigma)
    columns = [(140, 180), (460, 500), (300, 340), (60, 100)]  # dark, bright, between
    errors = {}
    for name, noise in (("sites", found), ("pixelwise", pixelwise)):
        fixed, fixed_black = dark.unclip(photo, noise), dark.unclip(black, noise)
        errors[name] = [float((fixed[:, lo:hi] - fixed_black[:, lo:hi]).sum(axis=2).mean()
                              - 3 * (light[:, lo:hi].mean() - 0.0005)) for lo, hi in columns]
    # the light above black, R + G + B: within 6 % of sigma with the sites (statistics: 2 %), not without
    assert max(abs(e) for e in errors["sites"]) < 0.06 * sigma, errors
    assert max(abs(e) for e in errors["pixelwise"]) > 0.15 * sigma, errors


@pytest.mark.parametrize("pattern", ["BayerBGGR", "BayerGRBG"])
def test_other_filter_layouts_are_found(pattern):
    rng = np.random.default_rng(7)
    raw16 = np.clip(rng.normal(0.0, 0.004, (256, 320)) * 65535.0 + 0.5, 0, 65535).astype(np.uint16)
    rgb = cv2.demosaicing(raw16, getattr(cv2, f"COLOR_{pattern}2RGB_EA")).astype(np.float32) / 65535.0
    found = dark.clipping_noise(rgb, rgb == 0)
    expected = {"BayerBGGR": (((1, 1),), ((0, 1), (1, 0)), ((0, 0),)),
                "BayerGRBG": (((0, 1),), ((0, 0), (1, 1)), ((1, 0),))}[pattern]
    assert found.sites == expected, found.sites


@pytest.mark.parametrize("blur", [0.0, 1.0])
def test_a_black_that_is_0_without_noise_is_not_taken_for_clipped_noise(blur):
    """A noiseless black photo: a panel at exactly 0 inside a dim room (0.002), its edge sharp or
    blurred by a pixel.  The blocks along the edge are partly 0, but not from noise: taken for
    clipped noise, their 'sigma' was the step's height, and the faint floor of every band photo
    (the panel's scatter) was wiped out.  No correction is made."""
    h, w = 480, 640
    light = np.full((h, w), 0.002, np.float32)
    light[100:380, 120:520] = 0.0
    if blur:
        light = cv2.GaussianBlur(light, (0, 0), blur)
    black = np.round(np.repeat(light[..., None], 3, axis=2) * 65535.0) / np.float32(65535.0)
    assert dark.clipping_noise(black, black == 0) is None


def test_a_photo_unclipped_with_too_small_a_sigma_is_restored_by_reclipping_with_the_right_one():
    """What the measurement's dark-clipping uncertainty computes (measure: a JPEG's sigma read too
    small): light unclipped with sigma, clipped again and unclipped with 2 sigma, is the light a
    camera of 2 sigma clipped; scale 1 and places far above the noise are left as they are."""
    from scipy.stats import norm

    sigma, true_sigma = 0.003, 0.006
    light = np.linspace(-0.5, 6.0, 200) * true_sigma  # per channel
    t = light / true_sigma
    clipped = true_sigma * (t * norm.cdf(t) + norm.pdf(t))  # the mean of the clipped pixels
    table_t = np.linspace(dark.LOWEST, dark.REACH + 1.0, 4001)
    table = table_t * norm.cdf(table_t) + norm.pdf(table_t)
    u = clipped / sigma  # unclipped with the smaller sigma, as dark.unclip would
    too_small = np.where(u < table[-1], sigma * np.interp(u, table, table_t), clipped)
    assert np.abs(too_small - light)[light < 2 * true_sigma].max() > 0.3 * sigma  # the error to undo
    restored = dark.reclipped(3 * too_small, sigma, true_sigma / sigma) / 3
    inside = light > dark.LOWEST * sigma  # what the smaller sigma could still tell apart
    np.testing.assert_allclose(restored[inside], light[inside], atol=2e-3 * sigma)
    np.testing.assert_array_equal(dark.reclipped(3 * too_small, sigma, 1.0), 3 * too_small)
    far = np.array([0.2, 0.5])
    np.testing.assert_array_equal(dark.reclipped(far, sigma, 2.0), far)


def test_a_channel_seldom_at_zero_takes_the_other_channels_sigma():
    """A JPEG's green, averaged over two sensor sites of every four, sits at 0 in a few blocks only:
    the photo is still measured, where it was left clipped as a whole before (bench hard case 1: the
    far views 25 % short); a photo without sensor sites takes every channel's sigma from its block
    means (dark.block_noise), within what the measurement carries (``SIGMA_RANGE``)."""
    import cv2

    h, w = 480, 640
    y, x = np.mgrid[0:h, 0:w]
    site_light = np.where((y % 2 == 0) & (x % 2 == 0), 0.002, np.where((y % 2 == 1) & (x % 2 == 1), 0.002,
                                                                        0.0135 + 0.004 * (x > 600)))
    site_sigma = np.where((y % 2 == 1) & (x % 2 == 1), 0.005, 0.004)  # RGGB: blue at the odd rows and columns
    rng = np.random.default_rng(6)
    sensor = np.clip(site_light + rng.normal(0.0, 1.0, (h, w)) * site_sigma, 0.0, 1.0)
    black = (cv2.demosaicing(np.round(sensor * 65535).astype(np.uint16), cv2.COLOR_BayerRGGB2RGB)
             / 65535.0).astype(np.float32)
    black[0::2, 1::2] += 1e-6  # no sensor sites left at exactly 0: the phases a JPEG hides
    zero = black == 0
    assert 0 < np.count_nonzero(zero[..., 1]) < 0.001 * zero[..., 1].size  # green: a handful of pixels at 0
    found = dark.clipping_noise(black, zero)
    assert found is not None
    low, high = dark.SIGMA_RANGE
    ratio = np.array([0.004, 0.004, 0.005]) / found.sigma
    assert np.all((ratio >= low) & (ratio <= high)), found.sigma
