"""The band photos over white, as the measurement reads them (working pixels, linear light).

Each photo relinearised as a tone curve that differs by a power or by its toe would have it
(:func:`relinearised`: how the measurement propagates the tone curve's uncertainty), less black,
its light above black lifted as a curve with another slope just above black would have it
(:func:`toe_lifted`: the light's closure, :mod:`.closure`), the
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


def _toe_factor(share: np.ndarray, amount: float) -> np.ndarray:
    """``1 + amount (1 - share / TOE_END)`` below ``TOE_END``, 1 from there up: a toe's change of the
    light, whole at black and none from ``TOE_END`` of white's light (``share``: the light over white's)."""
    return 1.0 + amount * np.clip(1.0 - share / TOE_END, 0.0, 1.0)


def relinearised(light: np.ndarray, white: np.ndarray, power: float = 1.0, toe: float = 0.0) -> np.ndarray:
    """``light`` (working pixels, linearised) as a tone curve that differs by ``power`` and by ``toe`` would
    have it: ``light ** power``, times ``1 + toe (1 - x / TOE_END)`` where ``x``, the light over ``white``'s
    at the same pixel, is below ``TOE_END`` (the curve's toe: whole at black, none from TOE_END up).
    Black's own light moves with it: where the black code's light sits against white's is as
    uncertain as the slope just above it (the uncertainty the measurement propagates)."""
    positive = np.maximum(light, 0.0)
    out = positive ** power
    if toe:
        out = out * _toe_factor(positive / np.maximum(white, 1e-9), toe)
    return out


def toe_lifted(above: np.ndarray, reference: float, lift: float) -> np.ndarray:
    """The light above black ``above`` (working pixels) as a tone curve whose slope just above black
    differs by ``lift`` would have it: times ``1 + lift (1 - x / TOE_END)`` where ``x = above /
    reference`` (``reference``: white's typical light above black on the panel) is below ``TOE_END``:
    whole just above black, none from ``TOE_END`` of white's light up.  Unlike :func:`relinearised`'s
    toe it leaves black's own light and the bright views as they are: it moves only the dark light,
    which is what the light's closure asks about (:mod:`.closure`)."""
    if not lift:
        return above
    return above * _toe_factor(above / max(float(reference), 1e-12), lift)


def band_ratios(luma, mask, pattern_set, glare, power=1.0, column_average=COLUMN_AVERAGE, toe=0.0, clip=None,
                lift=0.0):
    """(float64 (n, K) band ratios, rows, cols, corrected white) inside the eroded panel mask.

    ``column_average``: sigma of the average along the panel's columns, as a share of the panel's
    height in the photo (0: none); ``power``, ``toe``: the photos relinearised (:func:`relinearised`);
    ``lift``: their light above black lifted (:func:`toe_lifted`); ``clip`` (sigma, scale): the
    photos as unclipped with ``scale`` times the noise sigma they were unclipped with
    (:func:`.dark.reclipped`; None: as they are)."""
    import cv2

    from .dark import reclipped

    def linear(name):
        light = luma[name] if clip is None else reclipped(luma[name], *clip)
        return relinearised(light, luma["white"], power, toe)

    black = linear("black")  # once, not once per photo
    reference = float(np.median((luma["white"] - luma["black"])[mask])) if lift else 1.0

    def corrected(name):
        img = toe_lifted(linear(name) - black, reference, lift)
        return photometry.remove_glare(img.astype(np.float32), glare)

    white = corrected("white")
    # the pixels used: the same whatever the variation
    plain = (white if power == 1.0 and not toe and clip is None and not lift
             else photometry.remove_glare((luma["white"] - luma["black"]).astype(np.float32), glare))

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
