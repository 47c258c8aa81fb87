"""The two tone models fitted to the photos' relations: a power of the sRGB decoding, and a bent curve.

Pure functions of a curve ``table`` (float (256,): the linear light of each 8-bit code, units of
sRGB's at code 255), of tile code histograms (sparse (tiles, 256), :mod:`.tiles`) and of the
linear relations :mod:`.tone_relations` builds from them (``relations``: (relation, white - black, counts)
triples).  ``power``: ``D(c) ** p`` from the half relation (:func:`best_power`) or the relations
(:func:`level_power`); ``curve``: ``D(c) (1 + sum_j theta_j B_j(c))``, hats on ``KNOTS``, by linear
least squares with a second-difference penalty (:func:`fitted_curve`); :func:`bend_gain` the
evidence for a bend (``docs/crosstalk.md``).
"""

from __future__ import annotations

import numpy as np

from ...core.colour import srgb_decode_lut

PHOTOS = ("black", "white", "half-0", "half-1")  # the photos the curve is measured on
KNOTS = (0, 2, 4, 6, 8, 10, 12, 14, 16, 20, 24, 32) + tuple(range(48, 256, 16))
SMOOTHING = 1e-3  # weight of the curve's second differences, per relation
POWER_RANGE = (0.6, 1.6)


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
