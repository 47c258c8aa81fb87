"""The level photos' rows as the camera resolves them: the light a camera's demosaicing takes off them.

A level photo lights one panel row in ``K`` (:data:`..patterns.crosstalk_patterns.LEVEL_ROW_PERIODS`):
in linear light it holds ``1/K`` of white's above black, but only as far as the camera leaves the
rows alone.  Where it resolves them (a close camera, a sharp lens sheet), a demosaicing that is
not linear (edge-aware, as most are) loses some of their light: the bench's linear photos (OpenCV's
edge-aware demosaicing, before any tone curve) held 1-in-8 rows 1-13 % short, 1-in-4 rows up to 6 %,
1-in-2 rows up to 2 %, and a tone curve fitted to the levels as exact bent its mid-tones to follow
(hard cases 3, 4, 6, 7, 8: the own-view share 0.010-0.015 low, 0.004 with the camera's true
curve).  The photos cannot tell that loss from a bend of the camera's curve; what they show is
how much of each level's rows the camera resolved:

    modulation_K = sqrt(max(P(level) - P(white), 0)) / mean(level)

``P`` the mean square of the photo's codes less their running mean over ``ROW_WINDOW`` photo rows
(what varies from row to row, in codes), ``mean`` the level's mean code, both over the panel's lit
area; white's own texture and noise are taken off.  The loss does not follow it closely: on the
bench's linear photos (OpenCV's edge-aware demosaicing) it was 0.17-0.54 times the modulation
where rows 3 photo pixels apart showed (hard cases 1-12; case 13 0.3-0.5), but 0.02 times it on
the tests' panel, whose 1-in-8 rows are 11 pixels apart (modulation 0.65, loss 1.4 %: thick lines
keep their light), and another camera's demosaicing may lose nothing (a bilinear one is linear).
Expected as 0.15 times the modulation, the loss put hard cases 3-8 within 0.01 but the tests'
phone 0.026 off (0.006 with the levels as exact), and on a phone's S-curve one per cent of a
level's light moves the own-view share by about 0.004.  So the photos do not say the loss, and it
is carried, not corrected: the curve is fitted with the levels as exact, and half its change
when each level loses ``LOSS_BOUND`` times its modulation (:func:`shares_after_loss`) enters its
uncertainty (:mod:`.tone`).
"""

from __future__ import annotations

import numpy as np

from ..patterns.crosstalk_patterns import LEVEL_ROW_PERIODS

ROW_WINDOW = 9  # photo rows: the running mean the row-to-row variation is taken about
LOSS_BOUND = 0.3  # the share of a level's modulation its light may lose: half the curve's change to it is a 1-sigma
LIT_LEVEL = 0.3  # the lit area: white's codes above this share of their 95th percentile ...
ERODE = 15  # ... shrunk by this many photo pixels (the panel's edge is not row texture)


def grey_codes(image: np.ndarray) -> np.ndarray:
    """float32 (h, w): the mean of the three channels' codes of ``image`` (uint8 (h, w, 3))."""
    return image.astype(np.float32).mean(axis=2)


def row_variation(grey: np.ndarray, area: np.ndarray) -> tuple[float, float]:
    """(mean square of the row-to-row variation, mean) of the ``grey`` codes (float32 (h, w),
    :func:`grey_codes`) over ``area`` (bool (h, w)): codes less their running mean over ``ROW_WINDOW`` rows."""
    import cv2

    variation = grey - cv2.blur(grey, (1, ROW_WINDOW), borderType=cv2.BORDER_REFLECT)
    return float(np.mean(variation[area].astype(np.float64) ** 2)), float(np.mean(grey[area]))


def level_modulations(images: dict[str, np.ndarray]) -> dict[str, float]:
    """Each level photo's row modulation (module docstring): name -> 0 .. (about 1); ``images`` uint8
    (h, w, 3) photos holding "white" and the levels; {} where there are none or no lit area."""
    import cv2

    names = [f"level-1in{k}" for k in LEVEL_ROW_PERIODS if f"level-1in{k}" in images]
    white = grey_codes(images["white"])
    lit = white > LIT_LEVEL * np.percentile(white, 95)
    area = cv2.erode(lit.astype(np.uint8), np.ones((ERODE, ERODE), np.uint8)) > 0
    if not names or np.count_nonzero(area) < ROW_WINDOW ** 2:
        return {}
    white_power, _ = row_variation(white, area)
    modulations = {}
    for name in names:
        power, mean = row_variation(grey_codes(images[name]), area)
        modulations[name] = float(np.sqrt(max(power - white_power, 0.0)) / max(mean, 1e-6))
    return modulations


def shares_after_loss(modulations: dict[str, float], loss: float = LOSS_BOUND) -> dict[str, float]:
    """name -> the share of its ``1/K`` of white's light each level photo holds when it loses ``loss``
    times its modulation: ``1 - loss x modulation`` (at least a half)."""
    return {name: max(0.5, 1.0 - loss * value) for name, value in modulations.items()}
