"""Per-photo registration on the patterns' frame and the photometric phase correction of the fit, on synthetic images with
known shifts and tone curves (fixed seeds), and the no-false-alarm property of the checks."""

import math

import numpy as np
import pytest

from lenticalib.calib.routing import photometric
from lenticalib.calib.patterns import register


SIZE = (600, 900)
FRAME = 24  # pixels: the registration frame as seen


def _panel_photo(shift=(0.0, 0.0), step=None, gain=1.0, noise=0.0, seed=0, size=SIZE, room=0.0):
    """A photo of a framed pattern: a blurred bright rectangle on a dark bezel, its outer FRAME
    pixels evenly lit, inside them horizontal fringes at phase step ``step`` of 3 (None: their
    mean), the whole shifted by ``shift`` pixels, times ``gain``, plus Gaussian noise.  ``room``:
    the level of a lit room beyond a 6-pixel bezel."""
    import cv2

    h, w = size
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    xx -= shift[0]
    yy -= shift[1]
    x0, x1, y0, y1 = 0.15 * w, 0.85 * w, 0.15 * h, 0.85 * h

    def ramp(t):
        return 0.5 * (1 + np.tanh(t / 1.5))

    outer = ramp(xx - x0) * ramp(x1 - xx) * ramp(yy - y0) * ramp(y1 - yy)
    inner = ramp(xx - x0 - FRAME) * ramp(x1 - FRAME - xx) * ramp(yy - y0 - FRAME) * ramp(y1 - FRAME - yy)
    fringe = 0.5 if step is None else 0.5 + 0.45 * np.cos(2 * math.pi * (yy - y0) / 61.0 + 2 * math.pi * step / 3)
    img = (outer - inner) * 0.9 + inner * fringe
    bezel = 6
    img += room * (1 - ramp(xx - x0 + bezel) * ramp(x1 + bezel - xx) * ramp(yy - y0 + bezel) * ramp(y1 + bezel - yy))
    img = gain * img * (1.0 - 0.3 * ((xx - w / 2) / w) ** 2) + 0.005
    rng = np.random.default_rng(seed)
    img = img + noise * rng.standard_normal(img.shape)
    return cv2.GaussianBlur(img.astype(np.float32), (0, 0), 0.7)


def _reference(noise=0.01, room=0.0):
    from lenticalib.calib.patterns.phase import demodulate

    photos = [_panel_photo(step=k, noise=noise, seed=10 + k, room=room) for k in range(3)]
    z, mean = demodulate(photos, [2 * math.pi * k / 3 for k in range(3)])
    return register.Reference.from_mean_image(mean, z, FRAME / (0.7 * SIZE[0]))


@pytest.mark.parametrize("shift", [(0.0, 0.0), (0.13, -0.21), (-0.3, 0.07), (1.6, -2.4)])
@pytest.mark.parametrize("step", [0, 1, 2])
def test_each_photo_shift_is_recovered_whatever_its_fringe_and_exposure(shift, step):
    """The fringe next to the frame differs from photo to photo (here it is brightest or darkest
    at the frame's inner boundary, parallel to it); the measured shift must not follow it."""
    reference = _reference()
    result = reference.measure(_panel_photo(shift, step=step, gain=1.04, noise=0.01, seed=step))
    assert result.measured
    assert result.sigma < 0.02
    assert abs(result.dx - shift[0]) < max(0.01, 4 * result.sigma)
    assert abs(result.dy - shift[1]) < max(0.01, 4 * result.sigma)


def test_a_room_as_bright_as_the_panel_does_not_hide_the_panel():
    """The band is placed by the fringes, not by brightness: a lit room behind a thin bezel."""
    reference = _reference(room=0.9)
    result = reference.measure(_panel_photo((0.21, -0.12), step=2, noise=0.01, seed=5, room=0.9))
    assert result.measured
    assert abs(result.dx - 0.21) < 0.01 and abs(result.dy + 0.12) < 0.01


def test_noise_alone_is_never_reported_as_camera_motion():
    rng = np.random.default_rng(7)
    noise = rng.random(SIZE).astype(np.float32)
    reference = register.Reference.from_mean_image(noise, noise * np.exp(2j * np.pi * rng.random(SIZE)), 0.05)
    if reference is not None:
        result = reference.measure(rng.random(SIZE).astype(np.float32))
        assert not result.measured
        assert result.dx == 0.0 and result.dy == 0.0


def test_shift_image_undoes_a_shift_without_quantising_it():
    img = _panel_photo((0.4, -0.3), step=1)
    back = register.shift_image(img, 0.4, -0.3)
    inner = np.zeros(SIZE, bool)
    inner[100:500, 150:750] = True
    assert np.max(np.abs(back - _panel_photo(step=1))[inner]) < 3e-3
    # a hundredth of a pixel is applied as such (OpenCV's warpAffine rounds positions to 1/32 pixel)
    reference = _reference(noise=0.0)
    tiny = register.shift_image(_panel_photo(step=None), 0.0, 0.01)
    assert abs(reference.measure(tiny).dy - (-0.01)) < 0.002


def test_tone_curve_phase_error_is_measured_and_cancelled():
    """A 3-step fringe through a strong S-shaped tone curve: the phase error of the many-fringe
    group, tabulated by phase, cancels the error of a single-fringe group with the same curve."""
    from lenticalib.calib.patterns.phase import coordinate_from_single_period, demodulate, phase_cycles

    h, w = 300, 1200
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    x = xx * 9.6 + 0.3 * yy  # panel subpixels seen by each pixel, slightly rolled

    def tone(linear):  # decode(S(encode(L))): what the fit sees through a phone's S-curve
        from lenticalib.core.colour import srgb_decode, srgb_encode

        v = srgb_encode(linear)
        return srgb_decode(v + 0.9 * (3 * v ** 2 - 2 * v ** 3 - v))

    def group(period):
        thetas = [2 * math.pi * k / 3 for k in range(3)]
        images = [tone(0.5 + 0.45 * np.cos(2 * math.pi * x / period + t)).astype(np.float32) for t in thetas]
        z, _ = demodulate(images, thetas)
        return phase_cycles(z)

    weight = np.ones((h, w))
    many = group(960.0)
    table = photometric.phase_error_table(many, weight, "x")
    assert table is not None
    truth_many = np.mod(x / 960.0, 1.0)
    err_before = np.abs((many - truth_many + 0.5) % 1 - 0.5).max()
    err_after = np.abs((photometric.correct_phase(many, table) - truth_many + 0.5) % 1 - 0.5).max()
    assert err_before > 0.01 and err_after < err_before / 4
    single = group(14400.0)
    coord_before = coordinate_from_single_period(single, 14400.0, 11520.0)
    coord_after = coordinate_from_single_period(photometric.correct_phase(single, table), 14400.0, 11520.0)
    assert np.abs(coord_after - x).max() < np.abs(coord_before - x).max() / 3
