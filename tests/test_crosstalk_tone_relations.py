"""The tone curve's relations with the black photo's clipping taken off (lenticalib.calib.crosstalk.tone_models.relations),
on photos of a Bayer camera whose noise (sigma 0.03 of full scale, white at 0.55, black at 0.008) is
clipped at 0 before demosaicing, read through its true curve: the relations come out short by the
light the clipping added to black, the halves' by all of it, each level's by ``1 - 1/K`` of it, and
hold with it taken off."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.stats import norm

from lenticalib.calib.crosstalk import tiles, tone_models
from lenticalib.calib.crosstalk.tone_models import PHOTOS

from .crosstalk_support import phone_codes, rows_lit

SIGMA, BLACK, SIZE = 0.03, 0.008, (600, 400)


def _light() -> dict[str, np.ndarray]:
    """Linear light (h, w) of the photos: white with vignetting, black, halves lit 15-85 % everywhere
    (a band edge every 60 pixels, blurred), the levels' rows 0.25 photo pixels apart through a lens
    blur of 1 pixel (every place of the panel lit: no pixel of theirs at black)."""
    w, h = SIZE
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    r2 = ((x - w / 2) ** 2 + (y - h / 2) ** 2) / (w * w / 4 + h * h / 4)
    white, black = 0.55 * (1 - 0.35 * r2), np.full((h, w), BLACK)
    share = 0.5 + 0.35 * np.sin(2 * np.pi * (x + 0.3 * y) / 60.0)
    light = {"white": white, "black": black, "half-0": black + share * (white - black),
             "half-1": black + (1 - share) * (white - black)}
    for name, k in zip(tone_models.LEVELS, tone_models.LEVEL_PERIODS):
        rows = cv2.GaussianBlur(np.repeat(rows_lit(h, k, 0.25)[:, None], 8, axis=1), (0, 0), 1.0)[:, :1]
        light[name] = black + (white - black) * rows
    return light


def _photos(seed: int = 7) -> dict[str, np.ndarray]:
    """uint8 RGB photos (:func:`_light`) through the S-curve camera, its sensor's noise clipped at 0
    and demosaiced (bilinear)."""
    w, h = SIZE
    rng = np.random.default_rng(seed)
    photos = {}
    for name, value in _light().items():
        sensor = np.clip(value + rng.normal(0.0, SIGMA, (h, w)), 0.0, 1.0)
        rgb = cv2.demosaicing(np.round(sensor * 65535).astype(np.uint16), cv2.COLOR_BayerRGGB2RGB) / 65535.0
        photos[name] = np.clip(np.rint(phone_codes(rgb)), 0, 255).astype(np.uint8)
    return photos


def _true_table() -> np.ndarray:
    """float (256,): the camera's light of each code (the S-curve inverted)."""
    light = np.linspace(0.0, 1.0, 200001)
    return np.interp(np.arange(256), phone_codes(light), light)


def _histograms(photos) -> dict:
    """Each photo's code histograms over all its tiles of 16 x 16 pixels."""
    w, h = SIZE
    every = np.arange((h // 16) * (w // 16))
    return {k: tiles.tile_histograms(photos[k], 16, every) for k in PHOTOS + tone_models.LEVELS}


def _mean_residuals(photos, table, bias) -> list[float]:
    """Each relation's mean residual over white's light above black (tiles of 16 pixels, the half
    relation where both halves are 5-95 % lit)."""
    hist = _histograms(photos)
    light = {k: hist[k] @ table for k in ("black", "white", "half-0")}
    share = (light["half-0"] - light["black"]) / (light["white"] - light["black"])
    mixed = (share > 0.05) & (share < 0.95)  # all of them: no place of the halves is dark
    out = []
    for relation, lit, counts in tone_models.relations(hist, mixed, bias=bias):
        out.append(float(np.sum(counts * (relation @ table)) / np.sum(counts * (lit @ table))))
    return out


def test_the_clipping_s_light_is_read_on_black_and_closes_the_relations():
    """The clipping added 0.0084 to black (0.4 sigma at 0.27 sigma of light): read on the black photo
    within the tone curve's ``BIAS_RANGE`` (0.0061: the demosaicing smooths the blocks a little); the
    relations short by it (the halves' by 1.00 of it, the levels' by 0.86, 0.75 and 0.50 of it, the
    model's 1, 7/8, 3/4 and 1/2 within 0.05) and closed, within 0.05 of it, with it taken off; the
    levels' light over their share of white's 12, 5 and 2 % short without it, within 0.3 % with it."""
    table = _true_table()
    photos = _photos()
    true_bias = SIGMA * (BLACK / SIGMA * norm.cdf(BLACK / SIGMA) + norm.pdf(BLACK / SIGMA)) - BLACK
    read = tone_models.black_bias(photos["black"], table)
    low, high = tone_models.BIAS_RANGE
    assert low <= true_bias / read.light <= high
    plain = _mean_residuals(photos, table, None)
    white = float(np.mean(table[photos["white"]]) - np.mean(table[photos["black"]]))
    # short by the clipping's light: the halves' by all of it, the levels' by 1 - 1/K of it
    expected = [-1.0] + [-(1.0 - 1.0 / k) for k in tone_models.LEVEL_PERIODS]
    np.testing.assert_allclose(np.array(plain) * white / true_bias, expected, atol=0.05)
    closed = _mean_residuals(photos, table, tone_models.BlackBias(true_bias, table))
    assert max(abs(v) for v in closed) < 0.05 * true_bias / white
    assert tone_models.level_biases(_histograms(photos), table, true_bias) == pytest.approx(
        (0.0,) * len(tone_models.LEVELS), abs=0.003)
    assert min(tone_models.level_biases(_histograms(photos), table)) < -0.1  # 1 in 8 short by 12 % without
