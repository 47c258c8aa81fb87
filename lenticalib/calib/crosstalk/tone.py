"""The camera's tone curve, measured from the crosstalk photos themselves (``docs/crosstalk.md``).

A camera JPEG is not linear light, and not quite sRGB either: a camera's picture style bends the
curve by several per cent (a phone's S-curve by tens), which moves the measured view cone by a few
hundredths.  Two relations of the patterns hold in linear light whatever the panel's own tone
response does (its subpixels are only ever full on or off), at every place of the panel:

    half-0 + half-1 = white + black               (complementary halves of the views)
    level-1inK - black = (white - black) / K      (every subpixel of one panel row in K, K = 8, 4, 2)

Where the band of either half passes the camera both halves are partly lit, and the first relation
fixes how the curve bends (only its part that is not antisymmetric about the half-way light); the
levels pin it at 1/8, 1/4 and 1/2 of white everywhere on the panel.

The relations hold for the light of a pixel, not for its code: each photo is linearised pixel by
pixel and averaged over small tiles (``tile`` x ``tile`` photo pixels, all three channels) before
the photos are compared.  Each tile's code histogram is kept (a sparse matrix, tiles x 256 codes),
so a tile's mean light under a curve is one matrix product, and the relations are linear in the
curve's 256 values.  The half relation holds pixel by pixel; a level's only over whole periods of
its rows and only as far as the camera's demosaicing leaves resolved rows alone (a close camera's
came out 1-7 % short of their share in linear light, the coarser rows the more): the levels are
averaged over bins of tiles and trusted for the shape of a clearly bent curve, not for a power
(:func:`.tone_models.relations`); what the camera's demosaicing may take off rows it resolves is in the
curve's uncertainty (:mod:`.level_texture`), and a level whose one channel lost light (or gained
it) rests on the other two (:mod:`.level_channels`).  The black photo holds light the sensor's
clipped noise added to it, which the half and level photos' lit places do not: it is read on the
black photo and taken off black in every relation (:func:`.tone_models.relations`).

The relations hold at one exposure.  A phone's drifts from photo to photo, so each photo's exposure
is read on the registration frame every pattern carries (:mod:`.exposure`), under the curve fitted
so far, and the curve fitted again with every photo brought to white's exposure (where the frame
shows a drift worth undoing: ``Exposures.applied``).

Two models:

- ``power``: ``L(c) = D(c) ** p``, ``D`` the sRGB decoding of the 8-bit code ``c``, ``p`` from the
  half relation alone; in sets drawn before the levels each half photo has its own exposure;
- ``curve`` (sets with the level patterns, where the photos show a camera curve that bends: a
  phone's S-curve): ``L(c) = D(c) (1 + sum_j theta_j B_j(c))``, ``B_j`` hat functions on the
  knots ``KNOTS`` (finer near black; the last one's hat is zero at code 256: the scale), fitted by
  linear least squares to the half and level relations with a small second-difference penalty.

Which one, or a blend of both, is :mod:`.tone_choice`'s call: the result carries the other model
and its weight (``alternative``), which :func:`lenticalib.calib.crosstalk.measure.measure_crosstalk`
measures too and blends in.

The 1-sigma is stated as a power ``1 +- sigma`` on the linearised light (what the measurement
propagates): the spread of the curves fitted to ``GROUPS`` strips of the panel (each curve's
log-slope against the whole fit's), over the square root of their number, with a floor of
``POWER_FLOOR`` for what the model and the camera's processing leave, and, for the power, how far
the power the finest level rows pin together with the halves lies from it (``PINNING``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...core.colour import srgb_decode_lut
from .exposure import Exposures, frame_edge, measure_exposures
from .level_channels import photo_of, with_level_channels
from .level_texture import level_modulations, shares_after_loss
from ..patterns.crosstalk_patterns import LEVEL_ROW_PERIODS as LEVEL_PERIODS
from .tiles import tile_histograms, tile_max, tile_means
from .tone_models import (BIAS_RANGE, KNOTS, LEVELS, PHOTOS, BlackBias, bend_gain, best_power, black_bias,
                          fitted_curve, half_residual, level_biases, level_power, log_slope)
from .tone_models import relations as tone_relations
from .tone_choice import curve_weight

# the curve model's knots (codes): finer at the toe, where an S-curve bends most and the half photos'
# dark tiles are its only data (bench hard case 11: its codes 1-15 above black 16-20 % too dark with
# knots every 16, the mid-tones' bend carried into the toe by the smoothing)
GROUPS = 8  # strips of rows of the panel fitted on their own, for the power's spread
MIN_TILES = 400  # tiles where both halves are partly lit, at least (fewer: no fit)
MAX_TILES = 40000  # tiles used at most (drawn with a fixed seed)
PINNING = ("level-1in2",)  # the levels whose power is held against the halves' (the finest rows: tone_models.relations)
POWER_FLOOR = 0.01  # 1-sigma the power family leaves for any camera (its curve is not exactly sRGB ** p)
MAX_RESIDUAL = 0.15  # relative RMS of half-0 + half-1 - white - black above which the photos do not add up
MAX_LEVEL_BIAS = 0.25  # a level photo whose light is further than this from its share of white's: another photo
MAX_TOE_SIGMA = 0.5  # the toe's 1-sigma at most (its light moved by half: the perturbation stays positive)
MONOTONE_TOLERANCE = 0.001  # a bent curve's light may fall this share from one code to the next (noise), no more
BIAS_ROUNDS = 2  # fits with the black photo's clipping taken off (each reads it through the curve before it)
EXPOSURE_ROUNDS = 2  # fits with the frame's exposures (each reads the frame through the curve before it)


@dataclasses.dataclass(frozen=True)
class ToneCurve:
    """A fitted tone curve: ``table`` float32 (256,), the linear light of each 8-bit code (units:
    sRGB's at code 255); ``model`` "curve" or "power" (with ``power``); ``sigma`` its 1-sigma as a
    power on the linearised light; ``residual`` the relative RMS of the half relation;
    ``level_residuals`` each level photo's light (summed over the tiles) over its share of white's, less 1; ``tiles`` how many tiles it
    rests on; ``strips`` the strips' powers (model "power") or log-slopes (model "curve"); ``levels`` whether
    the level photos took part; ``code_range`` the median codes of black and white; ``alternative``
    the other model, to be blended in with ``alternative_weight`` (0..0.5; 0: not used), and the
    evidence for the curve, ``bend_gain`` and ``level_bias`` (:mod:`.tone_choice`); ``exposures`` the
    photos' exposures the relations were brought to white's with (:mod:`.exposure`; None: taken as locked);
    ``toe_sigma`` the 1-sigma of the light of the codes just above black, relative (:func:`_toe_sigma`);
    ``level_modulations`` each level photo's rows as the camera resolved them and ``texture_sigma``
    what the light its demosaicing may have taken off them leaves open, as a power (:mod:`.level_texture`);
    ``level_channels`` the channels each level's relation rests on and the three channels' shares
    (:mod:`.level_channels`); ``black_bias`` the light the black photo's clipped noise added, taken
    off black in the relations (the table's units; :func:`.tone_models.relations`)."""

    model: str
    table: np.ndarray
    sigma: float
    residual: float
    tiles: int
    power: float = 1.0
    strips: tuple[float, ...] = ()
    level_residuals: tuple[float, ...] = ()
    levels: bool = False
    code_range: tuple[int, int] = (0, 255)
    alternative: "ToneCurve | None" = None
    alternative_weight: float = 0.0
    bend_gain: float = math.nan
    level_bias: float = math.nan
    exposures: Exposures | None = None
    toe_sigma: float = 0.0
    level_modulations: tuple[float, ...] = ()
    texture_sigma: float = 0.0
    level_channels: dict = dataclasses.field(default_factory=dict)
    black_bias: float = 0.0

    def lut(self) -> np.ndarray:
        """float32 (256,): the linear light of each 8-bit code."""
        return self.table

    @property
    def curve_weight(self) -> float:
        """The bent curve's weight in the blend (0..1), whichever model is the main one."""
        return self.alternative_weight if self.model == "power" else 1.0 - self.alternative_weight

    def undecided(self) -> float:
        """0..1: how far the photos leave the choice between this model and the ``alternative`` open.
        Half their difference (as a power on the light over the codes read) is a possible error of
        either; where that exceeds this model's own sigma, weighted by how sure the other model is
        of itself (``min(1, sigma / other's sigma)``), the measurement takes the rows through both
        and half their difference into the uncertainty at that weight (0: not needed)."""
        other = self.alternative
        if other is None or not (math.isfinite(self.sigma) and math.isfinite(other.sigma)):
            return 0.0
        black, white = self.code_range
        codes = np.arange(min(black + 2, white - 1), white + 1)
        apart = 0.5 * abs(log_slope(np.asarray(other.table, np.float64), np.asarray(self.table, np.float64), codes))
        share = _other_share(self, other)
        return share if apart * share > self.sigma else 0.0

    def to_dict(self) -> dict:
        data = {"model": "sRGB decoding ** power" if self.model == "power" else
                f"sRGB decoding x piecewise-linear factor (knots at codes {', '.join(map(str, KNOTS))})",
                "power_sigma": round(self.sigma, 4), "toe_sigma": round(self.toe_sigma, 4), "code_range": list(self.code_range), "half_residual": round(self.residual, 4), "tiles": self.tiles,
                "strips": [round(v, 4) for v in self.strips],
                "relations": "half and level photos" if self.levels else "half photos (exposures free)"}
        if self.model == "power":
            data["power"] = round(self.power, 4)
        else:
            data["light_of_code"] = [round(float(v), 6) for v in self.table]
        if self.levels:
            data["level_residuals"] = [round(v, 4) for v in self.level_residuals]
        if self.level_modulations:
            shares = shares_after_loss(dict(zip(LEVELS, self.level_modulations)))
            data["level_texture"] = {"levels": list(shares), "modulations": [round(v, 4) for v in self.level_modulations],
                                     "shares_at_loss_bound": [round(v, 4) for v in shares.values()],
                                     "power_sigma": round(self.texture_sigma, 4)}
        if self.level_channels:
            data["level_channels"] = self.level_channels
        if self.black_bias:
            data["black_clip_bias"] = round(self.black_bias, 6)
        if math.isfinite(self.bend_gain):
            data["curve_evidence"] = {"bend_gain": round(self.bend_gain, 4), "level_bias": round(self.level_bias, 4)}
        if self.exposures is not None:
            data["exposures"] = self.exposures.to_dict()
        if self.alternative is not None and self.alternative_weight > 0:
            data["blended_with"] = {**self.alternative.to_dict(), "weight": round(self.alternative_weight, 4)}
        return data


def decode_lut(power: float = 1.0) -> np.ndarray:
    """float32 (256,): sRGB-decoded light of each 8-bit code, to the power ``power``."""
    return (srgb_decode_lut() ** power).astype(np.float32)


def fit_tone_curve(images: dict[str, np.ndarray], tile: int) -> ToneCurve | None:
    """The tone curve from uint8 RGB photos ``images`` (photo pixels, (h, w, 3)) of "black", "white",
    "half-0", "half-1" and, when the set has them, the ``LEVELS`` (the power from the halves and the
    curve, weighted by :func:`.tone_choice.curve_weight`; without the levels the power, exposures free);
    ``tile``: side of the tiles in photo pixels.  None where the photos give too little to fit
    (fewer than ``MIN_TILES`` tiles)."""
    means = {k: tile_means(images[k], tile) for k in PHOTOS}
    lit = means["white"] - means["black"]
    level = np.percentile(lit, 95)
    if not level > 0:
        return None
    inside = (lit > 0.3 * level) & (tile_max(images["white"], tile) < 250)
    share0 = (means["half-0"] - means["black"]) / np.maximum(lit, 1e-6)
    share1 = (means["half-1"] - means["black"]) / np.maximum(lit, 1e-6)
    # in codes: a tile whose halves are each lit by 5-95 % of white's code (the bend shows there)
    mixed = inside & (share0 > 0.05) & (share1 > 0.05) & (share0 < 0.95) & (share1 < 0.95)
    levels = all(k in images for k in LEVELS)
    picked = np.flatnonzero((inside if levels else mixed).ravel())
    if np.count_nonzero(mixed) < MIN_TILES or picked.size < MIN_TILES:
        return None
    if picked.size > MAX_TILES:
        picked = np.sort(np.random.default_rng(0).choice(picked, MAX_TILES, replace=False))
    hist = {k: tile_histograms(images[k], tile, picked) for k in PHOTOS + (LEVELS if levels else ())}
    mixed = mixed.ravel()[picked]
    rows = picked // lit.shape[1]
    edges = np.quantile(rows, np.linspace(0, 1, GROUPS + 1))
    group = np.clip(np.searchsorted(edges, rows, side="right") - 1, 0, GROUPS - 1)
    # the codes the measurement reads: from black to white (median tiles)
    black = int(np.ceil(np.median(hist["black"] @ np.arange(256))))
    white = int(np.floor(np.median(hist["white"] @ np.arange(256))))
    codes = np.arange(min(black + 2, white - 1), white + 1)
    strips = []
    if not levels:
        power, residual = best_power(hist)
        for g in range(GROUPS):
            sel = group == g
            if sel.sum() >= MIN_TILES // GROUPS:
                strips.append(best_power({k: v[sel] for k, v in hist.items()})[0])
        spread = float(np.std(strips, ddof=1)) / math.sqrt(len(strips)) if len(strips) > 2 else abs(power - 1.0)
        sigma = math.sqrt(spread ** 2 + POWER_FLOOR ** 2) / power
        return ToneCurve("power", decode_lut(power), sigma, residual, int(picked.size), power, tuple(strips),
                         code_range=(black, white))
    modulations = level_modulations(images)  # the level rows as the camera resolved them
    fitted = _fit_with_levels(hist, mixed, group, codes, modulations=modulations)
    if math.isnan(fitted.sigma):
        return dataclasses.replace(fitted, code_range=(black, white))  # a level photo of another pattern
    # each level's relation on the channels that agree, judged under the curve fitted on the three pooled
    # (level_channels: a camera's demosaicing can take a quarter of one channel's light off resolved rows)
    hist, channels = with_level_channels(hist, images, fitted.table, tile, picked, LEVELS, LEVEL_PERIODS)
    if any(len(v["channels"]) < 3 for v in channels.values()):
        fitted = _fit_with_levels(hist, mixed, group, codes, modulations=modulations)
    # the light the black photo's clipped noise added (tone_models.relations: the relations short by it,
    # the toe bent to make it up), read under the curve fitted so far and taken off black in every
    # relation; the curve fitted again (BIAS_ROUNDS times: the bias is read through the curve's toe)
    bias = None
    for _ in range(BIAS_ROUNDS):
        bias = black_bias(images["black"], fitted.table)
        if bias is None or not bias.light > 0:
            bias = None  # nothing to take off
            break
        fitted = _fit_with_levels(hist, mixed, group, codes, modulations=modulations, bias=bias)
    # the exposures from the registration frame (exposure.py), under the curve fitted so far, and
    # the curve fitted again with every photo brought to white's exposure (twice: the exposures
    # read the frame's codes through the curve).  The blend of the two models stays what the
    # photos as taken said: with the exposures undone a phone's S-curve no longer shows as a bend
    # of the halves (bench hard case 6: a bend gain of 0.42 became 0.02, the power was taken, and
    # its dark end put the glare fit off and the own view 0.024 high; the curve refitted with the
    # exposures is 0.006 off)
    photos = {photo_of(k): images[photo_of(k)] for k in hist}
    edge = frame_edge(photos, fitted.table) if EXPOSURE_ROUNDS else None  # where to read them: found once
    exposures, weight = None, fitted.curve_weight
    for _ in range(EXPOSURE_ROUNDS if edge is not None else 0):
        found = measure_exposures(photos, fitted.table, edge)
        if found is None:
            break
        exposures = found
        applied = exposures.applied()
        if all(v == 1.0 for v in applied.values()):
            break  # an exposure that held: the fit stands as it is
        fitted = _fit_with_levels({k: v / applied[photo_of(k)] for k, v in hist.items()}, mixed, group, codes,
                                  weight, modulations, bias)
    return dataclasses.replace(fitted, code_range=(black, white), exposures=exposures, level_channels=channels,
                               black_bias=0.0 if bias is None else bias.light)


def _fit_with_levels(hist, mixed, group, codes, weight: float | None = None,
                     modulations: dict[str, float] | None = None, bias: BlackBias | None = None) -> ToneCurve:
    """The power and the bent curve fitted to the half and level relations of ``hist`` (each photo's
    tile histograms, at one exposure), the main model and its blend weight (:mod:`.tone_choice`;
    ``weight``: the curve's weight given instead); model "power" with a NaN sigma where a level
    photo is too far from its share of white.  ``modulations``: the level rows as the camera
    resolved them (:func:`.level_texture.level_modulations`; None: taken as unresolved); ``bias``: the
    light the black photo's clipping added (:class:`.tone_models.BlackBias`; None: none)."""
    # a level photo of another pattern would bend the fit: each is judged first under the halves' power
    halves_power, halves_residual = best_power({k: v[mixed] for k, v in hist.items()})
    biases = level_biases(hist, srgb_decode_lut() ** halves_power, 0.0 if bias is None else bias.light)
    if max(abs(b) for b in biases) > MAX_LEVEL_BIAS:
        return ToneCurve("power", decode_lut(halves_power), math.nan, halves_residual, int(hist["white"].shape[0]),
                         halves_power, level_residuals=biases, levels=True)
    modulations = modulations or {}
    relations = tone_relations(hist, mixed, bias=bias)
    finest = tone_relations(hist, mixed, PINNING, bias=bias)
    # the power from the half relation alone (the exposure locked): it holds pixel by pixel, where the
    # levels' rows hold only as far as the camera's demosaicing and sharpening leave them (tone_models.relations)
    power = level_power(relations[:1])
    curve = fitted_curve(relations)
    # the light the camera's demosaicing may have taken off the level rows (level_texture): half the
    # curve's change (as a power) when each loses LOSS_BOUND times its modulation, in its uncertainty
    # what the black's clipping light leaves open (tone_models.BIAS_RANGE): half the change of the
    # curve (as a power) between its ends, in its uncertainty
    clipping = (0.5 * abs(log_slope(*(fitted_curve(tone_relations(hist, mixed, bias=bias.scaled(f))) for f in BIAS_RANGE),
                                    codes)) if bias is not None else 0.0)
    texture = (0.5 * abs(log_slope(fitted_curve(tone_relations(hist, mixed, shares=shares_after_loss(modulations), bias=bias)),
                                   curve, codes)) if modulations else 0.0)
    # the curve's weight (tone_choice): by how much a bend of the mid-tones fits the halves better
    # than the power and how far the levels lie from their shares under the halves' power (a
    # camera's S-curve); the curve's freedom otherwise follows the level photos' texture more than
    # the camera.  Between the two, both models are measured and blended
    gain = bend_gain(relations[:1], power)
    level_bias = max(abs(b) for b in biases)
    if weight is None:
        weight = curve_weight(gain, level_bias)
    # a curve that folds back (light falling with the code) is no camera's; a step flat to within
    # MONOTONE_TOLERANCE of the light is noise (hard case 17: code 23 a 1e-4 below code 22)
    weight = weight if np.all(np.diff(curve[codes]) > -MONOTONE_TOLERANCE * curve[codes[:-1]]) else 0.0
    # both models, whatever the weight: the other one's distance says how undecided the photos are
    fitted = {model: _finished(model, table, power, hist, mixed, group, codes, finest,
                               texture if model == "curve" else 0.0, bias, clipping if model == "curve" else 0.0)
              for model, table in (("power", srgb_decode_lut() ** power), ("curve", curve))}
    main, other = ("curve", "power") if weight > 0.5 else ("power", "curve")
    toe = _toe_sigma(fitted[main], fitted[other], codes)
    textured = tuple(modulations.get(name, 0.0) for name in LEVELS) if modulations else ()
    return dataclasses.replace(fitted[main], alternative=dataclasses.replace(fitted[other], toe_sigma=toe,
                                                                             level_modulations=textured),
                               alternative_weight=min(weight, 1.0 - weight), bend_gain=gain, level_bias=level_bias,
                               toe_sigma=toe, level_modulations=textured)


def _toe_sigma(main: ToneCurve, other: ToneCurve, codes) -> float:
    """The 1-sigma of the light of the codes just above black, relative: half the two models' difference
    there, in log (each table scaled to white; ``codes`` from black + 2 up to white), weighted as
    :meth:`ToneCurve.undecided` weighs the other model (``min(1, sigma / other's sigma)``: a model that
    is far less sure of itself than the main one says little about the toe either).

    The relations pin the toe only through small differences: a tail a few codes above black sends a
    few per cent of white's light, so a bias of a few tenths of a per cent of white in the relations
    (a camera's demosaicing and chroma subsampling of the photos' texture; linear photos of the
    bench's cameras broke the half relation by 0.1-0.3 % of white) moves the toe's light by tens of
    per cent.  How far apart the power and the bent curve put it is what the photos leave open
    there; the measurement propagates it as a relative change of the light that fades out by
    ``ratios.TOE_END`` of white's (the power's sigma holds the rest of the curve)."""
    first, last = int(codes[0]), int(codes[-1])
    a = float(main.table[first]) / max(float(main.table[last]), 1e-12)
    b = float(other.table[first]) / max(float(other.table[last]), 1e-12)
    share = _other_share(main, other) if math.isfinite(main.sigma + other.sigma) else 1.0
    return min(MAX_TOE_SIGMA, 0.5 * abs(math.log(max(b, 1e-12) / max(a, 1e-12))) * share)


def _other_share(main: ToneCurve, other: ToneCurve) -> float:
    """How much the ``other`` model's difference from the ``main`` one counts: ``min(1, sigma / other's
    sigma)`` (a model far less sure of itself than the main one says little against it)."""
    return min(1.0, main.sigma / max(other.sigma, 1e-12))


def _finished(model: str, table: np.ndarray, power: float, hist, mixed, group, codes, finest,
              texture: float = 0.0, bias: BlackBias | None = None, clipping: float = 0.0) -> ToneCurve:
    """The :class:`ToneCurve` of ``model`` ("power" of ``power``, or "curve") with ``table`` (256,),
    its residuals and its 1-sigma: the strips' spread, what the relations leave open and ``texture``
    (a power: what the light the level rows may have lost leaves open); ``bias`` as for
    :func:`_fit_with_levels`, ``clipping`` what it leaves open (a power)."""
    residual = half_residual(table, {k: v[mixed] for k, v in hist.items()}, np.ones(2))[0]
    level_residuals = level_biases(hist, table, 0.0 if bias is None else bias.light)
    strips = []
    for g in range(GROUPS):
        sel = group == g
        if sel.sum() >= MIN_TILES // GROUPS and np.count_nonzero(mixed[sel]) > 10:
            part = tone_relations({k: v[sel] for k, v in hist.items()}, mixed[sel], bias=bias)
            fitted = fitted_curve(part) if model == "curve" else srgb_decode_lut() ** level_power(part[:1])
            strips.append(log_slope(fitted, table, codes))
    spread = float(np.std(strips, ddof=1)) / math.sqrt(len(strips)) if len(strips) > 2 else 0.05
    # what the relations leave open: the halves' power against the one the finest level pins too, a
    # bent curve against the one the halves and the finest rows alone give (they differ by the
    # coarser levels' texture bias and by what the power family cannot follow)
    reference = srgb_decode_lut() ** level_power(finest) if model == "power" else fitted_curve(finest)
    spread = math.sqrt(spread ** 2 + log_slope(reference, table, codes) ** 2)
    return ToneCurve(model, table.astype(np.float32),
                     math.sqrt(spread ** 2 + texture ** 2 + clipping ** 2 + POWER_FLOOR ** 2),
                     residual, int(hist["white"].shape[0]), power if model == "power" else math.nan, tuple(strips),
                     level_residuals, levels=True, texture_sigma=texture)
