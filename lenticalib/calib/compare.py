"""How far one profile is from another, in views, in the docs/optics.md convention.

Over every subpixel (x_s, y) of the panel, ``d = w_a(x_s, y) - w_b(x_s, y)`` taken as a
circular difference modulo N.  Reported: centring (the circular mean of d), non-uniformity
(RMS and worst |d - mean|), and whether the subpixel orders agree.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..core.errors import InputError
from ..core.profile import PanelProfile


@dataclasses.dataclass(frozen=True)
class ProfileDifference:
    """Statistics of w_a - w_b over all subpixels (views)."""

    centring: float
    rms: float
    worst: float
    order_match: bool
    subpixels: int

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def _w(profile: PanelProfile, xs: np.ndarray, y: float) -> np.ndarray:
    n, d = profile.views, profile.period
    return profile.reference_view + (3.0 * profile.slant * y + profile.offset - xs) * n / d


def compare_profiles(a: PanelProfile, b: PanelProfile) -> ProfileDifference:
    """w_a - w_b over every subpixel; InputError if the panels differ in size or views."""
    if (a.width, a.height, a.views) != (b.width, b.height, b.views):
        raise InputError(f"profiles describe different panels ({a.width}x{a.height}, {a.views} views vs "
                         f"{b.width}x{b.height}, {b.views} views)", source="profiles",
                         hint="compare profiles of the same panel")
    n = a.views
    xs = np.arange(3 * a.width, dtype=np.float64)
    # circular mean first, from a coarse subset, then exact sums over every subpixel
    probe = np.concatenate([_w(a, xs[::97], y) - _w(b, xs[::97], y) for y in range(0, a.height, 37)])
    ang = 2 * math.pi * probe / n
    centre = math.atan2(np.sin(ang).mean(), np.cos(ang).mean()) * n / (2 * math.pi)
    total = total2 = 0.0
    lo, hi = math.inf, -math.inf
    count = 0
    for y in range(a.height):
        d = _w(a, xs, y) - _w(b, xs, y) - centre
        d = (d + n / 2) % n - n / 2
        total += d.sum()
        total2 += np.square(d).sum()
        lo, hi = min(lo, d.min()), max(hi, d.max())
        count += d.size
    mean = total / count
    rms = math.sqrt(max(total2 / count - mean * mean, 0.0))
    worst = max(abs(lo - mean), abs(hi - mean))
    centring = (centre + mean + n / 2) % n - n / 2
    return ProfileDifference(float(centring), float(rms), float(worst), a.subpixel_order == b.subpixel_order, count)
