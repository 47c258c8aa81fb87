"""The camera's tone curve (lenticalib.calib.crosstalk.tone) on synthetic photos whose light is known
pixel by pixel: the level rows resolved by the camera and left short of their share by its
demosaicing, as a close camera's are."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lenticalib.calib.crosstalk import tiles, tone
from lenticalib.core.colour import srgb_encode

from .crosstalk_support import tone_photo_light

POWER = 1.05  # the camera's light of code c: sRGB decoding ** POWER
ROW_PITCH = 0.6  # photo pixels per panel row: a close camera resolves 1-in-8 rows (4.8 pixels apart)
DEMOSAIC_SHORTFALL = {8: 0.065, 4: 0.03, 2: 0.008}  # resolved rows' light short of 1/K (OpenCV's EA demosaicing)


def _photos(shortfall: dict[int, float], seed: int = 3, size=(600, 400)) -> dict[str, np.ndarray]:
    """uint8 RGB photos of a virtual panel (:func:`crosstalk_support.tone_photo_light`, rows
    ``ROW_PITCH`` apart, ``shortfall`` taken off the levels' light); codes of a camera whose light
    is ``D(c) ** POWER``, with noise of half a code."""
    w, h = size
    light = tone_photo_light(shortfall, ROW_PITCH, size)
    rng = np.random.default_rng(seed)
    photos = {}
    for name, value in light.items():
        code = 255 * srgb_encode(value ** (1 / POWER))[:, :, None] + rng.normal(0, 0.5, (h, w, 3))
        photos[name] = np.clip(np.rint(code), 0, 255).astype(np.uint8)
    return photos


@pytest.mark.parametrize("shortfall", [{}, DEMOSAIC_SHORTFALL])
def test_the_power_rests_on_the_halves_not_on_resolved_level_rows(shortfall):
    """Level rows the camera resolves are a lit row more or less per tile, and its demosaicing
    leaves them short of their share (6.5 % for 1 in 8): the power still comes out within 0.01 of
    the camera's, inside 3 sigma, and the levels are no photos of another pattern.  (Pinned by the
    levels, tile by tile, it came out 1.064 with the shortfall, and the medians of the tiles put 1-in-8
    and 1-in-4 rows 19 % off their share.)"""
    curve = tone.fit_tone_curve(_photos(shortfall), tiles.tile_size(600))
    assert curve.model == "power" and curve.levels
    assert abs(curve.power - POWER) < 0.01
    assert abs(math.log(curve.power / POWER)) <= 3 * curve.sigma
    assert all(abs(r) < tone.MAX_LEVEL_BIAS for r in curve.level_residuals)


def test_level_residuals_are_sums_over_the_tiles_not_medians():
    """Without a shortfall the levels hold over whole periods of their rows: each level's light over
    the panel is its share of white's within 1 %, although most tiles hold one lit row too few."""
    curve = tone.fit_tone_curve(_photos({}), tiles.tile_size(600))
    assert max(abs(r) for r in curve.level_residuals) < 0.01


def test_the_curve_weight_rises_smoothly_with_either_sign_of_a_bent_camera_curve():
    """No switch: a camera near the boundary gets a blend, and a small change of the evidence a small
    change of the weight; either sign alone (a bend the halves show, levels off their shares
    under the power) is enough."""
    from lenticalib.calib.crosstalk.tone_choice import GAIN_RANGE, LEVEL_BIAS_RANGE, curve_weight

    assert curve_weight(0.0, 0.0) == 0.0
    assert curve_weight(GAIN_RANGE[1], 0.0) == 1.0 and curve_weight(0.0, LEVEL_BIAS_RANGE[1]) == 1.0
    middle = sum(GAIN_RANGE) / 2
    assert curve_weight(middle, 0.0) == pytest.approx(0.5)
    gains = np.linspace(0.0, 0.2, 401)
    weights = np.array([curve_weight(g, 0.0) for g in gains])
    assert np.all(np.diff(weights) >= 0) and np.max(np.diff(weights)) < 0.05
    assert curve_weight(math.nan, 0.0) == 0.0


def test_a_blend_of_two_models_reports_the_mixture_s_spread():
    """The blended sigma is the standard deviation of the two models' results as a mixture: drawn
    from it (fixed seed), the spread agrees within 2 %."""
    from lenticalib.calib.crosstalk.tone_choice import blended, blended_sigma

    main, other, s_main, s_other, weight = 0.50, 0.53, 0.004, 0.006, 0.3
    rng = np.random.default_rng(11)
    pick = rng.random(400_000) < weight
    draws = np.where(pick, rng.normal(other, s_other, pick.size), rng.normal(main, s_main, pick.size))
    assert blended(main, other, weight) == pytest.approx(draws.mean(), abs=1e-4)
    assert blended_sigma(main, s_main, other, s_other, weight) == pytest.approx(draws.std(), rel=0.02)


