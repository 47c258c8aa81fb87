"""The tone curve's relations, and its two models fitted to them: a power of the sRGB decoding, a bent curve.

Pure functions of a curve ``table`` (float (256,): the linear light of each 8-bit code, units of
sRGB's at code 255), of tile code histograms (sparse (tiles, 256), :mod:`.tiles`) and of the
linear relations built from them (:func:`relations`: (relation, white - black, counts) triples).
``power``: ``D(c) ** p`` from the half relation (:func:`best_power`) or the relations
(:func:`level_power`); ``curve``: ``D(c) (1 + sum_j theta_j B_j(c))``, hats on ``KNOTS``, by linear
least squares with a second-difference penalty (:func:`fitted_curve`); :func:`bend_gain` the
evidence for a bend (``docs/crosstalk.md``).

**The relations** (:func:`relations`, used by :mod:`.tone`) hold in linear light:

    half-0 + half-1 = white + black,   level-1inK - black = (white - black) / K

with ``black`` the panel's black.  A camera clips its sensor's noise at 0, which adds light to
the black photo, all of it where the black is within a few sigma of 0, and next to none to the
level and half photos' lit places: both relations then come out short by that light, the halves'
by all of it and each level's by ``1 - 1/K`` of it (through the bench's true tone curves, hard
case 3: the halves 0.023 of white's light short, the levels 0.023, 0.026 and 0.025; case 13:
0.013, 0.014, 0.014, 0.013).  A curve fitted without it bends its toe to make the light up: hard
case 3's came out 1.5-1.7 times the true light a few codes above black and 10-15 % over it at a
quarter of white, and the own view 0.015 low.  The bias is read on the black photo
(:class:`BlackBias`, :func:`.dark.block_noise`) under the curve fitted so far and taken off black in
every relation; the curve is fitted again (``tone.BIAS_ROUNDS``).  The bias so read was 0.70-1.57
times the truth on the tests' camera (the channels' mean; ``tests/test_crosstalk_dark_blocks.py``):
half the change of the curve between ``BIAS_RANGE``'s ends is in its uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.colour import srgb_decode_lut
from ..patterns.crosstalk_patterns import LEVEL_ROW_PERIODS as LEVEL_PERIODS
from .dark import block_noise
from .level_channels import channel_key

PHOTOS = ("black", "white", "half-0", "half-1")  # the photos the curve is measured on
KNOTS = (0, 2, 4, 6, 8, 10, 12, 14, 16, 20, 24, 32) + tuple(range(48, 256, 16))
SMOOTHING = 1e-3  # weight of the curve's second differences, per relation
POWER_RANGE = (0.6, 1.6)
LEVELS = tuple(f"level-1in{k}" for k in LEVEL_PERIODS)  # the level photos, when the set has them
BINS = 64  # bins of tiles (by white's code) the level relations are averaged over
MIN_BIN = 50  # tiles per bin at least
BIAS_RANGE = (0.6, 1.6)  # the clipping's light over the one read, as far as the tests showed it (dark.block_noise)


def half_residual(table, hist, gains=None):
    """(relative RMS, gains (2,)) of ``a0 half-0 + a1 half-1 = white + black`` under ``table``;
    ``gains`` None: the best (least squares)."""
    means = {k: hist[k] @ table for k in PHOTOS}
    lit = np.maximum(means["white"] - means["black"], 1e-9)
    y = (means["white"] + means["black"]) / lit
    a = np.stack([means["half-0"] / lit, means["half-1"] / lit], axis=1)
    if gains is None:
        gains, *_ = np.linalg.lstsq(a, y, rcond=None)
    return float(np.sqrt(np.mean((a @ gains - y) ** 2))), gains


def best_power(hist) -> tuple[float, float]:
    from scipy.optimize import minimize_scalar

    srgb = srgb_decode_lut()
    grid = np.linspace(*POWER_RANGE, 21)
    values = [half_residual(srgb ** p, hist)[0] for p in grid]
    i = int(np.argmin(values))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    best = minimize_scalar(lambda p: half_residual(srgb ** p, hist)[0], bounds=(lo, hi), method="bounded",
                           options={"xatol": 1e-4})
    return float(best.x), float(best.fun)


def curve_basis() -> np.ndarray:
    """float64 (256, len(KNOTS)): the sRGB decoding times hat functions on ``KNOTS`` (each rises from
    the knot before and falls to the knot after; the last one falls to 0 at code 256)."""
    codes = np.arange(256, dtype=np.float64)
    knots = np.asarray(KNOTS + (256,), np.float64)
    hats = np.stack([np.interp(codes, knots, np.eye(knots.size)[j]) for j in range(len(KNOTS))], axis=1)
    return srgb_decode_lut()[:, None] * hats


def misfit(table, relations) -> float:
    """RMS of the relations under ``table`` (float (256,)), each row over white's light under it,
    weighted by the tiles it stands for."""
    total = sum(float(np.sum(n)) for *_, n in relations)
    return float(np.sqrt(sum(float(np.sum(n * ((r @ table) / np.maximum(lit @ table, 1e-12)) ** 2))
                             for r, lit, n in relations) / total))


def level_power(relations) -> float:
    """The power ``p`` of ``D ** p`` that fits the relations best (the exposure locked)."""
    from scipy.optimize import minimize_scalar

    srgb = srgb_decode_lut()
    best = minimize_scalar(lambda p: misfit(srgb ** p, relations), bounds=POWER_RANGE, method="bounded",
                           options={"xatol": 1e-4})
    return float(best.x)


def bent(power: float, bend: float) -> np.ndarray:
    """float64 (256,): ``D ** power x exp(bend v (1 - v))``, ``v`` the code over 255: the power with one
    smooth bend of the mid-tones (the test for a curve that is not a power)."""
    v = np.arange(256) / 255.0
    return srgb_decode_lut() ** power * np.exp(bend * v * (1.0 - v))


def bend_gain(relations, power: float) -> float:
    """How much better (relative RMS of the relations, 0..1) the power fits with a bend of the mid-tones."""
    from scipy.optimize import minimize

    plain = misfit(bent(power, 0.0), relations)
    best = minimize(lambda x: misfit(bent(x[0], x[1]), relations), [power, 0.0], method="Nelder-Mead",
                    options={"xatol": 1e-4, "fatol": 1e-9})
    return 1.0 - float(best.fun) / max(plain, 1e-12)


def fitted_curve(relations) -> np.ndarray:
    """float64 (256,): the curve model fitted to the relations (linear least squares, smoothed)."""
    srgb, basis = srgb_decode_lut(), curve_basis()
    weights = [np.sqrt(n) / np.maximum(lit @ srgb, 1e-6) for _, lit, n in relations]
    a = np.vstack([(r @ basis) * w[:, None] for (r, _, _), w in zip(relations, weights)])
    b = -np.concatenate([(r @ srgb) * w for (r, _, _), w in zip(relations, weights)])
    n, rows = basis.shape[1], sum(float(np.sum(c)) for *_, c in relations)
    penalty = np.sqrt(SMOOTHING * rows) * np.diff(np.eye(n), 2, axis=0)
    ridge = np.sqrt(1e-6 * rows) * np.eye(n)
    theta, *_ = np.linalg.lstsq(np.vstack([a, penalty, ridge]), np.concatenate([b, np.zeros(2 * n - 2)]),
                                rcond=None)
    return srgb + basis @ theta


def log_slope(table, reference, codes) -> float:
    """The power ``d`` that best maps ``reference`` onto ``table`` over ``codes`` (both scaled to 1 at the
    last code): ``log(table / reference) ~ d log(reference)``."""
    x = np.log(reference[codes] / reference[codes[-1]])
    y = np.log(np.maximum(table[codes], 1e-12) / table[codes[-1]]) - x
    return float(np.dot(x, y) / max(np.dot(x, x), 1e-12))


@dataclass(frozen=True)
class BlackBias:
    """The light the black photo's clipped noise added to it: ``light`` (the tone curve's units, the
    channels' mean) under ``table`` (float (256,), the curve it was read under)."""

    light: float
    table: np.ndarray

    def scaled(self, factor: float) -> "BlackBias":
        """The same bias ``factor`` times as large (the curve's uncertainty: ``BIAS_RANGE``)."""
        return BlackBias(self.light * factor, self.table)


