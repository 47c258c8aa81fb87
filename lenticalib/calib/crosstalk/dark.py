"""Photos clipped at zero: the bias it leaves in dark areas, measured on the black photo and undone.

A camera's sensor noise is symmetric, but a photo cannot hold negative light: a RAW converter
subtracts the black level and clips at 0, and a JPEG's code 0 is the least it can say.  Where the
light ``s`` is within a few noise sigmas of zero, the mean of the clipped pixels is

    f(s) = s Phi(s / sigma) + sigma phi(s / sigma)                 (Phi, phi: the normal's)

which is more than ``s`` (``0.40 sigma`` at ``s = 0``) and less so the brighter the place.  The
crosstalk measurement subtracts black from each band photo, so the faint tails of the view cone
(a few thousandths of white, where a noisy camera's sigma is about as large) came out short and
the own-view share high: a phone-like camera (1000 electrons at saturation, 8 electrons of read
noise) put a soft sheet's own-view share 0.011 high from linear photos, six times its sigma;
with 8000 electrons the same scene was 0.0006 off.

:func:`clipping_noise` measures ``sigma`` per channel on the black photo (blocks where 2-98 % of
the pixels are at 0: their share at 0 and their mean fix both the light and sigma of a clipped
normal); :func:`unclip` replaces each pixel by itself plus ``g(m) - m``, ``m`` the mean of the
``WINDOW`` x ``WINDOW`` pixels around it and ``g`` the inverse of ``f``, so that every average
taken afterwards over such areas is one of the light, not of the clipped light.  Only the read
noise is modelled (shot noise is small where clipping happens); where no block of the black
photo is clipped, nothing is changed.
"""

from __future__ import annotations

import numpy as np

WINDOW = 15  # photo pixels: the side of the area whose mean is un-clipped
BLOCK = 32  # photo pixels: the side of the black photo's blocks that sigma is measured on
MIN_BLOCKS = 20  # blocks with some pixels at 0 (and most not) needed to measure sigma
REACH = 5.0  # pixels whose area's mean is above this many sigma are left as they are
LOWEST = -1.5  # sigmas: the least light an area is given (light is not negative; an area's mean is noisy)


def _clipped_mean(t: np.ndarray) -> np.ndarray:
    """f(s) / sigma at ``t = s / sigma``."""
    from scipy.stats import norm

    return t * norm.cdf(t) + norm.pdf(t)


def clipping_noise(black: np.ndarray, zero: np.ndarray) -> np.ndarray | None:
    """float (channels,): the noise sigma of each channel of the black photo ``black`` (float
    (h, w, c), linear light) where it is clipped at 0 (``zero``: bool (h, w, c), the pixels at
    code 0); None where too few blocks are partly clipped to tell (then the photos need no
    correction, or cannot get one)."""
    from scipy.stats import norm

    h, w, c = black.shape
    hh, ww = h // BLOCK, w // BLOCK
    if hh * ww == 0:
        return None
    means = black[:hh * BLOCK, :ww * BLOCK].reshape(hh, BLOCK, ww, BLOCK, c).mean(axis=(1, 3))
    shares = zero[:hh * BLOCK, :ww * BLOCK].reshape(hh, BLOCK, ww, BLOCK, c).mean(axis=(1, 3))
    sigmas = []
    for k in range(c):
        p, m = shares[..., k].ravel(), means[..., k].ravel()
        use = (p > 0.02) & (p < 0.98) & (m > 0)
        if np.count_nonzero(use) < MIN_BLOCKS:
            return None
        t = -norm.ppf(p[use])  # s / sigma from the share at 0
        sigmas.append(float(np.median(m[use] / _clipped_mean(t))))
    return np.asarray(sigmas)


def unclip(image: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """float32 (h, w, c): ``image`` (linear light, clipped at 0) with each pixel moved by
    ``g(m) - m``, ``m`` its ``WINDOW`` x ``WINDOW`` area's mean in that channel (see the module's
    text); pixels whose area is brighter than ``REACH`` sigma unchanged."""
    import cv2

    t = np.linspace(LOWEST, REACH + 1.0, 2001)
    table = _clipped_mean(t)  # increasing
    out = image.astype(np.float32, copy=True)
    for k in range(image.shape[2]):
        s = float(sigma[k])
        if not s > 0:
            continue
        plane = out[..., k]
        mean = cv2.blur(plane, (WINDOW, WINDOW), borderType=cv2.BORDER_REFLECT)
        near = mean < REACH * s
        m = mean[near] / s
        plane[near] += (s * np.interp(m, table, t) - mean[near]).astype(np.float32)
    return out
