"""The crosstalk tests' shared panel: a virtual 1280x720, 32-view panel photographed at 1500x1000,
and the profile a fit would give for it (fixed seed)."""

from __future__ import annotations

from lenticalib.sim.scene import random_scene

VIEWS = 32


def crosstalk_scene():
    """The seed-31 virtual panel at 620 mm, photographed at 1500x1000 with 2x2 rays a pixel."""
    return random_scene(31, width=1280, height=720, resolution=(1500, 1000), subsamples=2, distance=620.0)


def fitted_profile(scene, period_error: float = 0.0):
    """``scene``'s true profile as a fit gives it: 0.05 view of centring error and the period
    off by the relative ``period_error``."""
    truth = scene.truth_profile(VIEWS)
    return truth.replace(offset=truth.offset + 0.05 * truth.period / VIEWS, period=truth.period * (1 + period_error))
