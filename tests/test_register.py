"""Group registration and the photometric phase correction of the fit, on synthetic images with
known shifts and tone curves (fixed seeds), and the no-false-alarm property of the checks."""

import math

import numpy as np
import pytest

from lenticalib.calib import photometric, register


def _panel_image(shift=(0.0, 0.0), fringe_period=None, noise=0.0, seed=0, size=(600, 900)):
    """A blurred bright rectangle (the panel's mean image) on a dark bezel, shifted by ``shift``
    pixels, optionally with a residue of horizontal fringes along it, plus Gaussian noise."""
    import cv2

    h, w = size
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    xx -= shift[0]
    yy -= shift[1]
    x0, x1, y0, y1 = 0.15 * w, 0.85 * w, 0.15 * h, 0.85 * h
    edge = 1.5

    def ramp(t):
        return 0.5 * (1 + np.tanh(t / edge))

    img = ramp(xx - x0) * ramp(x1 - xx) * ramp(yy - y0) * ramp(y1 - yy) * (1.0 - 0.3 * ((xx - w / 2) / w) ** 2)
    if fringe_period:
        img *= 1.0 + 0.03 * np.cos(2 * math.pi * yy / fringe_period)
    img = img + 0.005
    rng = np.random.default_rng(seed)
    img = img + noise * rng.standard_normal(img.shape)
    return cv2.GaussianBlur(img.astype(np.float32), (0, 0), 0.7)


def _mask(size=(600, 900)):
    h, w = size
    m = np.zeros(size, bool)
    m[int(0.16 * h):int(0.84 * h), int(0.16 * w):int(0.84 * w)] = True  # eroded like the fit's mask
    return m


@pytest.mark.parametrize("shift", [(0.0, 0.0), (0.13, -0.21), (-0.3, 0.07), (1.6, -2.4)])
def test_measure_shift_recovers_a_known_subpixel_shift(shift):
    mask = _mask()
    band = register.edge_band(mask)
    ref = register.silhouette(_panel_image(noise=0.01, seed=1), mask)
    moved = register.silhouette(_panel_image(shift, noise=0.01, seed=2), mask)
    result = register.measure_shift(ref, moved, band)
    assert result.measured
    tolerance = 0.01 + 0.01 * math.hypot(*shift)
    assert abs(result.dx - shift[0]) < tolerance and abs(result.dy - shift[1]) < tolerance
    assert 0 < result.sigma < 0.02


def test_fringe_residue_along_the_edge_does_not_bias_the_shift():
    """Fringe residue in one group's mean image runs along the panel edge; divided out with the
    group's complex fringe, the measured shift stays unbiased."""
    mask = _mask()
    band = register.edge_band(mask)
    h, w = mask.shape
    yy = np.mgrid[0:h, 0:w][0].astype(np.float64)
    z = np.exp(2j * math.pi * (yy - 0.2) / 40.0)  # the group's fringe phase (horizontal fringes)
    ref = register.silhouette(_panel_image(noise=0.003, seed=3), mask)
    moved_dc = _panel_image((0.0, 0.2), fringe_period=40.0, noise=0.003, seed=4)
    plain = register.measure_shift(ref, register.silhouette(moved_dc, mask), band)
    cleaned = register.measure_shift(ref, register.silhouette(moved_dc, mask, z), band)
    assert abs(cleaned.dy - 0.2) < 0.02
    assert abs(cleaned.dy - 0.2) <= abs(plain.dy - 0.2) + 1e-3


def test_noise_alone_is_never_reported_as_camera_motion():
    """Two photos of nothing but noise: the shift cannot be measured, and says so."""
    rng = np.random.default_rng(5)
    mask = _mask()
    band = register.edge_band(mask)
    a = register.silhouette(rng.random(mask.shape).astype(np.float32), mask)
    b = register.silhouette(rng.random(mask.shape).astype(np.float32), mask)
    result = register.measure_shift(a, b, band)
    assert not result.measured
    assert (result.dx, result.dy) == (0.0, 0.0)
    assert result.note


def test_shift_image_undoes_a_shift():
    img = _panel_image((0.4, -0.3))
    back = register.shift_image(img, 0.4, -0.3)
    ref = _panel_image()
    inner = _mask()
    assert np.max(np.abs(back - ref)[inner]) < 2e-3


def test_tone_curve_phase_error_is_measured_and_cancelled():
    """A 3-step fringe through a strong S-shaped tone curve: the phase error of the many-fringe
    group, tabulated by phase, cancels the error of a single-fringe group with the same curve."""
    from lenticalib.calib.phase import coordinate_from_single_period, demodulate, phase_cycles

    h, w = 300, 1200
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    x = xx * 9.6 + 0.3 * yy  # panel subpixels seen by each pixel, slightly rolled

    def tone(linear):  # decode(S(encode(L))): what the fit sees through a phone's S-curve
        from lenticalib.calib.patterns import srgb_decode, srgb_encode

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
