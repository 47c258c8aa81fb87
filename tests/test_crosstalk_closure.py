"""The light's closure (``calib/crosstalk/closure.py``): the band photos' light adds up to white's,
and the toe that would close it; each band photo's exposure, read on the frame.

Synthetic ground truth with fixed seeds: a view cone that integrates to 1 over one period, swept
across a panel of working pixels, its dark light read short as a camera whose tone curve's toe
is off would read it."""

from __future__ import annotations

import types

import numpy as np
import pytest

from lenticalib.calib.crosstalk import closure, cone, exposure
from lenticalib.calib.crosstalk.ratios import TOE_END, toe_lifted
from lenticalib.core.colour import srgb_decode_lut, srgb_encode

VIEWS = 32
BANDS = 10
SHIFTS = np.arange(BANDS) * VIEWS / BANDS


def _cone(t: np.ndarray) -> np.ndarray:
    """A view cone (share of white's light from a one-view band ``t`` views away) whose integral
    over one period is 1: a core a view wide, shoulders and a floor of far light."""
    t = np.mod(np.asarray(t, np.float64) + VIEWS / 2, VIEWS) - VIEWS / 2
    shape = np.exp(-0.5 * (t / 0.55) ** 2) + 0.25 * np.exp(-0.5 * (t / 1.6) ** 2) + 0.004
    grid = np.linspace(-VIEWS / 2, VIEWS / 2, 64001)[:-1]
    total = np.mean(np.exp(-0.5 * (grid / 0.55) ** 2) + 0.25 * np.exp(-0.5 * (grid / 1.6) ** 2) + 0.004) * VIEWS
    return shape / total


def _samples(toe: float, seed: int = 3):
    """(ratios (n, K) as a camera with a toe short by ``toe`` reads them, rows, cols): the light above
    black that :func:`toe_lifted` by ``toe`` takes to the truth (the root of
    ``r (1 + toe (1 - r / TOE_END)) = true`` below TOE_END)."""
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0:40, 0:400]
    rows, cols = rows.ravel(), cols.ravel()
    delta = VIEWS * cols / 200.0 + 0.3 * rows / 40.0  # two sweep periods across, a slight slant
    true = _cone(delta[:, None] + SHIFTS[None, :])
    if toe:
        a, b = toe / TOE_END, 1.0 + toe
        read = np.where(true < TOE_END, (b - np.sqrt(np.maximum(b * b - 4 * a * true, 0.0))) / (2 * a), true)
    else:
        read = true
    return read + rng.normal(0.0, 2e-5, read.shape), rows, cols


def _bands():
    return [types.SimpleNamespace(name=f"band-{k:02d}") for k in range(BANDS)]


def _close(toe: float, exposures=None):
    ratios, rows, cols = _samples(toe)
    fit = cone.fit_cone(ratios, rows, cols, SHIFTS, VIEWS, (40, 400))

    def with_toe(t):
        return toe_lifted(ratios, 1.0, t)

    return closure.close_toe(with_toe, fit, rows, cols, SHIFTS, exposures, _bands()), ratios, rows, cols, fit


@pytest.mark.parametrize("toe", [0.0, 0.15, 0.4])
def test_the_toe_that_closes_the_light_is_the_one_the_camera_lost(toe):
    """The cone read with the dark light short by ``toe`` integrates to less than 1; the toe found
    puts it back (within 0.02) and lifts the far views' light back to the truth (within 2 %)."""
    found, ratios, rows, cols, fit = _close(toe)
    assert found.pinned and not found.exposures_read
    assert found.integral == pytest.approx(1.0 - toe * found.slope, abs=0.01)
    assert toe == 0 or found.integral < 0.99
    assert found.toe == pytest.approx(toe, abs=0.02)
    # taken as locked: E known to UNKNOWN_EXPOSURE_SIGMA, the toe's sigma that over the slope
    assert found.toe_sigma == pytest.approx(closure.UNKNOWN_EXPOSURE_SIGMA / found.slope, rel=0.2)
    lifted = toe_lifted(ratios, 1.0, found.toe)
    grid, profile, _ = cone.profile_for(fit, lifted, rows, cols, SHIFTS)
    far = np.abs(grid) > 6
    assert np.mean(profile[far]) == pytest.approx(np.mean(_cone(grid[far])), rel=0.02)
    assert np.mean(profile) * VIEWS == pytest.approx(1.0, abs=0.003)


