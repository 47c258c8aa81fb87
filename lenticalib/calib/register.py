"""Camera shake between photo groups: measured on the panel's silhouette, with a confidence, and undone.

Frames: working-image pixels (see :mod:`.phase`), OpenCV convention (x right, y down).

Why it matters: the fit combines the panel coordinate ``X`` seen by a camera pixel (from the
coordinate groups) with the fine fringe's phase at the same pixel.  The camera sees 3-6
subpixels per pixel and the view coordinate changes by ``N / Delta_r`` (about 1.7) views per
subpixel, so a shift of a tenth of a pixel between groups moves the measured view coordinate
by most of a view.  A tripod that shakes by a fraction of a pixel between photos is normal.

How: every group's mean image (its DC; the phase steps average out) shows the same evenly
lit panel, whatever its fringe.  Its *silhouette* -- the DC with the group's own fringe
residue divided out, over the panel's local level -- removes what differs between groups
(fringe residue from the camera's tone curve and from shake between phase steps, exposure
drift, vignetting) and keeps the panel's edge, which is the same in every group.  ECC (OpenCV ``findTransformECC``, translation only) aligns each silhouette with the
reference group's inside a band around the panel edge.  The confidence of a shift is its
Cramer-Rao bound from the residual noise and the edge gradients; a shift that cannot be
measured is reported as such, never as camera motion.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

# Where the silhouette saturates, as a multiple of the panel's local level: above the panel, so the
# edge ramp is never cut (clipping inside the ramp biased ECC by ~8 % of the shift); only glare
# and specular outliers are limited.
SILHOUETTE_LEVEL = 1.5


@dataclasses.dataclass(frozen=True)
class Shift:
    """Translation (working pixels) of one group's images against the reference group.

    ``dx, dy``: where a panel feature at (x, y) in the reference sits in this group
    (x + dx, y + dy).  ``sigma``: 1-sigma of each component (pixels); ``measured``: False when
    ECC did not converge or the edge band is too weak (then dx = dy = 0 and nothing is undone).
    """

    dx: float
    dy: float
    sigma: float
    measured: bool
    note: str = ""

    @property
    def size(self) -> float:
        return math.hypot(self.dx, self.dy)


def silhouette(dc: np.ndarray, mask: np.ndarray, z: np.ndarray | None = None) -> np.ndarray:
    """float32 (h, w) in [0, 1]: ``dc`` over SILHOUETTE_LEVEL x its local panel level, clipped
    (about 0.67 inside the panel, 0 outside).

    The local level is ``dc`` averaged over the panel (``mask``) with a Gaussian of 1/20 of the
    frame width, so vignetting and fall-off do not let fringe residue through the clip.  With
    the group's complex fringe ``z``, the fringe residue itself (harmonics 1-3 of the fringe
    phase, left in the mean image by shake between the phase steps and by the tone curve) is
    fitted inside the panel and divided out first: it runs along the panel edge parallel to
    the fringes and would pull the edge, and so the measured shift, across them.
    """
    level = local_level(dc, mask)
    if z is not None and mask.any():
        dc = _without_fringe_residue(dc, mask, z, level)
    return np.clip(dc / np.maximum(SILHOUETTE_LEVEL * level, 1e-9), 0.0, 1.0).astype(np.float32)


def local_level(image: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """float32 (h, w): ``image`` averaged over ``mask`` with a Gaussian of 1/20 of the frame width
    (normalised convolution, computed at 1/8 resolution), extended beyond the mask."""
    import cv2

    h, w = image.shape
    small = (max(1, w // 8), max(1, h // 8))
    m = cv2.resize(mask.astype(np.float32), small, interpolation=cv2.INTER_AREA)
    v = cv2.resize(image.astype(np.float32) * mask, small, interpolation=cv2.INTER_AREA)
    sigma = small[0] / 20.0
    num = cv2.GaussianBlur(v, (0, 0), sigma)
    den = cv2.GaussianBlur(m, (0, 0), sigma)
    fallback = float(np.median(image[mask])) if mask.any() else float(np.median(image))
    level = np.where(den > 1e-3, num / np.maximum(den, 1e-3), fallback).astype(np.float32)
    return cv2.resize(level, (w, h), interpolation=cv2.INTER_LINEAR)


def _without_fringe_residue(dc: np.ndarray, mask: np.ndarray, z: np.ndarray, level: np.ndarray) -> np.ndarray:
    relative = dc / np.maximum(level, 1e-9) - 1.0
    u = z / np.maximum(np.abs(z), 1e-12)
    step = max(1, int(mask.sum() // 300_000))
    sel = np.flatnonzero(mask.ravel())[::step]
    us = u.ravel()[sel]
    basis = np.stack([f(us ** n) for n in (1, 2, 3) for f in (np.real, np.imag)], axis=1).astype(np.float64)
    coef, *_ = np.linalg.lstsq(basis, relative.ravel()[sel].astype(np.float64), rcond=None)
    residue = sum(coef[2 * (n - 1)] * np.real(u ** n) + coef[2 * (n - 1) + 1] * np.imag(u ** n) for n in (1, 2, 3))
    return (dc / (1.0 + residue)).astype(np.float32)


def edge_band(mask: np.ndarray) -> np.ndarray:
    """uint8 (h, w): 1 within about 1/60 of the frame width of the panel outline."""
    import cv2

    half = max(5, int(round(mask.shape[1] / 64)))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * half + 1, 2 * half + 1))
    m8 = mask.astype(np.uint8)
    return (cv2.dilate(m8, kernel) - cv2.erode(m8, kernel)).astype(np.uint8)


def measure_shift(reference: np.ndarray, moving: np.ndarray, band: np.ndarray) -> Shift:
    """Shift of silhouette ``moving`` against silhouette ``reference`` (both float32 (h, w))."""
    import cv2

    warp = np.eye(2, 3, dtype=np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 200, 1e-7)
    try:
        _, warp = cv2.findTransformECC(reference, moving, warp, cv2.MOTION_TRANSLATION, criteria, band, 3)
    except cv2.error:
        return Shift(0.0, 0.0, math.inf, False, "the panel edge did not align (ECC did not converge)")
    dx, dy = float(warp[0, 2]), float(warp[1, 2])
    if not (math.isfinite(dx) and math.isfinite(dy)) or math.hypot(dx, dy) > 0.05 * reference.shape[1]:
        return Shift(0.0, 0.0, math.inf, False, "the panel edge did not align (no consistent shift)")
    # Cramer-Rao: var(d) = noise variance / sum of squared gradients (noise from the aligned residual)
    aligned = shift_image(moving, dx, dy)
    sel = band.astype(bool)
    residual = (aligned - reference)[sel]
    noise = float(np.var(residual)) / 2.0
    ref = cv2.GaussianBlur(reference, (0, 0), 1.0)
    gx = cv2.Sobel(ref, cv2.CV_32F, 1, 0, ksize=3)[sel] / 8.0
    gy = cv2.Sobel(ref, cv2.CV_32F, 0, 1, ksize=3)[sel] / 8.0
    info = min(float(np.sum(gx * gx)), float(np.sum(gy * gy)))
    # neighbouring residuals are correlated (demosaicing, JPEG, the lens sheet): count ~4 pixels as one
    sigma = math.sqrt(4.0 * noise / info) if info > 0 else math.inf
    if not sigma < 0.2:
        return Shift(0.0, 0.0, sigma, False, f"the panel edge is too faint to align (1-sigma {sigma:.2f} px)")
    return Shift(dx, dy, sigma, True)


def shift_image(image: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``image`` (h, w) real, sampled at (x + dx, y + dy): undoes a measured :class:`Shift`."""
    import cv2

    matrix = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]], dtype=np.float64)
    return cv2.warpAffine(image, matrix, (image.shape[1], image.shape[0]),
                          flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)


def shift_complex(z: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """:func:`shift_image` for a complex map (real and imaginary parts separately)."""
    re = shift_image(np.ascontiguousarray(z.real), dx, dy)
    im = shift_image(np.ascontiguousarray(z.imag), dx, dy)
    return (re + 1j * im).astype(np.complex64)
