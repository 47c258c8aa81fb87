"""The band photos over white, as the measurement reads them (working pixels, linear light).

Each photo relinearised as a tone curve that differs by a power would have it (:func:`relinearised`),
less black, its light above black as a curve with another toe would have it (:func:`toe_lifted`: how
the measurement sets the toe, :mod:`.closure`, and propagates the tone curve's uncertainty), the
camera's veiling glare removed (:mod:`.photometry`), divided by white; inside the eroded panel
mask, optionally averaged along the panel's columns (:func:`.cone.average_along_columns`: a close
camera's moire of the lit subpixels).
"""

from __future__ import annotations

import numpy as np

from . import cone, photometry

COLUMN_AVERAGE = 1 / 16  # sigma of the average along the panel's columns, of the panel's height in the photo
TOE_END = 0.25  # share of white's light where the toe's uncertainty has faded out (it is whole at black)


CENTRE_FRACTION = 0.4  # the centre region: this share of the panel's extent in the photo, each way


def bounding_box(mask: np.ndarray) -> tuple[int, int, int, int]:
    """(first row, last row, first column, last column) of the true pixels of ``mask``."""
    rows, cols = np.nonzero(mask)
    return int(rows.min()), int(rows.max()), int(cols.min()), int(cols.max())


def centre_region(rows: np.ndarray, cols: np.ndarray, box) -> np.ndarray:
    """bool (n,): which working pixels (``rows``, ``cols``: int (n,)) lie in the centre region, the
    middle ``CENTRE_FRACTION`` of the panel outline ``box`` (:func:`bounding_box`) each way."""
    r0, r1, c0, c1 = box
    lo, hi = 0.5 - CENTRE_FRACTION / 2, 0.5 + CENTRE_FRACTION / 2
    return ((rows >= r0 + lo * (r1 - r0)) & (rows <= r0 + hi * (r1 - r0))
            & (cols >= c0 + lo * (c1 - c0)) & (cols <= c0 + hi * (c1 - c0)))


def relinearised(light: np.ndarray, power: float = 1.0) -> np.ndarray:
    """``light`` (working pixels, linearised) as a tone curve that differs by ``power`` would have it:
    ``max(light, 0) ** power``."""
    return np.maximum(light, 0.0) ** power


def toe_lifted(above: np.ndarray, reference: float, toe: float, end: float = TOE_END) -> np.ndarray:
    """The light above black ``above`` (working pixels) as a tone curve whose toe differs by ``toe``
    would have it: times ``1 + toe (1 - x / end)`` where ``x = above / reference`` (``reference``:
    white's typical light above black on the panel) is below ``end``: whole just above black, none
    from ``end`` of white's light up.  A tone curve maps codes to light whatever the place, so ``x``
    is the light on one scale for the whole photo (not over white's at the same pixel, which a
    panel's vignetting changes by tens of per cent).  It acts on the light above black, not on the
    light itself: black's own light, which every photo holds, stays what it is (a toe that scaled
    it would take it off the bright views too: the own view of bench hard case 13 moved by 4 % for
    a toe of 0.9)."""
    if not toe:
        return above
    share = above / max(float(reference), 1e-12)
    return above * (1.0 + toe * np.clip(1.0 - share / end, 0.0, 1.0))


def band_ratios(luma, mask, pattern_set, glare, power=1.0, column_average=COLUMN_AVERAGE, toe=0.0, clip=None,
                toe_end=TOE_END):
    """(float64 (n, K) band ratios, rows, cols, corrected white) inside the eroded panel mask.

    ``column_average``: sigma of the average along the panel's columns, as a share of the panel's
    height in the photo (0: none); ``power``: the photos relinearised (:func:`relinearised`); ``toe``,
    ``toe_end``: their light above black lifted (:func:`toe_lifted`);
    ``clip`` (sigma, scale): the photos as unclipped with ``scale`` times the noise sigma they were
    unclipped with (:func:`.dark.reclipped`; None: as they are)."""
    import cv2

    from .dark import reclipped

    def linear(name):
        return relinearised(luma[name] if clip is None else reclipped(luma[name], *clip), power)

    black = linear("black")  # once, not once per photo
    plain_white = linear("white") - black
    reference = float(np.median(plain_white[mask])) if toe else 1.0

    def corrected(name):
        img = toe_lifted(linear(name) - black, reference, toe, toe_end)
        return photometry.remove_glare(img.astype(np.float32), glare)

    plain = photometry.remove_glare(plain_white.astype(np.float32), glare)
    white = corrected("white") if toe else plain  # the same where white is lit
    if power != 1.0 or clip is not None:  # the pixels used: the same whatever the variation
        plain = photometry.remove_glare((luma["white"] - luma["black"]).astype(np.float32), glare)

    def over_white(name):
        return corrected(name) / np.maximum(white, 1e-6)

    inner = cv2.erode(mask.astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    inner &= plain > 0.2 * np.percentile(plain[mask], 50)
    rows, cols = np.nonzero(inner)
    # the band photos' moire (one phase of the lit subpixels per place) averaged out along the
    # panel's columns, where the sweep stays put (cone.average_along_columns)
    bands = pattern_set.bands
    if column_average:
        r0, r1, _, _ = bounding_box(mask)
        sigma, angle = column_average * (r1 - r0), cone.column_angle(mask)
        ratios = np.stack([cone.average_along_columns(over_white(p.name), inner, sigma, angle)[rows, cols]
                           for p in bands], axis=1)
    else:
        ratios = np.stack([over_white(p.name)[rows, cols] for p in bands], axis=1)
    return ratios.astype(np.float64), rows, cols, white
