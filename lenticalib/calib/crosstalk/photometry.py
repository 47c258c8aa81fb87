"""Photometry of the crosstalk photos: the camera's veiling glare (its tone curve: :mod:`.tone`).

Frames: *working* pixels (the photo area-averaged by an integer ``factor``).  Light is linear, in
units where the camera's saturation is about 1.

Veiling glare.  A camera spreads a few per cent of the light of the whole image into a wide halo;
between views that looks exactly like the panel's own crosstalk (a floor under every view).  It
is measured where only glare can be: outside the panel, where ``white - black`` is the halo of
the lit panel (the bezel and the room are the same in both photos), as ``fraction x Gaussian(sigma)``
of the panel's light (:func:`fit_glare`), and removed from every photo (:func:`remove_glare`).

The bezel and the room are the same light in both photos, but not always the same exposure: a
camera whose exposure drifts from photo to photo (a phone's automatic exposure, up to 4 % on the
bench's hard conditions) leaves a few per cent of the room's light in ``white - black`` outside
the panel, of either sign, as large as the glare itself.  Fitted as glare alone, that took the
halo far too narrow (hard case 8: 4 % of the image width and a fraction of 0.040, for the true
9.4 % and 0.047; its view cone's far entries came out 0.0016 high, 3.5 sigma).  So the fit holds a
constant ``offset`` beside the halo (the room is about even; so is a black level that does not
scale with the exposure): hard case 8 then gives 8 % and 0.051, and where the exposure holds the
offset comes out near 0 and the halo as before.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

def working(image: np.ndarray, factor: int) -> np.ndarray:
    """``image`` (h, w) or (h, w, c) area-averaged over ``factor`` x ``factor`` blocks: float32
    (h // factor, w // factor[, c]), the edge rows and columns that make no whole block dropped."""
    import cv2

    h, w = image.shape[:2]
    hh, ww = h // factor, w // factor
    return cv2.resize(image[:hh * factor, :ww * factor].astype(np.float32), (ww, hh), interpolation=cv2.INTER_AREA)


LIT_FLOOR = 0.04  # of white's 95th percentile: the least light a part of the panel may show (above any glare halo)
LOCAL_WINDOW = 0.02  # of the image width: the neighbourhood whose brightest light a panel pixel shows at least half of


def lit_region(lit: np.ndarray, blur: int = 0) -> np.ndarray | None:
    """bool (h, w): the panel's lit inside in ``lit`` (white - black), closed; None where nothing is lit.

    The core is the largest blob above half the 95th percentile (after a ``blur`` x ``blur``
    box, 0: none).  It is grown into the pixels joined to it that show at least half the
    brightest light within ``LOCAL_WINDOW`` of the image width around them and at least
    ``LIT_FLOOR`` of that percentile: the parts of the panel a strong angular fall-off or a
    camera's vignetting leave dim (a lens aperture that cuts steep rays left the sides of a panel
    seen from 700 mm at 8-35 % of its centre, and half-maximum alone cut them off: the sweep
    check then refused right photos), but not the panel's blurred edge (under half of the lit
    side beside it) nor a glare halo (under the floor).
    """
    import cv2

    if blur:
        lit = cv2.blur(lit.astype(np.float32), (blur, blur))
    lit = lit.astype(np.float32)
    level = float(np.percentile(lit, 95))
    if not level > 0:
        return None
    count, labels, stats, _ = cv2.connectedComponentsWithStats((lit > 0.5 * level).astype(np.uint8), connectivity=8)
    if count < 2:
        return None
    core = labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    side = max(3, int(round(LOCAL_WINDOW * lit.shape[1])) | 1)
    local_max = cv2.dilate(lit, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (side, side)))
    grown = core | ((lit > LIT_FLOOR * level) & (lit >= 0.5 * local_max))
    _, labels = cv2.connectedComponents(grown.astype(np.uint8), connectivity=8)
    mask = np.isin(labels, np.unique(labels[core])).astype(np.uint8)
    return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8)) > 0


GLARE_SIGMAS = (0.015, 0.02, 0.03, 0.04, 0.05, 0.065, 0.08, 0.1, 0.13)  # of the image width


@dataclasses.dataclass(frozen=True)
class Glare:
    """Veiling glare: ``fraction`` of the light spread as a Gaussian of ``sigma`` working pixels;
    ``offset``: the even light of ``white - black`` outside the panel fitted beside it (exposure
    drift on the room's light), ``rms`` the fit's residual (both in the photos' linear units)."""

    fraction: float
    sigma: float
    rms: float
    offset: float = 0.0

    def to_dict(self) -> dict:
        return {"fraction": round(self.fraction, 5), "sigma_pixels": round(self.sigma, 2), "residual": round(self.rms, 6),
                "offset": round(self.offset, 6)}


def _blur(image: np.ndarray, sigma: float) -> np.ndarray:
    import cv2

    return cv2.GaussianBlur(image, (0, 0), sigma, borderType=cv2.BORDER_CONSTANT)


def fit_glare(lit: np.ndarray, outside: np.ndarray) -> Glare:
    """Glare from ``white - black`` (float32 (h, w), working pixels) seen ``outside`` the panel (bool (h, w)).

    ``lit`` is zeroed outside the panel and taken as the panel's own light; for each width in
    ``GLARE_SIGMAS`` the fraction and an even offset (see the module's text) are the least-squares
    fit of its blur onto ``lit`` outside; the width that fits best wins.
    """
    source = np.where(outside, 0.0, lit).astype(np.float32)
    target = lit[outside].astype(np.float64)
    if target.size < 500:
        return Glare(0.0, 0.0, math.nan)
    width = lit.shape[1]
    best = None
    for s in GLARE_SIGMAS:
        halo = _blur(source, s * width)[outside].astype(np.float64)
        design = np.stack([halo, np.ones_like(halo)], axis=1)
        (fraction, offset), *_ = np.linalg.lstsq(design, target, rcond=None)
        rms = float(np.sqrt(np.mean((target - design @ (fraction, offset)) ** 2)))
        if best is None or rms < best.rms:
            best = Glare(max(0.0, float(fraction)), s * width, rms, float(offset))
    return best


def remove_glare(image: np.ndarray, glare: Glare) -> np.ndarray:
    """``image`` (linear, black subtracted, float32 (h, w)) without its glare, to first order in the fraction."""
    if glare.fraction <= 0:
        return image
    return (image - glare.fraction * _blur(image, glare.sigma)) / (1.0 - glare.fraction)
