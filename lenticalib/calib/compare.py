"""How far one profile is from another, in views, in the docs/optics.md convention.

Over every subpixel (x_s, y) of the panel, ``d = w_a(x_s, y) - w_b(x_s, y)`` taken as a
circular difference modulo N.  Reported: centring (the circular mean of d), non-uniformity
(RMS and worst |d - mean|), and whether the subpixel orders agree.

When either profile has a subpixel layout (cells), the subpixels are compared colour by colour:
``d`` is the difference of the two ``w`` of the same channel of the same pixel, each at its slot's
continuous index (slot shift included, :func:`lenticalib.core.routing.view_coordinate`); two
stripe profiles are compared position by position as above.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..core.errors import InputError
from ..core.profile import PanelProfile
from ..core.routing import view_coordinate


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


def _w(profile: PanelProfile, xs: np.ndarray, y: float, by_colour: bool) -> np.ndarray:
    """``w`` of row ``y`` at the slots ``xs`` (integer indices); ``by_colour``: ``xs`` are output
    values ``3 x + c`` and each is taken at the slot that holds channel ``c``."""
    if by_colour:
        xs = 3 * (xs // 3) + np.asarray(profile.rho)[xs % 3]
        return view_coordinate(profile, np.array([y]))[0][xs]
    n, d = profile.views, profile.period
    w = profile.reference_view + (3.0 * profile.slant * y + profile.offset - xs) * n / d
    return profile.views - w if profile.views_reversed else w


def compare_profiles(a: PanelProfile, b: PanelProfile) -> ProfileDifference:
    """w_a - w_b over every subpixel; InputError if the panels differ in size or views."""
    if (a.width, a.height, a.views) != (b.width, b.height, b.views):
        raise InputError(f"profiles describe different panels ({a.width}x{a.height}, {a.views} views vs "
                         f"{b.width}x{b.height}, {b.views} views)", source="profiles",
                         hint="compare profiles of the same panel")
    n = a.views
    by_colour = not (a.is_stripe and b.is_stripe)
    xs = np.arange(3 * a.width, dtype=np.int64) if by_colour else np.arange(3 * a.width, dtype=np.float64)
    # circular mean first, from a coarse subset, then exact sums over every subpixel
    probe = np.concatenate([_w(a, xs[::97], y, by_colour) - _w(b, xs[::97], y, by_colour)
                            for y in range(0, a.height, 37)])
    ang = 2 * math.pi * probe / n
    centre = math.atan2(np.sin(ang).mean(), np.cos(ang).mean()) * n / (2 * math.pi)
    total = total2 = 0.0
    lo, hi = math.inf, -math.inf
    count = 0
    for y in range(a.height):
        d = _w(a, xs, y, by_colour) - _w(b, xs, y, by_colour) - centre
        d = (d + n / 2) % n - n / 2
        total += d.sum()
        total2 += np.square(d).sum()
        lo, hi = min(lo, d.min()), max(hi, d.max())
        count += d.size
    mean = total / count
    rms = math.sqrt(max(total2 / count - mean * mean, 0.0))
    worst = max(abs(lo - mean), abs(hi - mean))
    centring = (centre + mean + n / 2) % n - n / 2
    order_match = a.subpixel_order == b.subpixel_order and a.is_stripe == b.is_stripe
    return ProfileDifference(float(centring), float(rms), float(worst), order_match, count)