def test_two_tone_models_blend_into_one_measurement_whose_figures_carry_their_spread():
    """``measure._blend``: the row, cone and uniformity map blended at the weight, the sigmas the
    mixture's, the figures' sigmas grown by the two models' difference, the record JSON-ready."""
    import json

    from lenticalib.calib.crosstalk.measure import Measurement, _blend
    from lenticalib.calib.crosstalk.result import figures_with_sigma

    def measurement(row, scale):
        row = np.asarray(row, float)
        return Measurement(views=4, row=row, row_sigma=np.full(4, 0.002), cone_grid=np.linspace(-2, 2, 5),
                           cone=row.sum() * np.ones(5) * scale, cone_sigma=np.full(5, 0.001),
                           regions=np.full((2, 3), row[0]), regions_sigma=np.full((2, 3), 0.003),
                           samples={"blocks": np.tile(row, (3, 1))}, photometry={}, diagnostics={},
                           warnings=[], inputs=[], profile=None, pattern_set=None, seconds=1.0)

    power, curve = measurement([0.50, 0.20, 0.10, 0.20], 1.0), measurement([0.56, 0.18, 0.08, 0.18], 1.1)
    both = _blend(power, curve, 0.25)
    assert both.row == pytest.approx([0.515, 0.195, 0.095, 0.195]) and both.row.sum() == pytest.approx(1.0)
    assert both.regions[0, 0] == pytest.approx(0.515)
    assert both.row_sigma[0] == pytest.approx(math.sqrt(0.002 ** 2 + 0.25 * 0.75 * 0.06 ** 2))
    plain = figures_with_sigma(power.row, power.samples, None)
    blended = figures_with_sigma(both.row, both.samples, None)
    assert blended["own_view_share"]["sigma"] == pytest.approx(math.sqrt(0.25 * 0.75) * 0.06, rel=1e-6)
    assert plain["own_view_share"]["sigma"] == 0.0
    json.dumps(both.diagnostics["tone_blend"])


def test_the_report_draws_the_measured_tone_curve_with_its_sigma_and_the_codes_it_reads(tmp_path):
    """``tone-curve.png`` (camera JPEGs): the fitted curve of ``crosstalk.json`` against plain sRGB,
    with the 1-sigma it propagates, the black and white photos' codes, and a blended model named
    with its weight; all texts and the numbers recorded in the PNG."""
    from lenticalib.calib.crosstalk.report import FIGURE_SIZES, _tone_curve
    from lenticalib.core.figures import read_figure_record
    from lenticalib.core.figures import write_figures

    fitted = tone.fit_tone_curve(_photos(DEMOSAIC_SHORTFALL), tiles.tile_size(600))
    curve = fitted.to_dict()
    other = tone.ToneCurve("curve", tone.decode_lut(1.1), 0.03, 0.01, 1000, levels=True)
    blended = dict(curve, blended_with={**other.to_dict(), "weight": 0.3})
    for name, data in (("plain", curve), ("blended", blended)):
        (tmp_path / name).mkdir()
        write_figures(tmp_path / name, [("tone-curve.png", lambda fig, _, d=data: _tone_curve(fig, d))],
                      FIGURE_SIZES, None)
    record = read_figure_record(tmp_path / "plain" / "tone-curve.png")
    assert record["numbers"] == {"model": "power", "power_sigma": curve["power_sigma"], "toe_sigma": curve["toe_sigma"],
                                 "code_range": curve["code_range"], "blended_weight": 0.0}
    assert "half and level photos" in record["title"]
    light, ratio = record["axes"][:2]
    assert light["xlabel"].startswith("8-bit code") and "linear light" in light["ylabel"]
    assert "sRGB" in ratio["ylabel"] and ratio["title"]
    assert all(label.endswith(")") and "(" in label for ax in (light, ratio) for label in (ax["xlabel"], ax["ylabel"]))
    assert any(f"1 ± {curve['power_sigma']:.3f}" in t for t in light["legend"])
    assert curve["toe_sigma"] > 0 and any(f"the toe ± {100 * curve['toe_sigma']:.0f} %" in t for t in light["legend"])
    assert any(f"** {curve['power']:.3f}" in t for t in light["legend"])
    assert not any("blended" in t for t in light["legend"])
    black, white = curve["code_range"]
    assert any(f"median code {black}" in t for t in light["texts"]) and any(f"median code {white}" in t
                                                                           for t in light["texts"])
    record = read_figure_record(tmp_path / "blended" / "tone-curve.png")
    assert record["numbers"]["blended_weight"] == 0.3
    assert any("weight 0.30" in t and "bent curve" in t for t in record["axes"][0]["legend"])


