"""How far one profile is from another, in views, in the docs/optics.md convention.

Over every subpixel (x_s, y) of the panel, ``d = w_a(x_s, y) - w_b(x_s, y)`` taken as a
circular difference modulo N, ``w`` by :func:`lenticalib.core.routing.view_coordinate` (the slot
shifts of a subpixel layout and reversed views included).  Reported: centring (the circular mean
of d), non-uniformity (RMS and worst |d - mean|), and whether the subpixel layouts agree (the
same stripe order, or both cell layouts).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..core.errors import InputError
from ..core.profile import PanelProfile
from ..core.routing import view_coordinate

_ROWS = 64  # rows per chunk


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


def compare_profiles(a: PanelProfile, b: PanelProfile) -> ProfileDifference:
    """w_a - w_b over every subpixel; InputError if the panels differ in size or views.

    ``order_match``: both stripes of the same order, or both with a subpixel layout (how well
    the layouts agree is in the statistics: they route every slot)."""
    if (a.width, a.height, a.views) != (b.width, b.height, b.views):
        raise InputError(f"profiles describe different panels ({a.width}x{a.height}, {a.views} views vs "
                         f"{b.width}x{b.height}, {b.views} views)", source="profiles",
                         hint="compare profiles of the same panel")
    n = a.views
    # circular mean first, from a coarse subset, then exact sums over every subpixel
    rows = np.arange(0, a.height, 37)
    probe = (view_coordinate(a, rows) - view_coordinate(b, rows))[:, ::97].ravel()
    ang = 2 * math.pi * probe / n
    centre = math.atan2(np.sin(ang).mean(), np.cos(ang).mean()) * n / (2 * math.pi)
    total = total2 = 0.0
    lo, hi = math.inf, -math.inf
    count = 0
    for start in range(0, a.height, _ROWS):
        rows = np.arange(start, min(start + _ROWS, a.height))
        d = view_coordinate(a, rows) - view_coordinate(b, rows) - centre
        d = (d + n / 2) % n - n / 2
        total += d.sum()
        total2 += np.square(d).sum()
        lo, hi = min(lo, d.min()), max(hi, d.max())
        count += d.size
    mean = total / count
    rms = math.sqrt(max(total2 / count - mean * mean, 0.0))
    worst = max(abs(lo - mean), abs(hi - mean))
    centring = (centre + mean + n / 2) % n - n / 2
    same = (a.subpixel_order == b.subpixel_order) if a.is_stripe and b.is_stripe else (not a.is_stripe and not b.is_stripe)
    return ProfileDifference(float(centring), float(rms), float(worst), same, count)
