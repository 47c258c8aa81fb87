"""How much of a blurred point's light falls inside an aperture: the Gaussian CDF and its integral, from a table.

For the ray kernel (:mod:`.render`, numba): a seen point blurred by a Gaussian (sigma ``s``,
subpixels) whose centre sweeps a stretch ``ext`` (subpixels) lights an aperture ``[lo, lo + width)``
by :func:`coverage`.  ``PHI_TABLE`` is float64 (2, L) on ``[-PHI_RANGE, PHI_RANGE]`` sigma at
``PHI_SCALE`` entries per sigma: row 0 Phi(t), row 1 its integral.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

PHI_RANGE = 7.0  # the Gaussian CDF table spans [-7, 7] sigma
PHI_SCALE = 512.0  # table entries per sigma
EXACT_EXTENT = 0.02  # below this share of the blur's sigma a seen stretch's X-extent is a point


def phi_table() -> np.ndarray:
    """float64 (2, L) on t in [-7, 7] sigma: row 0 the Gaussian CDF Phi(t), row 1 its integral
    ``G(t) = t Phi(t) + phi(t)`` (``G' = Phi``)."""
    t = np.arange(-PHI_RANGE, PHI_RANGE + 2.0 / PHI_SCALE, 1.0 / PHI_SCALE)
    from scipy.special import ndtr

    cdf = ndtr(t)
    return np.ascontiguousarray(np.stack([cdf, t * cdf + np.exp(-0.5 * t * t) / math.sqrt(2.0 * math.pi)]))


PHI_TABLE = phi_table()


@njit(cache=True, inline="always")
def from_table(t, table, row):
    """Row ``row`` of :func:`phi_table` at ``t``, linear between entries; beyond the table's
    ends, the row's limits (0 left; 1 for Phi and ``t`` for its integral right)."""
    f = (t + PHI_RANGE) * PHI_SCALE
    if f <= 0.0:
        return 0.0
    if f >= table.shape[1] - 1:
        return 1.0 if row == 0 else t
    i = int(f)
    a = f - i
    return table[row, i] + a * (table[row, i + 1] - table[row, i])


@njit(cache=True, inline="always")
def phi(t, table):
    """Phi(t), the Gaussian CDF."""
    return from_table(t, table, 0)


@njit(cache=True, inline="always")
def phi_integral(t, table):
    """G(t) = integral of Phi up to t (t Phi(t) + phi(t)): 0 far left, t far right."""
    return from_table(t, table, 1)


@njit(cache=True, inline="always")
def coverage(lo, width, ext, s, table):
    """Share of a Gaussian's light (sigma ``s``) inside ``[lo, lo + width)`` (subpixels, relative
    to the Gaussian's centre), its centre averaged uniformly over ``[-ext/2, ext/2]``."""
    inv_s = 1.0 / s
    if ext < EXACT_EXTENT * s:
        return phi((lo + width) * inv_s, table) - phi(lo * inv_s, table)
    h = 0.5 * ext
    hi = lo + width
    return (phi_integral((hi + h) * inv_s, table) - phi_integral((hi - h) * inv_s, table)
            - phi_integral((lo + h) * inv_s, table) + phi_integral((lo - h) * inv_s, table)) * s / ext
