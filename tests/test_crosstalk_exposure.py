"""Each photo's exposure read on the registration frame (lenticalib.calib.crosstalk.exposure), on
synthetic photos whose exposures are known: a drifting exposure, veiling glare from the panel's
inside, a textured frame, shake and noise (fixed seeds)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lenticalib.calib.crosstalk import exposure, tiles, tone
from lenticalib.core.colour import srgb_decode_lut, srgb_encode

POWER = 1.05  # the camera's light of code c: sRGB decoding ** POWER
SIZE = (900, 600)  # photo (w, h)
OUTER = (100, 80, 800, 520)  # the frame's outer edge (x0, y0, x1, y1), photo pixels
FRAME = 14  # the frame's width, photo pixels
GLARE = (0.03, 60.0)  # fraction of the light spread, sigma (photo pixels)


def _inside_light(name: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The panel's inside as photo ``name`` shows it (linear, before exposure)."""
    white = 0.6 * (1 - 0.3 * (((x - 450) / 450) ** 2 + ((y - 300) / 300) ** 2))
    black = np.full_like(x, 0.004)
    if name == "white":
        return white
    if name == "black":
        return black
    if name.startswith("half"):
        share = np.clip(0.5 + 0.8 * np.sin(2 * np.pi * (x + 0.3 * y) / 60.0), 0.0, 1.0)
        return black + (share if name == "half-0" else 1 - share) * (white - black)
    if name.startswith("level"):
        k = int(name.rsplit("in", 1)[1])
        return black + (white - black) * ((np.floor(y / 0.6).astype(int) % k) == 0)
    shift = int(name.rsplit("-", 1)[1])  # a band: one view in 32 of a sweep across the panel
    phase = np.mod(x / 25.0 + 0.2 * y / 25.0 + 3.2 * shift, 32.0)
    return black + (white - black) * np.exp(-0.5 * ((phase - 16) / 0.6) ** 2)


