"""The crosstalk tests' shared panel: a virtual 1280x720, 32-view panel photographed at 1500x1000,
and the profile a fit would give for it (fixed seed); and the light of the tone curve's photos of a
panel whose level rows the camera resolves."""

from __future__ import annotations

import numpy as np

from lenticalib.calib.crosstalk.tone import LEVEL_PERIODS, LEVELS
from lenticalib.core.colour import srgb_encode
from lenticalib.sim.scene import random_scene

VIEWS = 32
PHONE_CONTRAST = 0.5  # the tests' phone S-curve on the sRGB encoding: v + PHONE_CONTRAST (3 v^2 - 2 v^3 - v)


def crosstalk_scene():
    """The seed-31 virtual panel at 620 mm, photographed at 1500x1000 with 2x2 rays a pixel."""
    return random_scene(31, width=1280, height=720, resolution=(1500, 1000), subsamples=2, distance=620.0)


def fitted_profile(scene, period_error: float = 0.0):
    """``scene``'s true profile as a fit gives it: 0.05 view of centring error and the period
    off by the relative ``period_error``."""
    truth = scene.truth_profile(VIEWS)
    return truth.replace(offset=truth.offset + 0.05 * truth.period / VIEWS, period=truth.period * (1 + period_error))


def rows_lit(height: int, period: int, pitch: float) -> np.ndarray:
    """float (height,): the share of each photo row covered by panel rows ``r`` with ``r % period == 0``,
    ``pitch`` photo pixels per panel row (20 samples per photo row)."""
    fine = (np.arange(height * 20) + 0.5) / 20.0
    lit = (np.floor(fine / pitch).astype(int) % period) == 0
    return lit.reshape(height, 20).mean(axis=1)


def tone_photo_light(losses: dict[int, float], pitch: float, size=(600, 400)) -> dict[str, np.ndarray]:
    """Linear light (h, w) of the tone curve's photos of a virtual panel: white with vignetting,
    black, the halves (a band edge every 30 pixels), the levels (rows ``pitch`` photo pixels apart,
    ``losses[K]`` of their light taken off, as a camera's demosaicing does)."""
    w, h = size
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    r2 = ((x - w / 2) ** 2 + (y - h / 2) ** 2) / (w * w / 4 + h * h / 4)
    white, black = 0.55 * (1 - 0.35 * r2), np.full((h, w), 0.008)
    share = np.clip(0.5 + 0.8 * np.sin(2 * np.pi * (x + 0.3 * y) / 60.0), 0.0, 1.0)
    light = {"white": white, "black": black, "half-0": black + share * (white - black),
             "half-1": black + (1 - share) * (white - black)}
    for name, k in zip(LEVELS, LEVEL_PERIODS):
        light[name] = black + (white - black) * rows_lit(h, k, pitch)[:, None] * (1 - losses.get(k, 0.0))
    return light


def phone_codes(light: np.ndarray) -> np.ndarray:
    """float codes (0..255, same shape as ``light``) of a phone-like camera: the sRGB encoding of the
    linear ``light`` (clipped to 0..1) bent by an S-curve of strength ``PHONE_CONTRAST``."""
    v = srgb_encode(np.clip(light, 0.0, 1.0))
    return 255.0 * (v + PHONE_CONTRAST * (3 * v ** 2 - 2 * v ** 3 - v))
