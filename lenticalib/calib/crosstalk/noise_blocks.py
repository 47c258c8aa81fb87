"""The sensor's clipped noise read from a photo's coarse detail: what a camera JPEG keeps of it.

Frames and units: photo pixels; light linear (the units of the photo's tone curve, per channel).

:func:`.dark.clipping_noise` reads the noise sigma of a clipped sensor from the share of the black
photo's pixels at 0 at the sensor's own sites.  A camera JPEG shows no sites: each pixel is
interpolated from several of them (demosaicing), sharpened and compressed, fewer pixels sit at 0,
and the sigma read that way came out 0.4-0.7 of the raw photos' on the bench's phone cameras.  The
coarse detail survives all of it: the mean of a ``BLOCK`` x ``BLOCK`` area is the mean of the
sensor's sites in it, whatever the interpolation, the sharpening and the JPEG's fine frequencies
did inside, so the spread of the black photo's block means is the clipped noise of one site over
the square root of the sites per block (a Bayer sensor: a quarter of the pixels red, a quarter
blue, half green; ``SITE_SHARES``).  From a block's mean ``m`` and the clipped sites' standard
deviation ``s`` the clipped normal's first two moments give the light ``mu`` under the clipping
and the noise ``sigma``:

    m = sigma F1(a),   s^2 = sigma^2 (F2(a) - F1(a)^2),   a = mu / sigma
    F1(a) = a Phi(a) + phi(a),   F2(a) = (1 + a^2) Phi(a) + a phi(a)

(``s / m`` falls with ``a``: one value of ``a`` per ratio).  A photo whose pixels are each a
site (a sensor without a colour filter mosaic, clipped pixel by pixel) shows ``s`` from one pixel
to the next, where interpolation and compression make neighbours alike and show less: the larger
of the two is taken.  The spread is taken over the
differences of neighbouring blocks, robustly (the median absolute deviation), so that slow changes
of the light (glare, vignetting) do not count, and ``m`` is the blocks' median.

On the bench's JPEGs through the cameras' true tone curves the sigma so read was 0.83-1.04 times
the raw photos' (read at the sensor's sites) where the black is clipped hard (hard cases 3, 13,
20, 23: 539-574 electrons at saturation) and 1.06-1.85 times where the black sits some sigmas above
0 (hard cases 1 and 4-12: the black photo's own texture adds to the spread; there the clipping
changes little).  On a bare camera (``tests/test_crosstalk_noise_blocks.py``: OpenCV's edge-aware
demosaicing, no sharpening) red's and blue's came out 0.66-0.89 times the sensor's, green's
0.92-1.19: choosing the direction of the smaller difference smooths the interpolated colours' blocks,
the more the more of their sites sit at 0 (bilinear demosaicing: 0.88-0.93 in all three).  The measurement carries what the read leaves open (``SIGMA_RANGE``,
:mod:`.measure`), and the bias ``m - mu`` is the light the black photo's clipping added
(:meth:`BlockNoise.bias`: the tone curve's relations, :mod:`.tone`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BLOCK = 16  # photo pixels: the side of the blocks whose means are compared
SITE_SHARES = (0.25, 0.5, 0.25)  # share of a Bayer sensor's sites per channel (R, G, B); one channel: all
MIN_NOISE_BLOCKS = 20  # blocks at least
SIGMA_RANGE = (0.54, 1.6)  # the sensor's sigma over the one read here, as far as the bench and the tests showed it (see above)
A_GRID = np.linspace(-3.0, 60.0, 4001)  # a = mu / sigma: the inversion's grid (from mostly clipped to far above 0)


@dataclass(frozen=True)
class BlockNoise:
    """The black photo's clipped noise per channel: ``sigma`` (c,), the mean of its pixels ``mean``
    (c,) and the light under the clipping ``light`` (c,), all linear light."""

    sigma: np.ndarray
    mean: np.ndarray
    light: np.ndarray

    def bias(self) -> np.ndarray:
        """float (c,): the light the clipping added to the photo's mean, per channel (``mean - light``)."""
        return self.mean - self.light


def clipped_moments(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F1, F2) of the normal clipped at 0 at ``a = mu / sigma``: its mean over sigma and its second
    moment over sigma^2 (``a`` any array shape; the same shape back)."""
    from scipy.stats import norm

    cdf, pdf = norm.cdf(a), norm.pdf(a)
    return a * cdf + pdf, (1.0 + a * a) * cdf + a * pdf


def block_noise(black: np.ndarray, block: int = BLOCK) -> BlockNoise | None:
    """The clipped noise of the black photo ``black`` (float (h, w, c), linear light) from the spread
    of its ``block`` x ``block`` means (see the module's text); None where it has fewer than
    ``MIN_NOISE_BLOCKS`` blocks or a channel shows no spread or no light (nothing to read)."""
    h, w, channels = black.shape
    hh, ww = h // block, w // block
    if hh * ww < MIN_NOISE_BLOCKS or min(hh, ww) < 2:
        return None
    f1, f2 = clipped_moments(A_GRID)
    ratio = np.sqrt(np.maximum(f2 - f1 ** 2, 1e-300)) / f1  # s / m, falling with a
    shares = SITE_SHARES if channels == 3 else (1.0,) * channels
    sigmas, means, lights = [], [], []
    for k in range(channels):
        m = black[:hh * block, :ww * block, k].astype(np.float64).reshape(hh, block, ww, block).mean(axis=(1, 3))
        # each direction's steps less their median (a slope of the light moves them all alike)
        steps = np.concatenate([d.ravel() - np.median(d) for d in (m[:, 1:] - m[:, :-1], m[1:] - m[:-1])])
        spread = 1.4826 * float(np.median(np.abs(steps))) / np.sqrt(2.0)  # of one block mean
        mean = float(np.median(m))
        if not (spread > 0 and mean > 0):
            return None
        # of one site; a photo whose pixels are each a site (no demosaicing) shows it pixel to pixel
        pixel = float(np.std(np.diff(black[:, :, k].astype(np.float64), axis=1))) / np.sqrt(2.0)
        s = max(spread * np.sqrt(shares[k] * block * block), pixel)
        a = float(np.interp(s / mean, ratio[::-1], A_GRID[::-1]))  # ratio beyond the grid: its end
        sigma = mean / float(np.interp(a, A_GRID, f1))
        sigmas.append(sigma)
        means.append(mean)
        lights.append(a * sigma)
    return BlockNoise(np.asarray(sigmas), np.asarray(means), np.asarray(lights))
