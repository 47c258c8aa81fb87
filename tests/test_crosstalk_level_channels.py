"""The level photos' channels in the tone curve's fit (lenticalib.calib.crosstalk.level_channels):
synthetic photos of a phone-like camera (an S-curve) whose demosaicing took light off one channel
of the level rows it resolves, as OpenCV's edge-aware one takes it off the green."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lenticalib.calib.crosstalk import level_channels, tiles, tone

from .crosstalk_support import phone_codes, tone_photo_light

GREEN_LOSS = {8: 0.25, 4: 0.04, 2: 0.02}  # of each level's light in green (bench hard case 7: 0.23, 0.035, 0.02)


def _photos(green_loss: dict[int, float], seed: int = 5, size=(600, 400)) -> dict[str, np.ndarray]:
    """uint8 RGB photos of the tests' virtual panel (rows 0.6 photo pixels apart) through the S-curve
    camera, each level's green light above black short by ``green_loss[K]``; noise of half a code."""
    w, h = size
    light = tone_photo_light({}, 0.6, size)
    rng = np.random.default_rng(seed)
    photos = {}
    for name, value in light.items():
        rgb = np.repeat(value[:, :, None], 3, axis=2)
        if name in tone.LEVELS:
            loss = green_loss.get(tone.LEVEL_PERIODS[tone.LEVELS.index(name)], 0.0)
            rgb[:, :, 1] = light["black"] + (value - light["black"]) * (1.0 - loss)
        photos[name] = np.clip(np.rint(phone_codes(rgb) + rng.normal(0, 0.5, (h, w, 3))), 0, 255).astype(np.uint8)
    return photos


def _apart(curve, other) -> float:
    """The largest relative difference of the light of two fitted curves (each scaled to its light at
    the white code) over the codes the measurement reads, from 2 above black to white."""
    first, last = curve.code_range[0] + 2, curve.code_range[1]
    a = np.asarray(curve.table[first:last + 1], float) / curve.table[last]
    b = np.asarray(other.table[first:last + 1], float) / other.table[last]
    return float(np.max(np.abs(np.log(a / b))))


@pytest.mark.parametrize("shares, used", [((1.07, 0.79, 1.06), (0, 2)), ((1.0, 0.98, 1.01), (0, 1, 2)),
                                          ((0.96, 1.0, 1.04), (0, 1, 2)), ((1.0, 1.0, 0.93), (0, 1)),
                                          ((1.0, math.nan, 1.0), (0, 2))])
def test_a_channel_far_from_the_middle_one_is_left_out(shares, used):
    assert level_channels.agreeing_channels(shares) == used


def test_a_level_whose_green_lost_light_rests_on_red_and_blue(monkeypatch):
    """A quarter of the 1-in-8 rows' green light lost: the level rests on red and blue, and the curve
    comes out within 8 % (light of every code read) of the one fitted to photos without the loss,
    where the three channels pooled put the toe tens of per cent off it; the record names the
    channels and the shares read.  Without the loss every level keeps all three."""
    kept = tone.fit_tone_curve(_photos({}), tiles.tile_size(600))
    assert all(v["channels"] == "RGB" for v in kept.level_channels.values())
    lost = tone.fit_tone_curve(_photos(GREEN_LOSS), tiles.tile_size(600))
    assert lost.model == kept.model == "curve"
    record = lost.to_dict()["level_channels"]
    assert record["level-1in8"]["channels"] == "RB"
    assert record["level-1in8"]["shares"][1] < record["level-1in8"]["shares"][0] - level_channels.OUTLIER
    assert all(record[name]["channels"] == "RGB" for name in ("level-1in4", "level-1in2"))
    monkeypatch.setattr(level_channels, "agreeing_channels", lambda shares: (0, 1, 2))
    pooled = tone.fit_tone_curve(_photos(GREEN_LOSS), tiles.tile_size(600))
    assert _apart(lost, kept) < 0.08
    assert _apart(pooled, kept) > 3 * _apart(lost, kept)
