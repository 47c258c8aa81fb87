"""Which tone model linearises camera JPEGs: the power, the bent curve, or a blend of the two.

:mod:`.tone` fits two models to the half and level photos: a power on sRGB (from the half relation
alone, which holds pixel by pixel) and a bent curve (which the level rows shape as well).  The
curve follows a phone's S-curve, which the power cannot; but on an ordinary camera its freedom
follows the level photos' texture and the demosaicing of resolved rows instead (measured on the
bench: the curve 0.018-0.023 off where the power is 0.004-0.007 off).  Two signs of an S-curve:

- ``bend_gain``: how much better (relative RMS) a smooth bend of the mid-tones fits the half
  relation than the power (the bench's ordinary cameras 0.000-0.039, but 0.118 for one far off
  axis, where the curve is right too; its phones 0.003-0.42);
- ``level_bias``: how far the level photos lie from their shares of white under the halves'
  power (demosaicing leaves resolved rows up to 9 % short on the bench's ordinary cameras; a
  phone's S-curve of strength 0.99 moved them by 15 %, where the bend gain was only 0.029).

Neither alone separates the cameras, and a hard switch on one of them flips the result on a
camera near the switch (a bench phone at a bend gain of 0.0998 against a switch at 0.1: 0.0068
off with the power, 0.0021 with the curve).  So the weight of the curve rises linearly from 0 to 1 between
a lower and an upper value of each sign, the larger of the two weights taken; in between, both
models are measured and the results blended (``measure``), the spread between them part of
the uncertainty.
"""

from __future__ import annotations

import numpy as np

GAIN_RANGE = (0.04, 0.07)  # bend gain: curve weight 0 below, 1 above
LEVEL_BIAS_RANGE = (0.10, 0.14)  # level bias under the halves' power: the same


def curve_weight(gain: float, level_bias: float) -> float:
    """The curve's weight, 0..1, from the two signs of a bent camera curve (module docstring)."""

    def ramp(value: float, bounds: tuple[float, float]) -> float:
        lo, hi = bounds
        return float(np.clip((value - lo) / (hi - lo), 0.0, 1.0)) if np.isfinite(value) else 0.0

    return max(ramp(gain, GAIN_RANGE), ramp(level_bias, LEVEL_BIAS_RANGE))


def blended(main: np.ndarray, other: np.ndarray, weight: float) -> np.ndarray:
    """``main`` with ``other`` blended in at ``weight`` (0..1), elementwise."""
    return (1.0 - weight) * np.asarray(main) + weight * np.asarray(other)


def blended_sigma(main, main_sigma, other, other_sigma, weight: float, undecided: float = 0.0) -> np.ndarray:
    """The 1-sigma of :func:`blended`: the two models as a mixture (each's variance at its weight,
    and the spread between their values), and ``undecided`` (0..1, :meth:`.tone.ToneCurve.undecided`)
    times half their difference."""
    main, other = np.asarray(main), np.asarray(other)
    return np.sqrt((1.0 - weight) * np.asarray(main_sigma) ** 2 + weight * np.asarray(other_sigma) ** 2
                   + weight * (1.0 - weight) * (main - other) ** 2 + (0.5 * undecided * (main - other)) ** 2)