def test_a_camera_that_read_the_light_right_closes_it_without_a_toe():
    found = _close(0.0)[0]
    assert abs(found.integral - 1.0) < 0.003 and abs(found.toe) < 0.02


def test_the_frame_s_exposures_set_the_integral_the_light_must_close_to():
    """Band photos taken at 3 % more exposure than white: their light integrates to 1.03, and with
    the exposures read on the frame the closure asks for that, keeping the toe at 0; told nothing,
    it would take the 3 % for a toe."""
    relative = {f"band-{k:02d}": 1.03 for k in range(BANDS)} | {"black": 1.03, "white": 1.0}
    read = exposure.Exposures(relative, {name: 0.002 for name in relative}, 0.01, 5000, 1)
    ratios, rows, cols = _samples(0.0)
    ratios = ratios * 1.03
    fit = cone.fit_cone(ratios, rows, cols, SHIFTS, VIEWS, (40, 400))

    def with_toe(t):
        return toe_lifted(ratios, 1.0, t)

    found = closure.close_toe(with_toe, fit, rows, cols, SHIFTS, read, _bands())
    assert found.exposures_read and abs(found.toe) < 0.02 and abs(found.integral - 1.0) < 0.003
    assert found.toe_sigma < 0.3 * closure.UNKNOWN_EXPOSURE_SIGMA / found.slope
    blind = closure.close_toe(with_toe, fit, rows, cols, SHIFTS, None, _bands())
    assert blind.toe < -0.1 and blind.integral > 1.02


def test_too_little_dark_light_pins_no_toe():
    """A cone with no light outside its core (nothing below TOE_END of white's but noise): no toe."""
    rows, cols = np.mgrid[0:40, 0:400]
    rows, cols = rows.ravel(), cols.ravel()
    t = np.mod(VIEWS * cols / 200.0 + SHIFTS[:, None] + VIEWS / 2, VIEWS).T - VIEWS / 2
    ratios = np.where(np.abs(t) < 0.5, 1.0, 0.0)
    fit = cone.fit_cone(ratios, rows, cols, SHIFTS, VIEWS, (40, 400))
    found = closure.close_toe(lambda toe: toe_lifted(ratios, 1.0, toe), fit, rows, cols, SHIFTS, None, _bands())
    assert not found.pinned and found.toe == 0.0 and found.slope < closure.MIN_SLOPE


def test_the_lift_moves_only_the_light_above_black_below_its_end():
    """``toe_lifted``: light above black at or beyond ``TOE_END`` of the reference unchanged; just
    above black lifted by the whole lift, half-way by half of it."""
    above = np.array([1e-6, TOE_END / 2, TOE_END, 0.8])
    out = toe_lifted(above, 1.0, 0.2)
    assert out[2:] == pytest.approx(above[2:])
    assert out[1] == pytest.approx(above[1] * 1.1)
    assert out[0] == pytest.approx(above[0] * 1.2, rel=1e-4)
    assert toe_lifted(above, 2.0, 0.2)[2] == pytest.approx(above[2] * 1.1)  # x = above / reference
    assert toe_lifted(above, 1.0, 0.0) is above


