"""Exact rational evaluation of the LentiAvatar routing rule (closed form), for golden comparisons."""

from fractions import Fraction

import numpy as np

NEAR = Fraction(1, 10**12)


def exact_view_map(profile):
    """Exact routing and where fixed point may differ.

    RETURNED VALUE ``(views, near)``: ``views`` (H, 3W) int16, floor(w) mod N where
    frac(w) < N/period else -1, in exact arithmetic; ``near`` bool (H, 3W), True where w lies
    less than 1e-12 views *below* a boundary without touching it (beyond 64-bit fixed point).
    """
    n = profile.views
    p = Fraction(profile.period)
    ratio = Fraction(n) / p
    views = np.empty((profile.height, profile.subpixels_per_row), dtype=np.int16)
    near = np.zeros(views.shape, dtype=bool)
    for y in range(profile.height):
        row0 = Fraction(profile.reference_view) + (3 * Fraction(profile.slant) * y + Fraction(profile.offset)) * ratio
        for xs in range(profile.subpixels_per_row):
            w = row0 - xs * ratio
            j = w.numerator // w.denominator
            frac = w - j
            views[y, xs] = j % n if frac < ratio else -1
            near[y, xs] = (0 < 1 - frac < NEAR) or (ratio < 1 and 0 < ratio - frac < NEAR)
    return views, near
