"""The level photos' rows as the camera resolves them (lenticalib.calib.crosstalk.level_texture) and the
light its demosaicing takes off them, in the tone curve's fit: synthetic photos of a phone-like
camera (an S-curve) whose level rows are short of their share by the loss the module expects."""

from __future__ import annotations

import numpy as np
import pytest

from lenticalib.calib.crosstalk import level_texture, tiles, tone
from lenticalib.calib.crosstalk.tone_models import log_slope
from lenticalib.core.colour import srgb_encode

from .crosstalk_support import tone_photo_light

CONTRAST = 0.5  # the camera's S-curve on the sRGB encoding: v + CONTRAST (3 v^2 - 2 v^3 - v)


def _encode(light: np.ndarray) -> np.ndarray:
    v = srgb_encode(np.clip(light, 0.0, 1.0))
    return 255.0 * (v + CONTRAST * (3 * v ** 2 - 2 * v ** 3 - v))


def _true_table() -> np.ndarray:
    """float (256,): the light of each code of the S-curve camera (its mean over the code's range)."""
    light = np.linspace(0.0, 1.0, 200001)
    code = np.clip(np.rint(_encode(light)).astype(int), 0, 255)
    sums, counts = np.bincount(code, light, 256), np.bincount(code, minlength=256)
    seen = counts > 0
    return np.interp(np.arange(256), np.flatnonzero(seen), sums[seen] / counts[seen])


def _photos(losses: dict[int, float], pitch: float = 0.6, seed: int = 5, size=(600, 400)) -> dict[str, np.ndarray]:
    """uint8 RGB photos of a virtual panel (:func:`crosstalk_support.tone_photo_light`: the levels'
    rows ``pitch`` photo pixels apart, ``losses[K]`` taken off their light) through the S-curve camera."""
    w, h = size
    light = tone_photo_light(losses, pitch, size)
    rng = np.random.default_rng(seed)
    return {name: np.clip(np.rint(_encode(value)[:, :, None] + rng.normal(0, 0.5, (h, w, 3))), 0, 255).astype(np.uint8)
            for name, value in light.items()}


def test_resolved_rows_show_a_modulation_unresolved_ones_none():
    """Rows 0.6 photo pixels apart: 1-in-8 rows (4.8 pixels) show most, 1-in-2 rows (1.2 pixels)
    least; rows 1/64 of a pixel apart (whole periods in every photo row) are uniform light to the
    camera: their modulation is the noise's, under 0.02."""
    resolved = level_texture.level_modulations(_photos({}))
    assert resolved["level-1in8"] > resolved["level-1in4"] > resolved["level-1in2"]
    assert resolved["level-1in8"] > 0.3
    unresolved = level_texture.level_modulations(_photos({}, pitch=1 / 64))
    assert max(unresolved.values()) < 0.02
    assert level_texture.level_modulations({"white": _photos({})["white"]}) == {}


def test_the_expected_share_is_one_less_the_loss_times_the_modulation_at_least_a_half():
    shares = level_texture.expected_shares({"level-1in8": 0.4, "level-1in2": 0.0, "odd": 9.0})
    assert shares["level-1in8"] == pytest.approx(1 - level_texture.TEXTURE_LOSS * 0.4)
    assert shares["level-1in2"] == 1.0 and shares["odd"] == 0.5
    assert level_texture.expected_shares({"level-1in8": 0.4}, 0.0) == {"level-1in8": 1.0}


def test_a_bent_curve_fitted_with_the_levels_expected_loss_follows_the_camera_closer(monkeypatch):
    """Level rows short by the loss the module expects from their modulation: the bent curve
    fitted with it follows the camera's S-curve over the codes the measurement reads at least three
    times closer than the one that takes the levels as exact, within 3 of its sigma, which holds
    the loss's range (``texture_sigma`` > 0, recorded in ``to_dict``)."""
    modulations = level_texture.level_modulations(_photos({}))
    losses = {k: level_texture.TEXTURE_LOSS * modulations[f"level-1in{k}"] for k in tone.LEVEL_PERIODS}
    photos = _photos(losses)
    truth = _true_table()
    corrected = tone.fit_tone_curve(photos, tiles.tile_size(600))
    monkeypatch.setattr(tone, "level_modulations", lambda images: {})
    exact = tone.fit_tone_curve(photos, tiles.tile_size(600))
    assert corrected.model == exact.model == "curve"
    codes = np.arange(corrected.code_range[0] + 2, corrected.code_range[1] + 1)
    off = abs(log_slope(np.asarray(corrected.table, float), truth, codes))
    off_exact = abs(log_slope(np.asarray(exact.table, float), truth, codes))
    assert off_exact > 3 * off
    assert off <= 3 * corrected.sigma
    assert corrected.texture_sigma > 0 and exact.texture_sigma == 0
    record = corrected.to_dict()["level_texture"]
    assert record["power_sigma"] == pytest.approx(corrected.texture_sigma, abs=1e-4)
    assert record["levels"][0] == "level-1in8"
    assert record["modulations"][0] == pytest.approx(level_texture.level_modulations(photos)["level-1in8"], abs=1e-4)
    assert record["expected_shares"][0] == pytest.approx(1 - level_texture.TEXTURE_LOSS * record["modulations"][0], abs=2e-4)
