"""The level photos' rows as the camera resolves them: the light a camera's demosaicing takes off them.

A level photo lights one panel row in ``K`` (:data:`..patterns.crosstalk_patterns.LEVEL_ROW_PERIODS`):
in linear light it holds ``1/K`` of white's above black, but only as far as the camera leaves the
rows alone.  Where it resolves them (a close camera, a sharp lens sheet), a demosaicing that is
not linear (edge-aware, as most are) loses some of their light: the bench's linear photos (OpenCV's
edge-aware demosaicing, before any tone curve) held 1-in-8 rows 1-13 % short, 1-in-4 rows up to 6 %,
1-in-2 rows up to 2 %, the more the more the rows showed in the photo, and a tone curve fitted to
the levels as exact bent its mid-tones to follow (hard cases 3, 4, 6, 7, 8: the own-view share
0.010-0.015 low, 0.004 with the camera's true curve).  The photos cannot tell that loss from a
bend of the camera's curve, so it is estimated from what they do show, how much of each level's
rows the camera resolved:

    modulation_K = sqrt(max(P(level) - P(white), 0)) / mean(level)

``P`` the mean square of the photo's codes less their running mean over ``ROW_WINDOW`` photo rows
(what varies from row to row, in codes), ``mean`` the level's mean code, both over the panel's lit
area; white's own texture and noise are taken off.  The loss is ``TEXTURE_LOSS`` times it: on the
bench the loss was 0.17-0.54 times the modulation where the rows showed (modulation above 0.1;
median 0.27), and about nothing below; another camera's demosaicing may lose none (a bilinear one
is linear).  So the fit takes the middle, ``TEXTURE_LOSS`` = 0.15, as the levels' expected share of
white (:func:`expected_shares`), and the curve's spread between no loss and twice it into its
uncertainty (:mod:`.tone`).
"""

from __future__ import annotations

import numpy as np

from ..patterns.crosstalk_patterns import LEVEL_ROW_PERIODS

ROW_WINDOW = 9  # photo rows: the running mean the row-to-row variation is taken about
TEXTURE_LOSS = 0.15  # the share of a level's modulation its light is taken to lose (0 .. 2x it in the uncertainty)
LIT_LEVEL = 0.3  # the lit area: white's codes above this share of their 95th percentile ...
ERODE = 15  # ... shrunk by this many photo pixels (the panel's edge is not row texture)


def row_variation(image: np.ndarray, area: np.ndarray) -> tuple[float, float]:
    """(mean square of the row-to-row variation, mean) of the grey codes of ``image`` (uint8 (h, w, 3))
    over ``area`` (bool (h, w)): codes less their running mean over ``ROW_WINDOW`` rows."""
    import cv2

    grey = image.astype(np.float32).mean(axis=2)
    variation = grey - cv2.blur(grey, (1, ROW_WINDOW), borderType=cv2.BORDER_REFLECT)
    return float(np.mean(variation[area].astype(np.float64) ** 2)), float(np.mean(grey[area]))


def level_modulations(images: dict[str, np.ndarray]) -> dict[str, float]:
    """Each level photo's row modulation (module docstring): name -> 0 .. (about 1); ``images`` uint8
    (h, w, 3) photos holding "white" and the levels; {} where there are none or no lit area."""
    import cv2

    names = [f"level-1in{k}" for k in LEVEL_ROW_PERIODS if f"level-1in{k}" in images]
    white = images["white"].astype(np.float32).mean(axis=2)
    lit = white > LIT_LEVEL * np.percentile(white, 95)
    area = cv2.erode(lit.astype(np.uint8), np.ones((ERODE, ERODE), np.uint8)) > 0
    if not names or np.count_nonzero(area) < ROW_WINDOW ** 2:
        return {}
    white_power, _ = row_variation(images["white"], area)
    modulations = {}
    for name in names:
        power, mean = row_variation(images[name], area)
        modulations[name] = float(np.sqrt(max(power - white_power, 0.0)) / max(mean, 1e-6))
    return modulations


def expected_shares(modulations: dict[str, float], loss: float = TEXTURE_LOSS) -> dict[str, float]:
    """name -> the share of its ``1/K`` of white's light each level photo is expected to hold:
    ``1 - loss x modulation`` (at least a half: a level further off is refused as another photo)."""
    return {name: max(0.5, 1.0 - loss * value) for name, value in modulations.items()}
