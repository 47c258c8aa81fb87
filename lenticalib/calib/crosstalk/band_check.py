"""The band photos' checks as the measurement runs them: the whole panel first, then its centre region.

Frames: working pixels (``mask``, the panel's lit inside from :func:`.photos.panel_mask`).  The
checks themselves are in :mod:`.checks`: duplicate photos, a band photo whose band is not where
the others put it, and a set that does not follow the profile's routing.  They hold the photos to
one view cone swept across the panel.  A panel whose cone changes across it as the camera sees it
(a lens aperture that cuts steep rays: the sides, seen at 20-25 degrees, lie outside the cone the
centre shows, dim and with a cone of another shape) fails them on right photos.  The measurement
only uses the centre region (:func:`.ratios.centre_region`), so when the whole panel is refused the
same checks are run on the centre region alone: if its photos agree and follow the profile there,
the set is measured with a warning that names what the whole panel showed; otherwise the whole
panel's refusal stands.  A wrong photo or a wrong profile shows in the centre region as well
(docs/crosstalk.md, "The band-photo check").
"""

from __future__ import annotations

import math

import numpy as np

from ...core.errors import CaptureError
from . import photometry
from .checks import check_band_photos, check_distinct, check_routing
from .ratios import COLUMN_AVERAGE, band_ratios, bounding_box, centre_region

NO_GLARE = photometry.Glare(0.0, 0.0, math.nan)  # the checks judge the ratios as photographed (see check_bands)


def check_bands(luma, mask, pattern_set, capture, warnings, force=False) -> tuple[float, dict]:
    """The band photos' checks, right after the photos are read and registered and before any of
    the measurement's own work (glare, cone fits, uncertainties).

    ARGUMENTS
    luma        name -> float (h, w) working image (linear light)
    mask        bool (h, w): the panel's lit inside
    warnings    list the warnings are appended to
    force       measure photos that do not follow the profile's routing anyway (with a warning)

    RETURNED VALUE
    (the column average to measure with (0 or ``COLUMN_AVERAGE``), the routing check's record
    (:func:`.checks.check_routing`) with ``"region"``: "panel" or "centre", the part it was judged
    on); CaptureError naming the photo (or the set) where the whole panel and its centre region
    both refuse (the whole panel's reason).

    The checks judge the ratios without the glare correction: the glare adds a smooth floor the
    cone model holds, and its fit and removal would take as long as the checks.
    """
    ratios, rows, cols, _ = band_ratios(luma, mask, pattern_set, NO_GLARE, column_average=0.0)
    check_distinct(ratios, pattern_set.bands, capture)
    box = bounding_box(mask)
    found: list[str] = []
    try:
        result = _check_region(luma, mask, box, None, pattern_set, capture, found, force, (ratios, rows, cols))
        warnings.extend(found)
        return result[0], dict(result[1], region="panel")
    except CaptureError as refusal:
        whole = refusal
    # the centre region's samples are the whole panel's that lie in it (read once)
    inside = centre_region(rows, cols, box)
    centre = np.zeros_like(mask)
    centre[rows[inside], cols[inside]] = True
    found = []
    try:
        result = _check_region(luma, centre, box, bounding_box(centre), pattern_set, capture, found, force,
                               (ratios[inside], rows[inside], cols[inside]))
    except CaptureError:
        raise whole from None
    warnings.extend(found)
    warnings.append("the band photos follow one view cone in the panel's centre region, where the matrix is measured, "
                    f"but not across the whole panel ({whole.message}): the cone changes across the panel (seen from "
                    "the camera its sides may lie outside the cone the centre shows: a lens aperture that cuts steep "
                    "rays, or a camera closer than the panel's viewing distance); the uniformity map shows the change")
    return result[0], dict(result[1], region="centre")


def _check_region(luma, region, box, span, pattern_set, capture, warnings, force, ratios) -> tuple[float, dict]:
    """The band-photo and routing checks (:mod:`.checks`) on the pixels of ``region`` (bool (h, w)):
    (column average, routing record) or CaptureError.  ``box``: the panel's outline; ``span``: the
    region's own box where it is a part of the panel (None: the whole panel); ``ratios``: the
    region's (ratios (n, K), rows (n,), cols (n,)) without glare correction."""
    bands = pattern_set.bands
    shifts = np.array([p.shift for p in bands])
    routing: dict = {}

    def judge(fit):
        routing.update(check_routing(fit, box, pattern_set, capture, warnings, force, span=span))

    try:
        check_band_photos(*ratios, shifts, bands, capture, pattern_set.views, region.shape, judge)
        return 0.0, routing
    except CaptureError as refusal:
        if not routing:  # refused by the routing check (judge), which runs before the band check refuses
            raise
        # a close camera may resolve the moire of a one-view band (which subpixel each lens shows):
        # the same photos averaged along the panel's columns, where the sweep stays put, must then
        # agree.  If they do not either, a photo the first check named stays named; otherwise the
        # averaged photos' verdict stands (their misfits hold neither noise nor moire)
        averaged = band_ratios(luma, region, pattern_set, NO_GLARE, column_average=COLUMN_AVERAGE)
        try:
            check_band_photos(*averaged[:3], shifts, bands, capture, pattern_set.views, region.shape)
        except CaptureError as second:
            raise (second if refusal.source == str(capture.directory / "captures") else refusal) from None
    warnings.append("the band photos show a moire of the lit subpixels (a close camera): they were averaged "
                    f"along the panel's columns (sigma {COLUMN_AVERAGE:.3f} of the panel's height)")
    return COLUMN_AVERAGE, routing
