"""Photometry of the crosstalk photos: the camera's tone curve, its veiling glare, and registration.

Frames: photo pixels (full resolution) for the tone curve, *working* pixels (the photo area-
averaged by an integer ``factor``) for everything after it.  Light is linear, in units where the
camera's saturation is about 1.

Tone curve.  A camera's JPEG is not linear light (sRGB plus a phone's S-curve, unknown).  The
two half patterns light complementary halves of the views, so in linear light
``half-0 + half-1 = white`` (each above black) at every pixel, whatever each receives; across
the panel the split runs from all-in-one to all-in-the-other, and the white level itself varies
(vignetting, the lens sheet's moire), which leaves only a linear response consistent with every
pixel.  The inverse response is fitted as a monotone piecewise-linear table over the 8-bit code
values (:func:`fit_inverse_response`), together with the two photos' exposure factors.

Veiling glare.  A camera spreads a few per cent of the light of the whole image into a wide halo;
between views that looks exactly like the panel's own crosstalk (a floor under every view).  It
is measured where only glare can be: outside the panel, where ``white - black`` is the halo of
the lit panel (the bezel and the room are the same in both photos), as ``fraction x Gaussian(sigma)``
of the panel's light (:func:`fit_glare`), and removed from every photo (:func:`remove_glare`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...errors import CaptureError

KNOTS = 17  # inverse-response table nodes over code values 0..1
SMOOTHNESS = 3e-3  # second-difference penalty of the table (relative to the data residuals)
TONE_SAMPLES = 30_000
BLOCK = 6  # pixels per side of the tiles whose medians the tone curve is fitted to
GLARE_SIGMAS = (0.015, 0.02, 0.03, 0.04, 0.05, 0.065, 0.08, 0.1, 0.13)  # of the image width


@dataclasses.dataclass(frozen=True)
class InverseResponse:
    """Code value (0..1) -> linear light: a monotone table on ``KNOTS`` evenly spaced nodes.

    ``values``: float64 (KNOTS,), 0 at code 0 and 1 at code 1.  ``gains``: exposure of the two
    half photos relative to white's.  ``rms``: relative residual of ``half-0 + half-1 = white``.
    ``sigma_values``: 1-sigma of ``values`` (from the fit's covariance).
    """

    values: np.ndarray
    gains: tuple[float, float]
    rms: float
    sigma_values: np.ndarray

    def lut8(self) -> np.ndarray:
        """float32 (256,): linear light of each 8-bit code."""
        codes = np.arange(256) / 255.0
        return np.interp(codes, np.linspace(0.0, 1.0, KNOTS), self.values).astype(np.float32)

    def to_dict(self) -> dict:
        return {"codes": np.linspace(0.0, 1.0, KNOTS).round(4).tolist(), "linear": self.values.round(6).tolist(),
                "half_gains": [round(g, 5) for g in self.gains], "residual_rms": round(self.rms, 5)}


def _srgb_table() -> np.ndarray:
    from ..patterns import srgb_decode

    return srgb_decode(np.linspace(0.0, 1.0, KNOTS))


def _table_from(params: np.ndarray) -> np.ndarray:
    """Monotone table from free parameters: increments exp(p), normalised to end at 1."""
    steps = np.exp(params)
    table = np.concatenate([[0.0], np.cumsum(steps)])
    return table / table[-1]


def _interp_weights(codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    position = np.clip(codes, 0.0, 1.0) * (KNOTS - 1)
    lo = np.minimum(position.astype(np.int64), KNOTS - 2)
    return lo, position - lo


def fit_inverse_response(half0: np.ndarray, half1: np.ndarray, white: np.ndarray, black: np.ndarray,
                         mask: np.ndarray, seed: int = 0) -> InverseResponse:
    """The camera's inverse tone curve from the two half photos, white and black.

    ARGUMENTS
    half0, half1, white, black   uint8 (h, w, 3) photos (full resolution, same framing)
    mask                         bool (h, w): pixels inside the panel's lit area
    seed                         which pixels are sampled (fixed: the result is reproducible)

    Minimises, over sampled pixels and channels, ``(a0 (g(h0) - g(b)) + a1 (g(h1) - g(b)) -
    (g(w) - g(b))) / (g(w) - g(b))`` plus a small curvature penalty, with ``g`` monotone,
    ``g(0) = 0``, ``g(1) = 1``, started from sRGB.  CaptureError when the photos do not add up
    (another pattern, a moving camera, clipping).
    """
    from scipy.optimize import least_squares

    rng = np.random.default_rng(seed)
    blocks = [block_medians(img, BLOCK) for img in (half0, half1, white, black)]
    inside = block_medians(mask.astype(np.uint8)[:, :, None] * 255, BLOCK)[..., 0] >= 255
    rows, cols = np.nonzero(inside)
    if rows.size < 200:
        raise CaptureError("the panel's lit area is too small to measure the camera's tone curve",
                           source="white", hint="fill more of the photo with the panel")
    pick = rng.choice(rows.size, size=min(TONE_SAMPLES, rows.size), replace=False)
    rows, cols = rows[pick], cols[pick]
    samples = [b[rows, cols].reshape(-1).astype(np.float64) / 255.0 for b in blocks]
    keep = (samples[2] < 250 / 255) & (samples[0] < 250 / 255) & (samples[1] < 250 / 255) & (samples[2] > samples[3] + 0.05)
    samples = [s[keep] for s in samples]
    if samples[0].size < 200:
        raise CaptureError("too few unclipped pixels to measure the camera's tone curve", source="white",
                           hint="expose so that the white pattern is bright but not clipped")
    weights = [_interp_weights(s) for s in samples]

    def evaluate(table, k):
        lo, f = weights[k]
        return table[lo] * (1 - f) + table[lo + 1] * f

    start = np.log(np.maximum(np.diff(_srgb_table()), 1e-6))

    def residuals(x):
        table = _table_from(x[:-2])
        a0, a1 = math.exp(x[-2]), math.exp(x[-1])
        h0, h1, w, b = (evaluate(table, k) for k in range(4))
        ref = np.maximum(w - b, 1e-4)
        data = (a0 * (h0 - b) + a1 * (h1 - b) - (w - b)) / ref
        curvature = np.diff(np.log(np.maximum(np.diff(table), 1e-9)), 2)
        return np.concatenate([data / math.sqrt(data.size), SMOOTHNESS * curvature])

    x0 = np.concatenate([start, [0.0, 0.0]])
    fit = least_squares(residuals, x0, method="trf", x_scale=1.0, max_nfev=200)
    table = _table_from(fit.x[:-2])
    gains = (math.exp(fit.x[-2]), math.exp(fit.x[-1]))
    data = residuals(fit.x)[:samples[0].size] * math.sqrt(samples[0].size)
    rms = float(np.sqrt(np.mean(data ** 2)))
    # covariance of the table values from the Jacobian (data part scaled by its residual variance)
    jac = fit.jac
    try:
        cov = np.linalg.pinv(jac.T @ jac) * max(rms ** 2 / samples[0].size, 1e-12) * samples[0].size
        jt = np.empty((KNOTS, fit.x.size - 2))
        eps = 1e-5
        for i in range(fit.x.size - 2):
            x = fit.x[:-2].copy()
            x[i] += eps
            jt[:, i] = (_table_from(x) - table) / eps
        sigma = np.sqrt(np.maximum(np.diag(jt @ cov[:-2, :-2] @ jt.T), 0.0))
    except np.linalg.LinAlgError:
        sigma = np.full(KNOTS, np.nan)
    if not rms < 0.15:
        raise CaptureError(f"half-0 and half-1 do not add up to white (relative residual {rms:.2f})",
                           source="half-0", hint="photograph every pattern of this folder with a still camera "
                                                 "and locked exposure, and no pattern twice")
    return InverseResponse(table, gains, rms, sigma)


def block_medians(image: np.ndarray, block: int) -> np.ndarray:
    """Median of each ``block`` x ``block`` tile, per channel: uint8 (h // block, w // block, c).

    A median commutes with any monotone tone curve, so the median code value of a tile is the
    code of the tile's median light: noise averages out without the bias that averaging code
    values through a curved response would bring.
    """
    h, w, c = image.shape
    hh, ww = h // block, w // block
    tiles = image[:hh * block, :ww * block].reshape(hh, block, ww, block, c).transpose(0, 2, 4, 1, 3)
    return np.median(tiles.reshape(hh, ww, c, block * block), axis=3).astype(np.float32)


def linear_luma(photo: np.ndarray, response: InverseResponse, factor: int) -> np.ndarray:
    """float32 (h // factor, w // factor): linear R + G + B, area-averaged over ``factor`` x ``factor`` pixels."""
    import cv2

    linear = response.lut8()[photo].sum(axis=2, dtype=np.float32)
    h, w = linear.shape
    hh, ww = h // factor, w // factor
    return cv2.resize(linear[:hh * factor, :ww * factor], (ww, hh), interpolation=cv2.INTER_AREA)


@dataclasses.dataclass(frozen=True)
class Glare:
    """Veiling glare: ``fraction`` of the light spread as a Gaussian of ``sigma`` working pixels."""

    fraction: float
    sigma: float
    rms: float

    def to_dict(self) -> dict:
        return {"fraction": round(self.fraction, 5), "sigma_pixels": round(self.sigma, 2), "residual": round(self.rms, 6)}


def _blur(image: np.ndarray, sigma: float) -> np.ndarray:
    import cv2

    return cv2.GaussianBlur(image, (0, 0), sigma, borderType=cv2.BORDER_CONSTANT)


def fit_glare(lit: np.ndarray, outside: np.ndarray) -> Glare:
    """Glare from ``white - black`` (float32 (h, w), working pixels) seen ``outside`` the panel (bool (h, w)).

    ``lit`` is zeroed outside the panel and taken as the panel's own light; for each width in
    ``GLARE_SIGMAS`` the fraction is the least-squares scale of its blur onto ``lit`` outside;
    the width that fits best wins.
    """
    source = np.where(outside, 0.0, lit).astype(np.float32)
    target = lit[outside].astype(np.float64)
    if target.size < 500:
        return Glare(0.0, 0.0, math.nan)
    width = lit.shape[1]
    best = None
    for s in GLARE_SIGMAS:
        halo = _blur(source, s * width)[outside].astype(np.float64)
        fraction = float(np.dot(halo, target) / max(np.dot(halo, halo), 1e-30))
        rms = float(np.sqrt(np.mean((target - fraction * halo) ** 2)))
        if best is None or rms < best.rms:
            best = Glare(max(0.0, fraction), s * width, rms)
    return best


def remove_glare(image: np.ndarray, glare: Glare) -> np.ndarray:
    """``image`` (linear, black subtracted, float32 (h, w)) without its glare, to first order in the fraction."""
    if glare.fraction <= 0:
        return image
    return (image - glare.fraction * _blur(image, glare.sigma)) / (1.0 - glare.fraction)