def black_bias(black: np.ndarray, table: np.ndarray) -> BlackBias | None:
    """The clipping's light in the uint8 RGB black photo ``black`` (h, w, 3) under the curve ``table``
    (:func:`.dark.block_noise`: the channels' mean of ``mean - light``); None where its
    blocks do not tell."""
    table = np.asarray(table, np.float64)
    noise = block_noise(table.astype(np.float32)[black])  # 12 bytes a pixel, as the measurement's own channels
    if noise is None:
        return None
    return BlackBias(float(max(np.mean(noise.bias()), 0.0)), table)


def _lifted(relation, lit_rows, factor: float, bias: BlackBias | None):
    """``relation`` (sparse (rows, 256)) with ``factor`` times ``bias``'s light added to each row: the
    rows ``lit_rows`` (white - black) scaled so that each carries that light under the bias's table
    (the relations stay linear in the curve; the curve fitted again, the share is read again);
    ``relation`` itself without a bias."""
    from scipy.sparse import diags

    if bias is None or not bias.light > 0:
        return relation
    light = np.asarray(lit_rows @ bias.table).ravel()
    return relation + factor * (diags(bias.light / np.maximum(light, 1e-12)) @ lit_rows)


def relations(hist, mixed, levels=LEVELS, shares=None, bias: "BlackBias | None" = None) -> list:
    """The linear relations of the curve's 256 values, as (sparse (rows, 256) relation, sparse (rows,
    256) white - black, counts (rows,)) triples, each row the mean over ``count`` tiles: the half
    relation tile by tile on the ``mixed`` tiles, and the ``levels``' on ``BINS`` bins of tiles of
    similar white code (their means), each level's light ``shares[name]`` (default 1) of its ``1/K``
    of white's (the light the camera's demosaicing takes off resolved rows: :mod:`.level_texture`);
    a level with :func:`.level_channels.channel_key` histograms in ``hist`` is related over those
    channels of its own, white's and black's photos; black's light less ``bias`` (the light its
    clipped noise added: :class:`BlackBias`).

    The half relation holds pixel by pixel.  A level's holds only over whole periods of its rows
    and only where the camera does not resolve them: a tile holds a lit row more or less than its
    share (a curve fitted tile by tile bends to shrink that texture instead of following the
    camera), which the hundreds of tiles of a bin, at every phase of the rows, average out; and a
    camera's demosaicing is not linear on resolved rows (OpenCV's edge-aware one left 1-in-8 rows
    6-7 % short of 1/8 of white in linear light, 1-in-4 rows 3 %, 1-in-2 rows 0.8 %, on a sharp
    sheet at 400 mm; 1-in-2 rows 2.5 % at 500 mm): the power rests on the halves, the finest rows
    (``PINNING``) only state how far off it could be, and all levels give a bent curve its shape (a
    phone's S-curve moves the levels by tens of per cent, far more than their texture)."""
    from scipy.sparse import csr_matrix

    lit = hist["white"] - hist["black"]
    relations = [(_lifted((hist["half-0"] + hist["half-1"] - hist["white"] - hist["black"])[mixed], lit[mixed],
                          1.0, bias), lit[mixed],
                  np.ones(int(np.count_nonzero(mixed))))]
    order = np.argsort(hist["white"] @ np.arange(256), kind="stable")
    bins = np.array_split(order, min(BINS, max(1, order.size // MIN_BIN)))
    index = np.concatenate([np.full(b.size, i) for i, b in enumerate(bins)])
    counts = np.array([b.size for b in bins], np.float64)
    mean = csr_matrix((1.0 / counts[index], (index, np.concatenate(bins))), shape=(len(bins), order.size))
    lit_bins = mean @ lit
    for name in levels:
        k = LEVEL_PERIODS[LEVELS.index(name)]
        share = 1.0 if shares is None else shares.get(name, 1.0)
        if channel_key(name, name) in hist:  # the channels that agree (level_channels)
            level, white, dark = (hist[channel_key(p, name)] for p in (name, "white", "black"))
            lit_level = mean @ (white - dark)
            relations.append((_lifted(mean @ (level - dark) - lit_level * (share / k), lit_level,
                                      1.0 - share / k, bias), lit_level, counts))
        else:
            relations.append((_lifted(mean @ (hist[name] - hist["black"]) - lit_bins * (share / k), lit_bins,
                                      1.0 - share / k, bias), lit_bins, counts))
    return relations


def level_biases(hist, table, bias: float = 0.0) -> tuple[float, ...]:
    """Each level photo's light over its share of white's (above black, less ``bias``: its clipping's
    light), less 1, under ``table``: sums over all tiles (a tile's own ratio is off by a lit row
    where the camera resolves them)."""
    lifted = bias * hist["white"].shape[0]
    lit = max(float(np.sum((hist["white"] - hist["black"]) @ table)) + lifted, 1e-9)
    return tuple(float(k * (np.sum((hist[name] - hist["black"]) @ table) + lifted) / lit - 1.0)
                 for name, k in zip(LEVELS, LEVEL_PERIODS))
