"""The camera's photometric response, cancelled where it biases the fringe phase.

Frames: working-image pixels (see :mod:`.phase`); phases in cycles in [0, 1).

A camera does not record linear light: a phone applies its own S-shaped tone curve on top of
sRGB, and the fit decodes photos as plain sRGB.  A fringe ``A + B cos(phi)`` then reaches the
demodulation as ``f(A + B cos(phi))``, whose harmonics alias into the 3-step phase: the
measured phase is ``phi + e(phi)`` with ``e`` periodic in ``phi`` (mostly ``sin 3 phi`` from the
second harmonic, ``sin phi`` from exposure drift).  The error depends only on the phase and
on the local fringe level and contrast, which are the same for every coarse green-only group
(the lenses do not reduce a fringe that is long compared with a lens).

So the error is measured where it can be seen and removed where it matters:

* a group with many fringes across the panel is unwrapped along each image line and a smooth
  polynomial taken out; what is left, binned by the measured phase, is ``e`` (a smooth misfit
  averages out over the many fringes, the periodic error does not);
* the error table of ``x1`` (``y1``) also corrects ``x0`` (``y0``), whose single fringe cannot
  measure its own; a single-period phase that is off by a few hundredths of a cycle picks the
  wrong fringe of the next group (the unwrapping fails over whole bands of the panel).
"""

from __future__ import annotations

import math

import numpy as np

TABLE_BINS = 48
LINE_DEGREE = 5


def phase_error_table(cycles: np.ndarray, weight: np.ndarray, along: str,
                      bins: int = TABLE_BINS, degree: int = LINE_DEGREE) -> np.ndarray | None:
    """The periodic phase error ``e`` of a many-fringe map as a function of its measured phase.

    ARGUMENTS
    cycles   float (h, w): measured phase in cycles, [0, 1)
    weight   float (h, w): >= 0, 0 where not to use (outside the panel)
    along    "x": the phase runs along image rows (x-patterns), "y": along columns
    bins     table size over one cycle
    degree   polynomial taken out of each unwrapped line

    RETURNED VALUE
    float64 (bins,): mean error (cycles) at bin centres ``(k + 0.5) / bins``, with zero weighted
    mean (so the correction does not move the group's mean phase); None when too few lines
    could be used.
    """
    c = cycles if along == "x" else cycles.T
    wt = weight if along == "x" else weight.T
    h, w = c.shape
    step = max(1, h // 400)
    sums = np.zeros(bins)
    wsum = np.zeros(bins)
    lines = 0
    for row in range(0, h, step):
        good = wt[row] > 0
        if good.sum() < 0.2 * w:
            continue
        cols = np.flatnonzero(good)
        runs = np.split(cols, np.flatnonzero(np.diff(cols) > 1) + 1)
        cols = max(runs, key=len)
        if cols.size < 0.2 * w:
            continue
        unwrapped = np.unwrap(2 * math.pi * c[row, cols]) / (2 * math.pi)
        t = (cols - cols.mean()) / max(1.0, cols.size)
        coef = np.polynomial.polynomial.polyfit(t, unwrapped, degree, w=np.sqrt(wt[row, cols]))
        residual = unwrapped - np.polynomial.polynomial.polyval(t, coef)
        index = np.minimum((c[row, cols] * bins).astype(np.int64), bins - 1)
        sums += np.bincount(index, weights=wt[row, cols] * residual, minlength=bins)
        wsum += np.bincount(index, weights=wt[row, cols], minlength=bins)
        lines += 1
    if lines < 20 or np.count_nonzero(wsum) < bins:
        return None
    table = sums / wsum
    return table - np.average(table, weights=wsum)


def correct_phase(cycles: np.ndarray, table: np.ndarray | None) -> np.ndarray:
    """``cycles`` (any shape, [0, 1)) minus the error ``table`` interpolated periodically; [0, 1)."""
    if table is None:
        return cycles
    bins = table.size
    centres = (np.arange(bins + 2) - 0.5) / bins
    values = np.concatenate([table[-1:], table, table[:1]])
    return np.mod(cycles - np.interp(cycles, centres, values), 1.0)