def test_the_toe_sigma_is_half_the_models_difference_just_above_black_weighted_by_their_sigmas():
    """Two models whose light at black + 2 codes (relative to white) differs by 30 % leave the toe
    open by half of log 1.3 (13 %), in full where the other model is as sure of itself as the main one, by the
    ratio of their sigmas where it is less sure; identical toes leave nothing."""
    codes = np.arange(12, 141)
    main_table = tone.decode_lut(1.0).astype(np.float64)
    other_table = main_table.copy()
    other_table[12] *= 1.3

    def curve(table, sigma):
        return tone.ToneCurve("curve", table, sigma, 0.0, 1000)

    assert tone._toe_sigma(curve(main_table, 0.02), curve(other_table, 0.02), codes) == pytest.approx(0.5 * math.log(1.3))
    assert tone._toe_sigma(curve(other_table, 0.02), curve(main_table, 0.02), codes) == pytest.approx(0.5 * math.log(1.3))
    assert tone._toe_sigma(curve(main_table, 0.02), curve(other_table, 0.08), codes) == pytest.approx(0.5 * math.log(1.3) / 4)
    assert tone._toe_sigma(curve(main_table, 0.02), curve(main_table * 2.0, 0.02), codes) == pytest.approx(0.0)
    far_off = other_table.copy()
    far_off[12] *= 100.0
    assert tone._toe_sigma(curve(main_table, 0.02), curve(far_off, 0.02), codes) == tone.MAX_TOE_SIGMA


def test_a_power_camera_s_toe_is_left_open_by_a_few_per_cent_only():
    """On photos of a camera whose curve is a power (the model chosen), the bent curve's freer toe
    is weighted by how much less sure it is of itself: both models fitted, the toe's sigma
    recorded, under 6 %."""
    curve = tone.fit_tone_curve(_photos({}), tiles.tile_size(600))
    assert curve.model == "power" and curve.alternative is not None
    assert 0.0 < curve.toe_sigma < 0.06 and curve.alternative.toe_sigma == curve.toe_sigma
    assert curve.to_dict()["toe_sigma"] == pytest.approx(curve.toe_sigma, abs=1e-4)


def test_the_toe_perturbation_changes_only_light_below_its_end_and_most_at_black():
    """``ratios.relinearised``: light at or above ``TOE_END`` of white's is only raised to the
    power; at black it changes by the whole ``toe``, half-way to TOE_END by half of it."""
    from lenticalib.calib.crosstalk.ratios import TOE_END, relinearised

    white = np.full(4, 2.0)
    light = white * np.array([0.0, TOE_END / 2, TOE_END, 0.8])
    assert relinearised(light, white) == pytest.approx(light)
    out = relinearised(light + 1e-12, white, toe=0.2)
    assert out[1] == pytest.approx(light[1] * 1.1) and out[2:] == pytest.approx(light[2:])
    assert relinearised(np.array([1e-3]), np.array([2.0]), toe=0.2)[0] == pytest.approx(1e-3 * (1 + 0.2 * (1 - 5e-4 / TOE_END)))
    assert relinearised(light, white, power=1.1, toe=0.0) == pytest.approx(light ** 1.1)


def test_the_toe_s_perturbed_rows_enter_the_derived_figures_sigma():
    """``result.figures_with_sigma``: the rows measured with the toe's light moved by +- its sigma add
    half their difference to each figure's sigma, as the glare's and the power's do."""
    from lenticalib.calib.crosstalk.result import figures_with_sigma

    row = np.array([0.5, 0.2, 0.1, 0.2])
    moved = {"toe-": np.array([0.52, 0.19, 0.09, 0.20]), "toe+": np.array([0.48, 0.21, 0.11, 0.20])}
    plain = figures_with_sigma(row, {}, None)
    with_toe = figures_with_sigma(row, moved, None)
    assert plain["own_view_share"]["sigma"] == 0.0
    assert with_toe["own_view_share"]["sigma"] == pytest.approx(0.02)
