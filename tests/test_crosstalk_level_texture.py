"""The level photos' rows as the camera resolves them (lenticalib.calib.crosstalk.level_texture) and the
light its demosaicing takes off them, in the tone curve's fit: synthetic photos of a phone-like
camera (an S-curve) whose level rows are short of their share by the loss the module expects."""

from __future__ import annotations

import numpy as np
import pytest

from lenticalib.calib.crosstalk import level_texture, tiles, tone
from lenticalib.calib.crosstalk.tone_models import log_slope

from .crosstalk_support import phone_codes, tone_photo_light


def _true_table() -> np.ndarray:
    """float (256,): the light of each code of the S-curve camera (its mean over the code's range)."""
    light = np.linspace(0.0, 1.0, 200001)
    code = np.clip(np.rint(phone_codes(light)).astype(int), 0, 255)
    sums, counts = np.bincount(code, light, 256), np.bincount(code, minlength=256)
    seen = counts > 0
    return np.interp(np.arange(256), np.flatnonzero(seen), sums[seen] / counts[seen])


def _photos(losses: dict[int, float], pitch: float = 0.6, seed: int = 5, size=(600, 400)) -> dict[str, np.ndarray]:
    """uint8 RGB photos of a virtual panel (:func:`crosstalk_support.tone_photo_light`: the levels'
    rows ``pitch`` photo pixels apart, ``losses[K]`` taken off their light) through the S-curve camera."""
    w, h = size
    light = tone_photo_light(losses, pitch, size)
    rng = np.random.default_rng(seed)
    return {name: np.clip(np.rint(phone_codes(value)[:, :, None] + rng.normal(0, 0.5, (h, w, 3))), 0, 255).astype(np.uint8)
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


def test_the_share_after_a_loss_is_one_less_the_loss_times_the_modulation_at_least_a_half():
    shares = level_texture.shares_after_loss({"level-1in8": 0.4, "level-1in2": 0.0, "odd": 9.0})
    assert shares["level-1in8"] == pytest.approx(1 - level_texture.LOSS_BOUND * 0.4)
    assert shares["level-1in2"] == 1.0 and shares["odd"] == 0.5
    assert level_texture.shares_after_loss({"level-1in8": 0.4}, 0.0) == {"level-1in8": 1.0}


def test_a_bent_curve_carries_the_light_a_camera_s_demosaicing_took_off_the_level_rows(monkeypatch):
    """Level rows short by half the loss bound times their modulation (the bench's edge-aware
    demosaicing lost about that much): the bent curve, fitted with the levels as exact, is off the
    camera's S-curve by several times what it is without the loss, and inside 3 of its sigma,
    which holds the loss's range (``texture_sigma`` > 0, recorded in ``to_dict``; none without
    the modulations)."""
    modulations = level_texture.level_modulations(_photos({}))
    losses = {k: 0.5 * level_texture.LOSS_BOUND * modulations[f"level-1in{k}"] for k in tone.LEVEL_PERIODS}
    truth = _true_table()
    lost = tone.fit_tone_curve(_photos(losses), tiles.tile_size(600))
    kept = tone.fit_tone_curve(_photos({}), tiles.tile_size(600))
    assert lost.model == kept.model == "curve"
    codes = np.arange(lost.code_range[0] + 2, lost.code_range[1] + 1)
    off = abs(log_slope(np.asarray(lost.table, float), truth, codes))
    off_kept = abs(log_slope(np.asarray(kept.table, float), truth, codes))
    assert off > 3 * off_kept
    assert off <= 3 * lost.sigma
    assert lost.texture_sigma > 0
    monkeypatch.setattr(tone, "level_modulations", lambda images: {})
    blind = tone.fit_tone_curve(_photos(losses), tiles.tile_size(600))
    assert blind.texture_sigma == 0 and blind.to_dict().get("level_texture") is None
    record = lost.to_dict()["level_texture"]
    assert record["power_sigma"] == pytest.approx(lost.texture_sigma, abs=1e-4)
    assert record["levels"][0] == "level-1in8"
    assert record["modulations"][0] == pytest.approx(level_texture.level_modulations(_photos(losses))["level-1in8"], abs=1e-4)
    assert record["shares_at_loss_bound"][0] == pytest.approx(1 - level_texture.LOSS_BOUND * record["modulations"][0],
                                                              abs=2e-4)
