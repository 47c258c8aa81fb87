"""How far one profile is from another, in views, in the docs/optics.md convention.

Over every subpixel (x_s, y) of the panel, ``d = w_a(x_s, y) - w_b(x_s, y)`` taken as a
circular difference modulo N.  Reported: centring (the circular mean of d), non-uniformity
(RMS and worst |d - mean|), and whether the subpixel orders agree.

When either profile has a subpixel layout (cells), the subpixels are compared colour by colour:
``d`` is the difference of the two ``w`` of the same channel of the same pixel, each at its slot's
continuous index (slot shift included, :func:`lenticalib.core.routing.view_coordinate`); two
stripe profiles are compared position by position as above.

AGREEMENT.  ``same_view`` is the fraction of those subpixels on which both profiles show the same
view (:func:`lenticalib.core.routing.view_map`, what every encoder shows).  Two descriptions of one
panel agree when it is at least :data:`AGREE_FRACTION`: a fit is off by a few hundredths of a
view, which moves a few percent of the subpixels across a view boundary, whereas reading a gen3
calibration with another ``CellPatternMode`` numbering moves a quarter to a half of them
(docs/looking-glass.md).  :func:`load_pair` also reads a Looking Glass visual.json, routed
as Looking Glass's rule routes it (:mod:`lenticalib.core.looking_glass.convert`), so that a unit's calibration can
be held against the layout a camera measured (a fit with the cell photos).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

import os

from ...core.files.documents import MAX_PROFILE_BYTES, read_json_file
from ...core.errors import InputError, ProfileError
from ...core.looking_glass.convert import profile_from_visual
from ...core.profile import PanelProfile, profile_from_dict
from ...core.routing import view_coordinate, view_map

AGREE_FRACTION = 0.9  # same_view at or above which two descriptions of one panel agree
_ROWS_PER_CHUNK = 256


@dataclasses.dataclass(frozen=True)
class ProfileDifference:
    """Statistics of w_a - w_b over all subpixels (views)."""

    centring: float
    rms: float
    worst: float
    order_match: bool
    subpixels: int
    same_view: float = 1.0  # fraction of the subpixels on which both show the same view

    @property
    def agree(self) -> bool:
        """Whether the two describe the panel alike (``same_view >= AGREE_FRACTION``)."""
        return self.same_view >= AGREE_FRACTION

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
    return ProfileDifference(float(centring), float(rms), float(worst), order_match, count,
                             same_view_fraction(a, b, by_colour))


def same_view_fraction(a: PanelProfile, b: PanelProfile, by_colour: bool = True) -> float:
    """Fraction of the subpixels on which ``a`` and ``b`` (same panel) show the same view.

    ``by_colour``: subpixels are matched by pixel and channel (R, G, B), else by position
    ``3 x + slot``.  Views by :func:`lenticalib.core.routing.view_map`; a dark subpixel matches
    only a dark one."""
    same = total = 0
    for start in range(0, a.height, _ROWS_PER_CHUNK):
        rows = slice(start, start + _ROWS_PER_CHUNK)
        va, vb = view_map(a, rows), view_map(b, rows)
        if by_colour:
            va = va.reshape(va.shape[0], a.width, 3)[:, :, list(a.rho)]
            vb = vb.reshape(vb.shape[0], b.width, 3)[:, :, list(b.rho)]
        same += int((va == vb).sum())
        total += va.size
    return same / total


def _is_visual_json(data) -> bool:
    return isinstance(data, dict) and "screenW" in data and "pitch" in data


def load_pair(path_a: str | os.PathLike, path_b: str | os.PathLike) -> tuple[PanelProfile, PanelProfile]:
    """Profiles A and B to compare; either may be a Looking Glass visual.json instead of a profile.

    A visual.json (an object with ``screenW`` and ``pitch``) does not record its number of views:
    it is imported (:func:`lenticalib.core.looking_glass.convert.profile_from_visual`) with the other profile's.
    ProfileError naming the file when both are visual.json files or either is invalid."""
    paths = (path_a, path_b)
    raw = [read_json_file(path, "profile", f"check the path given as {name}", ProfileError, MAX_PROFILE_BYTES)
           for path, name in zip(paths, "AB")]
    visual = [_is_visual_json(data) for data in raw]
    if all(visual):
        raise ProfileError("both A and B are Looking Glass visual.json files, which do not record their number of "
                           "views", source=str(path_b), hint="compare a visual.json with a profile of the same panel, such as "
                                                            "the one a fit with the cell photos wrote")
    if visual[0]:
        b = profile_from_dict(raw[1], source=str(path_b))
        return profile_from_visual(raw[0], b.views, source=str(path_a), path=path_a), b
    a = profile_from_dict(raw[0], source=str(path_a))
    if visual[1]:
        return a, profile_from_visual(raw[1], a.views, source=str(path_b), path=path_b)
    b = profile_from_dict(raw[1], source=str(path_b))
    return a, b
