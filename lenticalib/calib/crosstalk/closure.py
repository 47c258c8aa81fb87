"""The light's closure: the band photos' light adds up to white's; how far it is from that.

Frames and units: working pixels; view offsets ``t`` in views; light as a share of white's at the
same pixel (:mod:`.ratios`).

The ``N`` one-view bands centred ``t0, t0 + 1, ..., t0 + N - 1`` light every subpixel of the panel
exactly once, so in linear light their photos (less black) add up to white's at every camera
pixel, whatever the lens sheet, the blur, the scatter or the glare do (all linear in the light).
For the view cone ``h`` (the share of white's light from a one-view band ``t`` views away) that is

    integral of h(t) dt over one period  =  1                           (the closure)

and the sweep puts every offset everywhere, so the cone binned over the measurement's centre
region with each band photo divided by its exposure over white's (read on the registration frame,
:func:`band_exposures`; 1 where it cannot be read, with ``UNKNOWN_EXPOSURE_SIGMA``) integrates to
1 (:func:`cone_integral`).  From linear photos of the bench it does, within 0.011 (a close camera's
band photo whose light is not its frame's exposure left out: :func:`consistent_photos`).

From camera JPEGs it does not: 0.992-1.026 on the standard bench, 0.974 under a phone's S-curve
(hard case 13).  The row's normalisation hands the missing light to
every view in proportion, so a tone curve whose toe reads the far views' light short (hard case
13: the curve's slope 5-16 % short a few codes above black) puts the own view high.  The toe that
would close the light (:func:`close_toe`, a toe of :func:`.ratios.toe_lifted`; the integral is
linear in it: two evaluations) is not applied: the same shortfall comes from a power of the curve
(standard case 5: 1.026, where the halves and levels disagree on the power, and the own view is
right without a toe) or from the JPEG's processing of the bright, textured views; applied, it put
standard case 5's own view 0.014 high and hard cases 21 and 22 further off; shared between the
power and the toe by their uncertainties, hard case 20 0.018 off.  The row measured with the
closing toe, less its own 1-sigma (:meth:`Closure.pinned_toe`), is what the light's shortfall
could mean: its whole change is carried in the uncertainty (``diagnostics.sigma_closure``) and
the integral is reported (``photometry.closure``).

**Not the clipping's sigma.**  The closure was used to pick the scale of a JPEG's clipping sigma
(read too small on its pixels) between 1 and 2.5: a weak pin (1-sigma of the integral 0.05, the
optics and the tone curve move it as much: hard case 20's integral rose from 0.988 at the
sigma read to 1.128 at 2.5 times it), which took the prior's middle.  The sigma is now read from
the black photo's coarse detail, which a JPEG keeps (:func:`.dark.block_noise`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np

from ...core.colour import srgb_decode
from ...core.files.imageio import read_image
from . import cone
from .exposure import CODE_RANGE, Exposures, measure_each
from .tone import decode_lut

TRIAL_TOE = 0.2  # the second evaluation of the integral (it is linear in the toe)
MAX_TOE = 0.9  # |toe| at most (the light at black times 1 +- 0.9: still positive)
PHOTO_OUTLIER = 0.1  # a band photo whose fitted exposure is further than this from the frame's: left out
MIN_SLOPE = 0.005  # d integral / d toe below which the dark light is too little to pin the toe
UNKNOWN_EXPOSURE_SIGMA = 0.02  # 1-sigma of E where the frame cannot be read (a locked exposure: within 2 %)
EXPOSURE_FLOOR = 0.003  # 1-sigma of the frame's exposures' mean that their sectors' spread does not show
STRIPS = 8  # strips of rows of the panel for the integral's spread


@dataclasses.dataclass(frozen=True)
class Closure:
    """How far the band photos' light is from adding up to white's (:func:`close_toe`).

    ``integral``: the cone integral (the centre region's in the measurement; views x share of
    white; 1 where the light adds up), with its 1-sigma ``integral_sigma`` (strips) and that of the 1 it must reach,
    ``expected_sigma`` (the exposures); ``slope``: its change per unit toe; ``toe``: the toe
    (:func:`.ratios.toe_lifted`) that would close it, ``toe_sigma`` that toe's 1-sigma; ``pinned``:
    False where the cone holds too little dark light for a toe to close anything;
    ``exposures_read``: whether the frame gave the band photos' exposures; ``photos``: the band
    photos the integral was taken over; ``clamped``: the toe was larger than ``MAX_TOE``, cut there."""

    integral: float
    integral_sigma: float
    expected_sigma: float
    slope: float
    toe: float = 0.0
    toe_sigma: float = 0.0
    pinned: bool = False
    exposures_read: bool = False
    photos: int = 0
    clamped: bool = False

    def pinned_toe(self) -> float:
        """The part of the closing toe beyond its own 1-sigma (0 where the closure does not pin
        one): what the shortfall says about the toe beyond what unknown exposures and the
        integral's spread could make of it (hard case 3: a crushed bezel, exposures taken as
        locked to 2 %, a closing toe of -0.9 +- 0.63 and a row change of 0.025 on the own view
        whose error was 0.002)."""
        if not self.pinned:
            return 0.0
        return math.copysign(max(0.0, abs(self.toe) - self.toe_sigma), self.toe)

    def to_dict(self) -> dict:
        return {"integral": round(self.integral, 5), "integral_sigma": round(self.integral_sigma, 5),
                "expected": 1.0, "expected_sigma": round(self.expected_sigma, 5),
                "exposures": "read on the registration frame" if self.exposures_read else "taken as locked",
                "band_photos_used": self.photos, "slope_per_toe": round(self.slope, 5),
                "closing_toe": round(self.toe, 4), "closing_toe_sigma": round(self.toe_sigma, 4),
                "pinned_toe": round(self.pinned_toe(), 4),
                "pinned": bool(self.pinned), "clamped": bool(self.clamped)}


def band_exposures(capture, pattern_set, table: np.ndarray | None) -> Exposures | None:
    """The black and band photos' exposures over white's, read on the registration frame
    (:func:`.exposure.measure_each`) of camera photos: 8-bit ones through ``table`` (float (256,),
    the tone curve's light of each code; None: sRGB decoding), 16-bit ones through sRGB decoding;
    None where the photos are neither or the frame cannot be read on every band photo."""
    names = ["black", "white"] + [p.name for p in pattern_set.bands]
    images = {}
    for name in names:
        raw = read_image(capture.photo(name), camera_orientation=True)
        if raw.dtype not in (np.uint8, np.uint16) or raw.ndim != 3 or raw.shape[2] < 3:
            return None
        images[name] = raw[:, :, :3]
    if len({(v.shape, v.dtype) for v in images.values()}) > 1:
        return None
    if images["white"].dtype == np.uint8:
        table = decode_lut() if table is None else np.asarray(table, np.float64)
        return measure_each(images, table, names[2:])
    decoded = srgb_decode(np.arange(65536) / 65535.0)
    return measure_each(images, decoded, names[2:], (CODE_RANGE[0] * 257, CODE_RANGE[1] * 257))


def frame_exposures(exposures: Exposures | None, bands) -> tuple[np.ndarray, float, bool]:
    """(each band photo's exposure over white's (K,), the 1-sigma of their mean, whether read): the
    exposures the closure's integral is taken with (None: taken as locked, all 1, with
    ``UNKNOWN_EXPOSURE_SIGMA``)."""
    if exposures is None:
        return np.ones(len(bands)), UNKNOWN_EXPOSURE_SIGMA, False
    each = np.array([exposures.relative[p.name] for p in bands])
    sigma = np.array([exposures.sigma[p.name] for p in bands])
    return each, math.hypot(float(np.sqrt(np.mean(sigma ** 2))) / math.sqrt(each.size), EXPOSURE_FLOOR), True


def cone_integral(fit: cone.ConeFit, ratios: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                  shifts: np.ndarray) -> float:
    """The integral over one period of the cone the samples give with the fit's delta and
    exposures (views x share of white)."""
    _, profile, _ = cone.profile_for(fit, ratios, rows, cols, shifts)
    return float(np.mean(profile) * fit.views)


def integral_spread(fit: cone.ConeFit, ratios: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                    shifts: np.ndarray) -> float:
    """1-sigma of :func:`cone_integral` from the spread of its value over ``STRIPS`` strips of rows."""
    edges = np.quantile(rows, np.linspace(0.0, 1.0, STRIPS + 1))
    strip = np.clip(np.searchsorted(edges, rows, side="right") - 1, 0, STRIPS - 1)
    values = [cone_integral(fit, ratios[strip == s], rows[strip == s], cols[strip == s], shifts)
              for s in range(STRIPS) if np.count_nonzero(strip == s) >= 200]
    return float(np.std(values, ddof=1)) / math.sqrt(len(values)) if len(values) > 2 else 0.0


def consistent_photos(gains: np.ndarray, exposures: np.ndarray) -> np.ndarray:
    """bool (K,): the band photos whose fitted exposure ``gains`` agrees with the frame's
    ``exposures`` to ``PHOTO_OUTLIER`` (relative to the median agreement); all where fewer than
    half would be left.  A photo whose light is not its exposure's (bench case 1, a close camera:
    band-00 at 0.63 of the others, its frame at 1.004) would take its own share of the integral
    with it (3 % of it there)."""
    agreement = np.asarray(gains, np.float64) / np.asarray(exposures, np.float64)
    keep = np.abs(agreement / np.median(agreement) - 1.0) <= PHOTO_OUTLIER
    return keep if keep.sum() * 2 >= keep.size else np.ones(keep.size, bool)


def _usable(fit: cone.ConeFit, shifts: np.ndarray, exposures: Exposures | None, bands):
    """(fit with the frame's exposures, shifts, kept photos (K,) bool, the exposures' 1-sigma, read):
    the band photos the integral is taken over (:func:`consistent_photos`) and their exposures."""
    gains, expected_sigma, read = frame_exposures(exposures, bands)
    keep = consistent_photos(fit.gains, gains)
    return dataclasses.replace(fit, gains=gains[keep]), np.asarray(shifts)[keep], keep, expected_sigma, read


def close_toe(ratios_with_toe: Callable[[float], np.ndarray], fit: cone.ConeFit, rows: np.ndarray,
              cols: np.ndarray, shifts: np.ndarray, exposures: Exposures | None, bands) -> Closure:
    """The cone integral of the working pixels ``rows``, ``cols`` and the toe that would make it 1.

    ``ratios_with_toe(toe)``: float (n, K) band ratios at the working pixels ``rows``, ``cols``
    with the photos' light above black lifted by ``toe`` (:func:`.ratios.toe_lifted`); ``fit``:
    a cone fit of those pixels on the ratios with toe 0 (its delta is kept; the band photos'
    exposures are the frame's, :func:`frame_exposures`, over the photos that agree with them,
    :func:`consistent_photos`).  The integral is linear in the toe: two evaluations."""
    fit, shifts, keep, expected_sigma, read = _usable(fit, shifts, exposures, bands)
    base = ratios_with_toe(0.0)[:, keep]
    integral = cone_integral(fit, base, rows, cols, shifts)
    integral_sigma = integral_spread(fit, base, rows, cols, shifts)
    slope = (cone_integral(fit, ratios_with_toe(TRIAL_TOE)[:, keep], rows, cols, shifts) - integral) / TRIAL_TOE
    record = dict(integral=integral, integral_sigma=integral_sigma, expected_sigma=expected_sigma, slope=slope,
                  exposures_read=read, photos=int(keep.sum()))
    if not slope > MIN_SLOPE:
        return Closure(**record)
    toe = (1.0 - integral) / slope
    return Closure(**record, toe=float(np.clip(toe, -MAX_TOE, MAX_TOE)),
                   toe_sigma=math.hypot(expected_sigma, integral_sigma) / slope, pinned=True,
                   clamped=abs(toe) > MAX_TOE)