def _frame_photos(exposures: dict[str, float], seed: int = 11) -> dict[str, np.ndarray]:
    """uint8 RGB photos of a panel with the registration frame (light 0.25, a bezel at 0.03 around
    it) at the given exposures: a black inside, a white one, band sweeps lighting the frame's
    inner side each in its own places (through a glare halo), a blur of a pixel and noise."""
    import cv2

    w, h = 700, 480
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    panel = (x >= 80) & (x < 620) & (y >= 60) & (y < 420)
    inside = (x >= 92) & (x < 608) & (y >= 72) & (y < 408)
    rng = np.random.default_rng(seed)
    photos = {}
    for name, e in exposures.items():
        if name == "black":
            inner = np.full_like(x, 0.004)
        elif name == "white":
            inner = np.full_like(x, 0.6)
        else:
            k = int(name.rsplit("-", 1)[1])
            inner = 0.004 + 0.6 * np.exp(-0.5 * ((np.mod(x / 16.0 + 3.2 * k, 32.0) - 16) / 0.6) ** 2)
        light = np.where(panel, 0.25, 0.03 * (1 + 0.2 * x / w))
        light = np.where(inside, inner, light)
        light = 0.97 * light + 0.03 * cv2.GaussianBlur(light, (0, 0), 50.0)
        light = cv2.GaussianBlur((e * light).astype(np.float32), (0, 0), 1.0).astype(np.float64)
        code = 255 * srgb_encode(np.clip(light, 0, 1))[:, :, None] + rng.normal(0, 0.5, (h, w, 3))
        photos[name] = np.clip(np.rint(code), 0, 255).astype(np.uint8)
    return photos


def test_each_band_photo_s_exposure_is_read_with_black_and_white_alone():
    """``exposure.measure_each``: every band photo's exposure over white's within 0.6 % of the
    truth, black's too, white exactly 1; where one band photo has no readable frame, None."""
    rng = np.random.default_rng(2)
    truth = {"black": 1.02, "white": 1.0} | {f"band-{k:02d}": 1 + rng.uniform(-0.04, 0.04) for k in range(4)}
    photos = _frame_photos(truth)
    found = exposure.measure_each(photos, srgb_decode_lut().astype(np.float64), [f"band-{k:02d}" for k in range(4)])
    assert found is not None and found.relative["white"] == 1.0
    for name, value in truth.items():
        assert found.relative[name] == pytest.approx(value, abs=0.006), name
    photos["band-02"] = np.zeros_like(photos["band-02"])  # a photo with nothing on it
    assert exposure.measure_each(photos, srgb_decode_lut().astype(np.float64),
                                 [f"band-{k:02d}" for k in range(4)]) is None


def test_only_the_toe_the_closure_pins_beyond_its_sigma_is_carried():
    """``Closure.pinned_toe``: the closing toe less its own 1-sigma, 0 where that is larger or the
    closure pins nothing."""
    base = dict(integral=1.03, integral_sigma=0.005, expected_sigma=0.02, slope=0.033)
    assert closure.Closure(**base, toe=-0.9, toe_sigma=0.63, pinned=True).pinned_toe() == pytest.approx(-0.27)
    assert closure.Closure(**base, toe=0.14, toe_sigma=0.04, pinned=True).pinned_toe() == pytest.approx(0.10)
    assert closure.Closure(**base, toe=0.02, toe_sigma=0.03, pinned=True).pinned_toe() == 0.0
    assert closure.Closure(**base, toe=0.5, toe_sigma=0.1, pinned=False).pinned_toe() == 0.0


def test_16_bit_photos_exposures_are_read_through_their_own_code_range():
    """16-bit sRGB-encoded photos (a raw converter's): the same exposures as the 8-bit ones, read
    through the 65536-code decoding with the readable range scaled to 16 bits."""
    from lenticalib.core.colour import srgb_decode

    rng = np.random.default_rng(4)
    truth = {"black": 0.98, "white": 1.0} | {f"band-{k:02d}": 1 + rng.uniform(-0.04, 0.04) for k in range(3)}
    photos16 = {k: v.astype(np.uint16) * 257 for k, v in _frame_photos(truth).items()}
    found = exposure.measure_each(photos16, srgb_decode(np.arange(65536) / 65535.0),
                                  [f"band-{k:02d}" for k in range(3)],
                                  (exposure.CODE_RANGE[0] * 257, exposure.CODE_RANGE[1] * 257))
    assert found is not None
    for name, value in truth.items():
        assert found.relative[name] == pytest.approx(value, abs=0.006), name


