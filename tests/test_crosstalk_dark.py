"""Photos clipped at zero (lenticalib.calib.crosstalk.dark): sigma measured on a black photo, the bias undone."""

import numpy as np

from lenticalib.calib.crosstalk import dark


def _photo(seed, light, sigma, shape=(480, 640)):
    """A clipped noisy photo of ``light`` (h, w) in every channel, noise sigma per channel."""
    rng = np.random.default_rng(seed)
    noisy = light[..., None] + rng.normal(0.0, 1.0, shape + (3,)) * np.asarray(sigma)[None, None, :]
    return np.maximum(noisy, 0.0).astype(np.float32)


def test_the_noise_is_measured_on_a_clipped_black_photo():
    y, x = np.mgrid[0:480, 0:640]
    light = 0.002 + 0.004 * x / 640  # a faint gradient (glare), 0.4 to 1.2 sigma of the red channel
    sigma = (0.005, 0.004, 0.006)
    black = _photo(1, light, sigma)
    found = dark.clipping_noise(black, black == 0)
    assert np.allclose(found, sigma, rtol=0.05), found


def test_a_photo_that_is_not_clipped_needs_no_correction():
    black = _photo(2, np.full((480, 640), 0.05), (0.003, 0.003, 0.003))
    assert dark.clipping_noise(black, black == 0) is None


def test_the_mean_of_faint_light_is_restored():
    # a faint fringe, 0 to 2 sigma, under noise: clipped, its mean comes out high where it is darkest
    sigma = np.array([0.005, 0.005, 0.005])
    y, x = np.mgrid[0:480, 0:640]
    light = 0.005 * (1.0 + np.cos(2 * np.pi * x / 320.0))  # 0 .. 0.010
    photo = _photo(3, light, sigma)
    fixed = dark.unclip(photo, sigma)
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
    assert np.array_equal(dark.unclip(photo, sigma), photo)