def _photos(drift: float = 0.04, seed: int = 5, frame: bool = True, bezel: float = 0.03, fixed=None,
            names=("black", "white", "half-0", "half-1", "level-1in8", "level-1in4", "level-1in2",
                   "band-00", "band-03")) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """(uint8 RGB photos, true exposures) of a virtual panel whose camera's exposure drifts by up
    to ``drift`` from photo to photo; the frame (level 0.25, textured by the lens sheet) around
    the inside, a bezel of light ``bezel`` around it, glare, a blur of one pixel, shake of up to
    0.3 pixel and noise of half a code; ``fixed``: exposures of some photos, set instead of drawn."""
    import cv2

    w, h = SIZE
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    x0, y0, x1, y1 = OUTER
    panel = (x >= x0) & (x < x1) & (y >= y0) & (y < y1)
    inside = (x >= x0 + FRAME) & (x < x1 - FRAME) & (y >= y0 + FRAME) & (y < y1 - FRAME)
    texture = 1 + 0.1 * np.sin(2 * np.pi * (x + 0.35 * y) / 3.7)
    rng = np.random.default_rng(seed)
    photos, exposures = {}, {}
    for name in names:
        light = np.where(panel, 0.25 * texture if frame else 0.004, bezel * (1 + 0.2 * x / w))
        light = np.where(inside, _inside_light(name, x, y), light)
        light = (1 - GLARE[0]) * light + GLARE[0] * cv2.GaussianBlur(light, (0, 0), GLARE[1])
        e = 1.0 + rng.uniform(-drift, drift)
        e = (fixed or {}).get(name, e)
        exposures[name] = e
        dx, dy = rng.uniform(-0.3, 0.3, 2)
        moved = cv2.warpAffine((e * light).astype(np.float32), np.float32([[1, 0, dx], [0, 1, dy]]), (w, h),
                               flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        moved = cv2.GaussianBlur(moved, (0, 0), 1.0).astype(np.float64)
        code = 255 * srgb_encode(np.clip(moved, 0, 1) ** (1 / POWER))[:, :, None] + rng.normal(0, 0.5, (h, w, 3))
        photos[name] = np.clip(np.rint(code), 0, 255).astype(np.uint8)
    return photos, exposures


def _true_table() -> np.ndarray:
    return srgb_decode_lut() ** POWER


def test_the_exposures_are_read_on_the_frame_s_outer_edge_through_glare_and_shake():
    """Within 0.5 % of the truth for every photo, where the frame's mean light (the glare of the
    white inside on it) puts white's exposure 2 % off the bands'."""
    photos, truth = _photos()
    found = exposure.measure_exposures(photos, _true_table())
    assert found is not None and found.rms < exposure.MAX_RESIDUAL
    errors = {k: found.relative[k] / (truth[k] / truth["white"]) - 1 for k in photos}
    assert max(abs(v) for v in errors.values()) < 0.005, errors
    # the sectors' spread says how well each is known: the errors within 4 sigma (a floor of 0.1 %)
    assert all(abs(errors[k]) <= 4 * max(found.sigma[k], 0.001) for k in photos if k != "white")
    # what the frame's mean light would say: the glare from the inside read as exposure
    table = _true_table()
    x0, y0, x1, y1 = OUTER
    ring = np.zeros(photos["black"].shape[:2], bool)
    ring[y0 + 4:y1 - 4, x0 + 4:x1 - 4] = True
    ring[y0 + FRAME - 4:y1 - FRAME + 4, x0 + FRAME - 4:x1 - FRAME + 4] = False
    mean = {k: table[v].sum(axis=2)[ring].mean() for k, v in photos.items()}
    naive = mean["band-00"] / mean["white"] / (truth["band-00"] / truth["white"]) - 1
    assert abs(naive) > 0.01


def test_a_locked_exposure_reads_as_locked_and_is_left_alone():
    """No drift: every exposure within 0.4 % of white's, which is too little to be undone (the tone
    fit then stands as without the frame)."""
    photos, _ = _photos(drift=0.0)
    found = exposure.measure_exposures(photos, _true_table())
    assert max(abs(v - 1) for v in found.relative.values()) < 0.004
    assert found.applied_weight() == 0.0 and set(found.applied().values()) == {1.0}
    drifting = exposure.measure_exposures(_photos()[0], _true_table())
    assert drifting.drift() > exposure.DRIFT_RANGE[1] and drifting.applied() == drifting.relative


@pytest.mark.parametrize("case", ["no frame", "crushed bezel"])
def test_no_estimate_where_the_frame_s_step_cannot_be_read(case):
    """Photos without a frame (a panel showing other patterns) or with the bezel crushed to code 0
    (a phone's S-curve): no exposures, rather than wrong ones."""
    photos, _ = _photos(frame=case != "no frame", bezel=0.03 if case == "no frame" else 0.0)
    if case == "crushed bezel":
        for v in photos.values():
            v[v < 12] = 0
    assert exposure.measure_exposures(photos, _true_table()) is None


def test_the_tone_curve_is_fitted_with_the_photos_brought_to_white_s_exposure(monkeypatch):
    """With the halves 3-4 % brighter than white and black the relations no longer add up at one
    exposure: the power fitted with the frame's exposures is within 0.01 of the camera's; without
    them (the exposure taken as locked) it is not."""
    photos, _ = _photos(fixed={"white": 0.97, "black": 0.98, "half-0": 1.04, "half-1": 1.03})
    curve = tone.fit_tone_curve(photos, tiles.tile_size(SIZE[0]))
    assert curve.exposures is not None and curve.model == "power"
    assert abs(curve.power - POWER) < 0.01
    assert abs(math.log(curve.power / POWER)) <= 3 * curve.sigma
    monkeypatch.setattr(tone, "EXPOSURE_ROUNDS", 0)
    locked = tone.fit_tone_curve(photos, tiles.tile_size(SIZE[0]))
    assert locked.exposures is None and abs(locked.power - POWER) > 0.02
