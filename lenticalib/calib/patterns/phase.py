"""Phase-shift demodulation and the seen-coordinate maps of a photo.

Frames: arrays indexed [row, column] of the *working image* (a photo, area-averaged to at
most ``captures.MAX_WORKING_WIDTH`` wide).  Panel coordinates: ``X`` in subpixels and ``Y``
in rows, continuous, with subpixel ``x_s`` covering [x_s, x_s + 1) (its centre at x_s + 0.5).

For a group of K photos of the sinusoid ``cos(2 pi X / T + theta_k)``, ``theta_k = 2 pi k / K``,
the complex demodulation ``z = (2/K) sum_k I_k exp(-i theta_k)`` has ``arg z = 2 pi X_seen / T``
(plus, for the fine groups, the lens alias term) and ``|z|`` the fringe modulation.
"""

from __future__ import annotations

import math

import numpy as np


def demodulate(images: list[np.ndarray], thetas: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """K images (h, w) float32 -> (z complex64 (h, w), dc float32 (h, w))."""
    z = np.zeros(images[0].shape, dtype=np.complex64)
    dc = np.zeros(images[0].shape, dtype=np.float32)
    for image, theta in zip(images, thetas):
        z += image * np.complex64(complex(math.cos(theta), -math.sin(theta)))
        dc += image
    k = len(images)
    return z * np.float32(2.0 / k), dc / np.float32(k)


def smooth_complex(z: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian-average a complex map (sigma in pixels); identity for sigma < 0.5."""
    import cv2

    if sigma < 0.5:
        return z
    re = cv2.GaussianBlur(np.ascontiguousarray(z.real), (0, 0), sigma)
    im = cv2.GaussianBlur(np.ascontiguousarray(z.imag), (0, 0), sigma)
    return (re + 1j * im).astype(np.complex64)


def phase_cycles(z: np.ndarray) -> np.ndarray:
    """arg z / 2 pi in [0, 1), float64."""
    return np.mod(np.angle(z).astype(np.float64) / (2 * math.pi), 1.0)


def coordinate_from_single_period(cycles: np.ndarray, period: float, extent: float) -> np.ndarray:
    """Coordinate from a phase that covers the whole extent once (period > extent).

    Phases in the unused part of the cycle are split halfway, so pixels a little outside
    [0, extent] get small negative or slightly-too-large coordinates instead of wrapping.
    """
    coordinate = cycles * period
    gap_middle = extent + 0.5 * (period - extent)
    return np.where(coordinate > gap_middle, coordinate - period, coordinate)


def unwrap(coarse: np.ndarray, cycles: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    """Finer coordinate from a coarse one and the phase (cycles) of a pattern of ``period``.

    Returns (coordinate, residual): residual (cycles, in [-0.5, 0.5)) is how far the coarse
    coordinate was from the chosen fringe; a large one means the two groups disagree.
    """
    estimate = coarse / period - cycles
    order = np.rint(estimate)
    return (order + cycles) * period, estimate - order


def _poly_terms(u: np.ndarray, v: np.ndarray, degree: int) -> np.ndarray:
    return np.stack([u ** i * v ** j for i in range(degree + 1) for j in range(degree + 1 - i)], axis=-1)


def smooth_coordinate(coordinate: np.ndarray, weight: np.ndarray, sigma: float,
                      degree: int = 4) -> np.ndarray:
    """Smooth a seen-coordinate map (h, w) where ``weight > 0``; float64 result, NaN elsewhere.

    A global polynomial of ``degree`` in normalised pixel coordinates takes out the
    perspective and distortion; the residual is then averaged with a Gaussian of ``sigma``
    pixels (normalised convolution, so the panel border is not pulled toward zero).
    """
    import cv2

    h, w = coordinate.shape
    rows, cols = np.nonzero(weight > 0)
    if rows.size < 100:
        return np.full((h, w), np.nan)
    step = max(1, int(math.sqrt(rows.size / 200_000)))
    sel = slice(None, None, step * step)
    su = (cols[sel] - w / 2) / w
    sv = (rows[sel] - h / 2) / w
    terms = _poly_terms(su, sv, degree)
    wts = weight[rows[sel], cols[sel]].astype(np.float64)
    target = coordinate[rows[sel], cols[sel]]
    coef = _robust_lstsq(terms, target, wts)
    uu = (np.arange(w) - w / 2) / w
    vv = (np.arange(h) - h / 2) / w
    # sum_k coef_k u^i v^j over the grid = V @ M @ U^T with M[j, i] = coef of u^i v^j
    powers = [(i, j) for i in range(degree + 1) for j in range(degree + 1 - i)]
    mat = np.zeros((degree + 1, degree + 1))
    for (i, j), value in zip(powers, coef):
        mat[j, i] = value
    model = (vv[:, None] ** np.arange(degree + 1)) @ mat @ (uu[:, None] ** np.arange(degree + 1)).T
    residual = np.where(weight > 0, coordinate - model, 0.0)
    wmap = np.where(weight > 0, weight, 0.0).astype(np.float32)
    num = cv2.GaussianBlur((residual * wmap).astype(np.float32), (0, 0), sigma)
    den = cv2.GaussianBlur(wmap, (0, 0), sigma)
    with np.errstate(invalid="ignore", divide="ignore"):
        correction = np.where(den > 1e-6, num / den, 0.0)
    return np.where(weight > 0, model + correction, np.nan)


def _robust_lstsq(terms: np.ndarray, target: np.ndarray, weights: np.ndarray, rounds: int = 4) -> np.ndarray:
    """Weighted least squares with Tukey reweighting (drops unwrapping outliers).

    ``terms`` (n, k), ``target`` (n,), ``weights`` (n,) -> coefficients (k,).  Each round solves
    the k x k normal equations by Cholesky (a few times faster than an SVD of the n x k design for
    the polynomial maps of :func:`smooth_coordinate`, whose design is well conditioned); a
    singular or non-finite system falls back to ``numpy.linalg.lstsq`` (minimum norm)."""
    from scipy.linalg import LinAlgError, cho_factor, cho_solve

    w = weights.copy()
    coef = None
    for _ in range(rounds):
        weighted = terms * w[:, None]
        try:
            coef = cho_solve(cho_factor(weighted.T @ terms), weighted.T @ target)
        except (LinAlgError, ValueError):  # singular, or not finite: as lstsq always did
            sw = np.sqrt(w)
            coef, *_ = np.linalg.lstsq(terms * sw[:, None], target * sw, rcond=None)
        r = target - terms @ coef
        scale = 1.4826 * np.median(np.abs(r)) + 1e-9
        c = 4.685 * scale
        w = weights * np.where(np.abs(r) < c, (1 - (r / c) ** 2) ** 2, 0.0)
    return coef


def panel_mask(modulation: list[np.ndarray], erode_fraction: float = 0.012) -> np.ndarray:
    """Where the panel is: bool (h, w) from fringe modulation maps |z| of coarse groups.

    Pixels where every map (box-averaged over ~1/150 of the frame) exceeds a quarter of its
    99th percentile, morphologically
    cleaned, the largest connected part, holes filled, then eroded by ``erode_fraction``
    of its size (the panel edge and the bezel blur are not measured).
    """
    import cv2

    keep = np.ones(modulation[0].shape, dtype=bool)
    size = max(3, int(round(min(keep.shape) / 150)))
    for m in modulation:
        # single pixels may see no lit subpixel of a colour: judge modulation over small areas
        m = cv2.blur(m.astype(np.float32), (size, size))
        level = float(np.percentile(m, 99.0))
        keep &= m > 0.25 * level
    mask = keep.astype(np.uint8)
    k = max(3, int(round(min(mask.shape) / 300)) | 1)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if count <= 1:
        return np.zeros(mask.shape, dtype=bool)
    largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    mask = (labels == largest).astype(np.uint8)
    # fill holes: flood the background from the border
    flood = mask.copy()
    cv2.floodFill(flood, np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), np.uint8), (0, 0), 2)
    mask = np.where(flood == 2, 0, 1).astype(np.uint8)
    size = math.sqrt(float(mask.sum()))
    e = max(1, int(round(erode_fraction * size)))
    mask = cv2.erode(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * e + 1, 2 * e + 1)))
    return mask.astype(bool)
