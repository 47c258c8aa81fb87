"""Camera shake between photos: measured on the patterns' registration frame, with a confidence, and undone.

Frames: working-image pixels (see :mod:`.phase`), OpenCV convention (x right, y down).

Why it matters: the fit combines the panel coordinate ``X`` seen by a camera pixel (from the
coordinate groups) with the fine fringe's phase at the same pixel.  The camera sees 3-6
subpixels per pixel and the view coordinate changes by ``N / Delta_r`` (about 1.7) views per
subpixel, so a shift of a tenth of a pixel between photos moves the measured view coordinate
by up to a view on a steep slant.  A tripod that shakes by a fraction of a pixel between
photos is normal.

How: every pattern carries the same evenly lit frame around the panel (see
:mod:`.patterns`), so the panel's outline looks the same in every photo whatever its fringe.
The reference is the mean image of group x1; the band of pixels around the panel's outline
(the frame's outer half, the edge, the bezel beyond) is where
each photo is aligned to it, by Gauss-Newton (Lucas-Kanade) on a translation plus a gain and
an offset (exposure drift).  Each photo is aligned separately and resampled before
demodulation, so shake *within* a phase-shift group is undone too.  An edge lit by the
photo's own fringe would be weighted by that fringe's level at the edge, which biases the
group mean by a good part of the shake; the frame removes that bias at the source.

The confidence of a shift is its Cramer-Rao bound from the residual noise and the reference
gradients; a shift that cannot be measured is reported as such, never as camera motion.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

BAND_OUTSIDE = 1.5  # frame widths: the band reaches this far beyond the panel's outline
OUTLINE_SEARCH = 1.4  # frame widths beyond the fringe region where the outline is looked for
MAX_ITERATIONS = 30
MAX_MEASURABLE_SIGMA = 0.2  # working pixels: a shift known worse than this is "not measured"
SMOOTHING = 1.2  # working pixels: both images are Gaussian-smoothed before aligning (see measure)
EDGE_OVER_NOISE = 4.0  # band pixels kept where the reference gradient exceeds this x the band's median
MAX_BAND_PIXELS = 150_000  # the band is thinned evenly to about this many pixels (speed)


@dataclasses.dataclass(frozen=True)
class Shift:
    """Translation (working pixels) of one photo against the registration reference.

    ``dx, dy``: where a panel feature at (x, y) in the reference sits in this photo
    (x + dx, y + dy).  ``sigma``: 1-sigma of each component (pixels); ``measured``: False when
    the alignment did not converge, fits no better than no shift, or the outline is too weak
    (then dx = dy = 0 and nothing is undone).  ``improvement``: the fraction of the unshifted
    residual the shift removes (near 1 for a clear shift of several pixels; small for a shake
    of a tenth of a pixel in a noisy photo, which is still measured).
    """

    dx: float
    dy: float
    sigma: float
    measured: bool
    note: str = ""
    improvement: float = 0.0  # 1 - residual at the shift / residual unshifted: how much the shift explains

    @property
    def size(self) -> float:
        return math.hypot(self.dx, self.dy)


@dataclasses.dataclass
class Reference:
    """The registration reference: band pixels around the panel outline and the reference there.

    ``rows, cols``: int arrays (n,) of the band pixels; ``values``, ``grad_x``, ``grad_y``:
    float64 (n,) reference image and its gradient (per pixel) there; ``shape``: (h, w) of the
    images it aligns.
    """

    rows: np.ndarray
    cols: np.ndarray
    values: np.ndarray
    grad_x: np.ndarray
    grad_y: np.ndarray
    shape: tuple[int, int]

    @classmethod
    def from_mean_image(cls, dc: np.ndarray, fringe: np.ndarray, frame_fraction: float) -> "Reference | None":
        """Reference from a group's mean image ``dc`` (h, w) and its complex fringe ``z`` (h, w);
        ``frame_fraction``: the frame's width as a fraction of the panel height.  None when no
        fringe region is found.

        The band is the ring *outside* the panel's outline, up to 1.5 frame widths beyond it:
        the outer half of the edge, the bezel, maybe the room behind -- all still, all the same
        in every photo.  Not the frame's inside: through the lens sheet even an evenly lit area
        shows a moire texture near the camera's sampling limit, and a texture the camera
        aliases seems to move by a different amount than the image (seen: 2 pixels of it
        halved the measured vertical shake).  The outline is where the smoothed mean image
        crosses halfway between the frame's level and the darkest surround; it is searched
        for only near the *fringe region* (where the panel shows fringes): a room can be as
        bright as the panel, but only the panel has fringes.
        """
        import cv2

        from .phase import panel_mask, smooth_complex

        # averaged as a complex map, the fringe stays and sensor noise averages out (the
        # magnitude of noise would not: a noisy surround would pass for fringes)
        sigma = max(2.0, frame_fraction * min(dc.shape) / 4.0)
        fringes = panel_mask([np.abs(smooth_complex(np.asarray(fringe, dtype=np.complex64), sigma))],
                             erode_fraction=0.0)
        if fringes.sum() < 64:
            return None
        ys, _ = np.nonzero(fringes)
        fringe_height = float(np.percentile(ys, 99.5) - np.percentile(ys, 0.5))
        frame = frame_fraction / max(1e-6, 1.0 - 2.0 * frame_fraction) * fringe_height  # working pixels

        def grown(mask, r):
            r = max(1, int(round(r)))
            return cv2.dilate(mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))) > 0

        # smoothed enough that sensor noise neither drags the dark level down nor lets the
        # threshold leak into a dark surround (a noisy photo's outline would be ragged)
        smooth = cv2.GaussianBlur(dc.astype(np.float32), (0, 0), max(1.5, frame / 6.0))
        inside = grown(fringes, 0.7 * frame) & ~grown(fringes, 0.3 * frame)
        search = grown(fringes, OUTLINE_SEARCH * frame)
        surround = grown(fringes, 2.5 * frame) & ~grown(fringes, 0.9 * frame)
        if not inside.any() or not surround.any():
            return None
        frame_level = float(np.median(smooth[inside]))
        dark_level = float(np.percentile(smooth[surround], 5))
        lit = (search & (smooth > 0.5 * (frame_level + dark_level))) | fringes
        count, labels = cv2.connectedComponents(lit.astype(np.uint8), connectivity=8)
        panel_label = int(np.bincount(labels[fringes]).argmax())
        lit = labels == panel_label
        band = grown(lit, BAND_OUTSIDE * frame) & ~lit
        edge = 4  # the interpolation reaches 2 pixels, and shifts a little more
        band[:edge] = band[-edge:] = False
        band[:, :edge] = band[:, -edge:] = False
        ref = smoothed(dc)
        gx = cv2.Sobel(ref, cv2.CV_32F, 1, 0, ksize=3) / 8.0
        gy = cv2.Sobel(ref, cv2.CV_32F, 0, 1, ksize=3) / 8.0
        # Only pixels with a real edge: in a noisy photo most of the band is flat sensor noise,
        # whose gradients carry no shift but would inflate the Cramer-Rao information (and so
        # understate sigma) and pull the alignment.  The flat part's gradients are noise: keep
        # what stands well above their typical size.
        magnitude = np.hypot(gx, gy)
        typical = float(np.median(magnitude[band])) if band.any() else 0.0
        band &= magnitude > EDGE_OVER_NOISE * typical
        band = grown(band, 1.0) & grown(lit, BAND_OUTSIDE * frame) & ~lit
        rows, cols = np.nonzero(band)
        stride = max(1, rows.size // MAX_BAND_PIXELS)
        rows, cols = rows[::stride], cols[::stride]
        return cls(rows, cols, ref[rows, cols].astype(np.float64), gx[rows, cols].astype(np.float64),
                   gy[rows, cols].astype(np.float64), dc.shape)

    def measure(self, image: np.ndarray) -> Shift:
        """Shift of ``image`` (h, w) against the reference: Gauss-Newton on translation, gain, offset.

        Both images are smoothed first (:func:`smoothed`): a translation commutes with the
        filter, and it keeps texture near the sampling limit from making the cubic
        interpolation's error depend on the shift.
        """
        if image.shape != self.shape or self.rows.size < 100:
            return Shift(0.0, 0.0, math.inf, False, "no panel outline to align")
        img = smoothed(image)
        dx = dy = 0.0
        gain = 1.0
        ones = np.ones_like(self.values)
        for _ in range(MAX_ITERATIONS):
            moving = sample(img, self.rows, self.cols, dx, dy)
            design = np.column_stack([-gain * self.grad_x, -gain * self.grad_y, self.values, ones])
            solution, *_ = np.linalg.lstsq(design, moving, rcond=None)
            step_x, step_y, gain, _ = (float(v) for v in solution)
            if not (math.isfinite(step_x) and math.isfinite(step_y)) or gain <= 0:
                return Shift(0.0, 0.0, math.inf, False, "the panel outline did not align")
            dx += step_x
            dy += step_y
            if abs(dx) + abs(dy) > 0.05 * self.shape[1]:
                return Shift(0.0, 0.0, math.inf, False, "the panel outline did not align (no consistent shift)")
            if math.hypot(step_x, step_y) < 1e-4:
                break
        moving = sample(img, self.rows, self.cols, dx, dy)
        design = np.column_stack([-gain * self.grad_x, -gain * self.grad_y, self.values, ones])
        solution, *_ = np.linalg.lstsq(design, moving, rcond=None)
        residual = moving - design @ solution
        noise = float(np.mean(residual ** 2))
        try:
            cov = noise * np.linalg.inv(design.T @ design)
        except np.linalg.LinAlgError:
            return Shift(0.0, 0.0, math.inf, False, "the panel outline is too faint to align")
        still = sample(img, self.rows, self.cols, 0.0, 0.0)
        still_fit, *_ = np.linalg.lstsq(design[:, 2:], still, rcond=None)
        still_noise = float(np.mean((still - design[:, 2:] @ still_fit) ** 2))
        if not noise <= still_noise:
            return Shift(0.0, 0.0, math.inf, False, "no shift fits the panel outline better than none")
        improvement = 1.0 - noise / max(still_noise, 1e-30)
        # neighbouring residuals are correlated (demosaicing, JPEG, the lens sheet): count ~4 pixels as one
        sigma = math.sqrt(4.0 * max(cov[0, 0], cov[1, 1], 0.0))
        if not sigma < MAX_MEASURABLE_SIGMA:
            return Shift(0.0, 0.0, sigma, False, f"the panel outline is too faint to align (1-sigma {sigma:.2f} px)")
        return Shift(dx, dy, sigma, True, improvement=improvement)


def smoothed(image: np.ndarray) -> np.ndarray:
    """float32 (h, w): ``image`` smoothed by a Gaussian of SMOOTHING pixels (a translation commutes
    with it; it keeps texture near the sampling limit from making the cubic interpolation's
    error depend on the shift)."""
    import cv2

    img = np.ascontiguousarray(image, dtype=np.float32)
    return cv2.GaussianBlur(img, (0, 0), SMOOTHING)


def _keys_weights(fraction: float) -> np.ndarray:
    """Cubic convolution (Keys, a = -0.5) weights of the taps at offsets -1, 0, 1, 2 for a sample at +fraction."""
    t = np.abs(np.array([fraction + 1.0, fraction, 1.0 - fraction, 2.0 - fraction]))
    a = -0.5
    near = (a + 2) * t ** 3 - (a + 3) * t ** 2 + 1
    far = a * t ** 3 - 5 * a * t ** 2 + 8 * a * t - 4 * a
    return np.where(t <= 1.0, near, far)


def sample(image: np.ndarray, rows: np.ndarray, cols: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """float64 (n,): ``image`` at (cols + dx, rows + dy), cubic convolution, edges replicated."""
    h, w = image.shape
    ix, iy = math.floor(dx), math.floor(dy)
    wx, wy = _keys_weights(dx - ix), _keys_weights(dy - iy)
    out = np.zeros(rows.shape, dtype=np.float64)
    for k in range(4):
        r = np.clip(rows + iy + k - 1, 0, h - 1)
        line = np.zeros(rows.shape, dtype=np.float64)
        for j in range(4):
            line += wx[j] * image[r, np.clip(cols + ix + j - 1, 0, w - 1)]
        out += wy[k] * line
    return out


def _lanczos_weights(fraction: float) -> np.ndarray:
    """Lanczos-3 weights (normalised to sum 1) of the taps at offsets -2..3 for a sample at +fraction."""
    t = np.arange(-2, 4) - fraction
    weights = np.sinc(t) * np.sinc(t / 3.0)
    return (weights / weights.sum()).astype(np.float32)


def shift_image(image: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """float32 (h, w): ``image`` sampled at (x + dx, y + dy), undoing a measured :class:`Shift`.

    Lanczos-3 resampling with exact (floating-point) weights, separable, edges replicated.
    OpenCV's ``warpAffine`` quantises positions to 1/32 pixel, an error the fine fringes would
    show; this does not.
    """
    import cv2

    img = np.ascontiguousarray(image, dtype=np.float32)
    if dx == 0.0 and dy == 0.0:
        return img.copy()
    h, w = img.shape
    ix, iy = math.floor(dx), math.floor(dy)
    if ix or iy:
        img = img[np.clip(np.arange(h) + iy, 0, h - 1)][:, np.clip(np.arange(w) + ix, 0, w - 1)]
    return cv2.sepFilter2D(img, cv2.CV_32F, _lanczos_weights(dx - ix), _lanczos_weights(dy - iy),
                           anchor=(2, 2), borderType=cv2.BORDER_REPLICATE)
