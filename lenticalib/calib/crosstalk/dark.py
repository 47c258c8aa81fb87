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

**Demosaiced photos.**  A RAW converter (dcraw, rawpy, darktable) clips the sensor's values at 0
*before* demosaicing: each channel holds its sensor's clipped values at its own sites of the
colour filter (one in four pixels for red and blue, two in four for green) and interpolations
elsewhere, which are seldom exactly 0 and, from an edge-aware demosaicing, biased (the direction
of the smaller difference is chosen, and among clipped noise that is the darker one: on the
bench's hard case 3 the black photo's green came out 620 at the red and blue sites and 793 at its
own, in 16-bit codes).  A clipped normal fitted to all pixels then took sigma 1.4-1.9 times too
small, and the far views' light came out 0.028 of white where the truth was 0.039.  So the
sensor's layout is found on the black photo (the Bayer layout whose red and blue phases stand out
in their channels' share of pixels at 0, :func:`filter_sites`), sigma is measured on each
channel's own sites, and the areas' light is taken from their means alone; a camera's JPEG shows
no such phases, and all of its pixels are used.  The sigma its pixels at 0 show is too small
(each pixel is interpolated from several clipped sites, fewer sit at 0: 0.4-0.7 of the raw photo's
on the bench's phone cameras), so a JPEG's sigma is read from the spread of its black photo's block
means instead, which its processing keeps (:func:`block_noise`; the pixels at 0 still say whether
the camera clips at all), and the measurement states what another one would change
(:func:`reclipped`).

:func:`clipping_noise` measures ``sigma`` per channel on the black photo (blocks where 2-98 % of
the pixels at the channel's sites are at 0: their share at 0 and their mean fix both the light
and sigma of a clipped normal); :func:`unclip` moves each pixel by ``g(m_s) - m``, ``m`` the mean
of the ``WINDOW`` x ``WINDOW`` pixels around it, ``m_s`` that of the channel's sites among them
and ``g`` the inverse of ``f``, so that every average taken afterwards over such areas is one of
the light, not of the clipped light.  Only the read noise is modelled (shot noise is small where
clipping happens); where no block of the black photo is clipped, nothing is changed.

**Zeros that are not noise.**  A block is taken only where its pixels above 0 spread as a normal
cut at 0 would (within 1.5 times), and the correction only where such blocks outnumber the blocks
all at 0 (noise around light that is not negative leaves at most half of a place's pixels at 0).
A noiseless black photo, the panel at exactly 0 in a dim room, had its edge blocks taken for
clipped noise with a sigma of the step's height (180 codes of 65535), and the correction wiped out
the faint floor of every band photo (the sheet's scatter, 18 codes): a noiseless set at 500 mm
measured its far views at 0 for the true 0.0250.  Now it makes no correction (0.0252); on the
bench's noisy black photos sigma moved by under 1 %.

**A JPEG's sigma, from its blocks** (:func:`block_noise`). :func:`clipping_noise` reads the noise
sigma of a clipped sensor from the share of the black photo's pixels at 0 at the sensor's own
sites. A camera JPEG shows no sites: each pixel is interpolated from several of them (demosaicing),
sharpened and compressed, fewer pixels sit at 0, and the sigma read that way came out 0.4-0.7 of
the raw photos' on the bench's phone cameras. The coarse detail survives all of it: the mean of a
``MEAN_BLOCK`` x ``MEAN_BLOCK`` area is the mean of the sensor's sites in it, whatever the
interpolation, the sharpening and the JPEG's fine frequencies did inside, so the spread of the
black photo's block means is the clipped noise of one site over the square root of the sites per
block (a Bayer sensor: a quarter of the pixels red, a quarter blue, half green; ``SITE_SHARES``).
From a block's mean ``m`` and the clipped sites' standard deviation ``s`` the clipped normal's
first two moments give the light ``mu`` under the clipping and the noise ``sigma``:

    m = sigma F1(a),   s^2 = sigma^2 (F2(a) - F1(a)^2),   a = mu / sigma
    F1(a) = a Phi(a) + phi(a),   F2(a) = (1 + a^2) Phi(a) + a phi(a)

(``s / m`` falls with ``a``: one value of ``a`` per ratio). A photo whose pixels are each a site (a
sensor without a colour filter mosaic, clipped pixel by pixel) shows ``s`` from one pixel to the
next, where interpolation and compression make neighbours alike and show less: the larger of the
two is taken. The spread is taken over the differences of neighbouring blocks, robustly (the median
absolute deviation), so that slow changes of the light (glare, vignetting) do not count, and ``m``
is the blocks' median.

On the bench's JPEGs through the cameras' true tone curves the sigma so read was 0.83-1.04 times
the raw photos' (read at the sensor's sites) where the black is clipped hard (hard cases 3, 13, 20,
23: 539-574 electrons at saturation) and 1.06-1.85 times where the black sits some sigmas above 0
(hard cases 1 and 4-12: the black photo's own texture adds to the spread; there the clipping
changes little). On a bare camera (``tests/test_crosstalk_dark_blocks.py``: OpenCV's edge-aware
demosaicing, no sharpening) red's and blue's came out 0.66-0.89 times the sensor's, green's
0.92-1.19: choosing the direction of the smaller difference smooths the interpolated colours'
blocks, the more the more of their sites sit at 0 (bilinear demosaicing: 0.88-0.93 in all three).
The measurement carries what the read leaves open (``SIGMA_RANGE``, :mod:`.measure`), and the bias
``m - mu`` is the light the black photo's clipping added (:meth:`BlockNoise.bias`: the tone curve's
relations, :func:`.tone_models.relations`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

WINDOW = 15  # photo pixels: the side of the area whose mean is un-clipped
BLOCK = 32  # photo pixels: the side of the black photo's blocks that sigma is measured on
MIN_BLOCKS = 20  # blocks with some pixels at 0 (and most not) needed to measure sigma, over the channels
MIN_CHANNEL_BLOCKS = 5  # ... and in a channel for its own sigma (fewer: the other channels' median)
REACH = 5.0  # pixels whose area's mean is above this many sigma are left as they are
LOWEST = -1.5  # sigmas: the least light an area is given (light is not negative; an area's mean is noisy)
SITE_CONTRAST = 1.5  # a Bayer layout is taken when its red and blue phases have this many times any other's zeros
MIN_ZERO_SHARE = 0.01  # ... and at least this share of their pixels at 0
NORMAL_SHAPE = np.log(1.5)  # a block's spread of its pixels above 0 within this (log) of a clipped normal's
ALL_PHASES = ((0, 0), (0, 1), (1, 0), (1, 1))  # the 2 x 2 phases (row % 2, column % 2)
MEAN_BLOCK = 16  # photo pixels: the side of the blocks whose means are compared (block_noise)
SITE_SHARES = (0.25, 0.5, 0.25)  # share of a Bayer sensor's sites per channel (R, G, B); one channel: all
MIN_NOISE_BLOCKS = 20  # blocks at least
SIGMA_RANGE = (0.54, 1.6)  # the sensor's sigma over the one read here, as far as the bench and the tests showed it (see above)
A_GRID = np.linspace(-3.0, 60.0, 4001)  # a = mu / sigma: the inversion's grid (from mostly clipped to far above 0)


def phase_mask(phases: tuple[tuple[int, int], ...], shape: tuple[int, int]) -> np.ndarray:
    """bool ``shape``: the pixels at the 2 x 2 ``phases`` ``(row % 2, column % 2)``."""
    mask = np.zeros(shape, bool)
    for i, j in phases:
        mask[i::2, j::2] = True
    return mask


@dataclass(frozen=True)
class ClippingNoise:
    """The black photo's clipping, per channel: ``sigma`` float (channels,), linear light; ``sites``
    tuple per channel of the 2 x 2 phases ``(row % 2, column % 2)`` holding the sensor's own
    values (all four where the photo shows no colour-filter structure)."""

    sigma: np.ndarray
    sites: tuple[tuple[tuple[int, int], ...], ...]

    def site_mask(self, k: int, shape: tuple[int, int]) -> np.ndarray | None:
        """bool (h, w): channel ``k``'s sites; None where they are all pixels."""
        return None if len(self.sites[k]) == 4 else phase_mask(self.sites[k], shape)


def _clipped_mean(t: np.ndarray) -> np.ndarray:
    """f(s) / sigma at ``t = s / sigma``."""
    return clipped_moments(t)[0]


def _inverse_table() -> tuple[np.ndarray, np.ndarray]:
    """(t, f(t)) on ``LOWEST .. REACH + 1`` sigmas, ``f`` increasing: ``np.interp(m, f, t)`` is the
    light (in sigmas) whose clipped mean is ``m``."""
    t = np.linspace(LOWEST, REACH + 1.0, 2001)
    return t, _clipped_mean(t)


def filter_sites(zero: np.ndarray) -> tuple[tuple[tuple[int, int], ...], ...]:
    """Per channel, the 2 x 2 phases ``(row % 2, column % 2)`` of a photo's pixels at 0 (``zero``:
    bool (h, w, 3)) that hold a Bayer sensor's own values.  Of the four Bayer layouts (red at one
    phase, blue at the opposite one, green at the other two), the one whose red and blue phases
    stand out most in their channels' share of pixels at 0 (at least ``SITE_CONTRAST`` times any
    other phase's, in both); green's own sites follow from it (its contrast is small: an
    interpolated green is the mean of two clipped values, at 0 nearly as often).  All four phases
    per channel where no layout stands out (a JPEG, a sensor of another layout, too few zeros)."""
    if zero.shape[2] != 3:
        return (ALL_PHASES,) * zero.shape[2]
    shares = np.array([[zero[i::2, j::2, k].mean() for i, j in ALL_PHASES] for k in range(3)])
    best, best_score = None, 0.0
    for r, (i, j) in enumerate(ALL_PHASES):
        b = ALL_PHASES.index((1 - i, 1 - j))
        if min(shares[0, r], shares[2, b]) < MIN_ZERO_SHARE:
            continue
        score = min(shares[0, r] / max(np.delete(shares[0], r).max(), 1e-12),
                    shares[2, b] / max(np.delete(shares[2], b).max(), 1e-12))
        if score > best_score:
            best, best_score = (ALL_PHASES[r], ALL_PHASES[b]), score
    if best is None or best_score < SITE_CONTRAST:
        return (ALL_PHASES,) * 3
    red, blue = best
    return ((red,), tuple(p for p in ALL_PHASES if p not in best), (blue,))


def clipping_noise(black: np.ndarray, zero: np.ndarray, sites: bool = True) -> ClippingNoise | None:
    """The noise sigma and filter sites of each channel of the black photo ``black`` (float
    (h, w, c), linear light) where it is clipped at 0 (``zero``: bool (h, w, c), the pixels at
    code 0); None where too few blocks are partly clipped to tell (then the photos need no
    correction, or cannot get one).  A channel with fewer than ``MIN_CHANNEL_BLOCKS`` of them gets
    the other channels' median (a JPEG's green, averaged over two sites of every four, sat at 0 in
    16 blocks of bench hard case 1, its red and blue in 70: the photos were left clipped and the
    far views came out 25 % short).  ``sites=False``: every pixel taken as a site (the model of
    photos clipped pixel by pixel, for comparison)."""
    from scipy.stats import norm

    h, w, c = black.shape
    hh, ww = h // BLOCK, w // BLOCK
    if hh * ww == 0:
        return None
    layout = filter_sites(zero) if sites else (ALL_PHASES,) * c

    def blocks(a: np.ndarray) -> np.ndarray:  # sums over BLOCK x BLOCK blocks
        return a[:hh * BLOCK, :ww * BLOCK].reshape(hh, BLOCK, ww, BLOCK).sum(axis=(1, 3))

    sigmas, counts = [], []
    for k in range(c):
        mask = phase_mask(layout[k], (h, w))
        count = blocks(mask.astype(np.float64))
        v = np.where(mask, black[..., k], 0.0).astype(np.float64)  # the sites' light (0 where clipped)
        total = blocks(v).ravel()
        m = total / count.ravel()
        p = (blocks(mask & zero[..., k]) / count).ravel()
        use = (p > 0.02) & (p < 0.98) & (m > 0)
        t = -norm.ppf(np.clip(p, 0.02, 0.98))  # s / sigma from the share at 0
        sigma = m / _clipped_mean(t)
        # the pixels above 0 of a clipped normal spread like a normal cut at 0: std sigma
        # sqrt(1 + a l - l^2), a = -t, l = phi(a) / (1 - Phi(a)); a block that is partly 0 for
        # another reason (the edge of a black area, noiseless photos) spreads them otherwise, and
        # its sigma would be the step's height
        n1 = np.maximum(blocks(mask & ~zero[..., k]), 1).ravel()
        spread = np.sqrt(np.maximum(blocks(v * v).ravel() / n1 - (total / n1) ** 2, 0.0))
        a = -t
        lam = norm.pdf(a) / np.maximum(norm.sf(a), 1e-12)
        expected = sigma * np.sqrt(np.maximum(1.0 + a * lam - lam ** 2, 1e-12))
        use &= np.abs(np.log(np.maximum(spread, 1e-30) / np.maximum(expected, 1e-30))) < NORMAL_SHAPE
        # noise around light that is not negative leaves at most half of a place's pixels at 0:
        # blocks all at 0 outnumbering the ones measured are a black that is 0 for another reason
        if np.count_nonzero(p >= 0.98) > np.count_nonzero(use):
            return None
        counts.append(int(np.count_nonzero(use)))
        sigmas.append(float(np.median(sigma[use])) if counts[-1] >= MIN_CHANNEL_BLOCKS else math.nan)
    measured = [v for v in sigmas if math.isfinite(v)]
    if sum(counts) < MIN_BLOCKS or not measured:
        return None
    if sites and all(tuple(p) == ALL_PHASES for p in layout):  # no sensor sites show: a camera JPEG
        coarse = block_noise(black)
        if coarse is not None:
            return ClippingNoise(coarse.sigma, layout)
    return ClippingNoise(np.asarray([v if math.isfinite(v) else float(np.median(measured)) for v in sigmas]), layout)


def unclip(image: np.ndarray, noise: ClippingNoise) -> np.ndarray:
    """float32 (h, w, c): ``image`` (linear light, clipped at 0) with each pixel moved by
    ``g(m_s) - m``, ``m`` its ``WINDOW`` x ``WINDOW`` area's mean in that channel and ``m_s`` the
    mean of the channel's filter sites in it (see the module's text); pixels whose area is brighter
    than ``REACH`` sigma unchanged."""
    import cv2

    t, table = _inverse_table()
    out = image.astype(np.float32, copy=True)
    h, w = image.shape[:2]
    for k in range(image.shape[2]):
        s = float(noise.sigma[k])
        if not s > 0:
            continue
        plane = out[..., k]
        mean = cv2.blur(plane, (WINDOW, WINDOW), borderType=cv2.BORDER_REFLECT)
        mask = noise.site_mask(k, (h, w))
        if mask is None:
            site_mean = mean
        else:
            share = cv2.blur(mask.astype(np.float32), (WINDOW, WINDOW), borderType=cv2.BORDER_REFLECT)
            site_mean = cv2.blur(np.where(mask, plane, 0.0).astype(np.float32), (WINDOW, WINDOW),
                                 borderType=cv2.BORDER_REFLECT) / share
        near = site_mean < REACH * s
        m = site_mean[near] / s
        plane[near] += (s * np.interp(m, table, t) - mean[near]).astype(np.float32)
    return out


def reclipped(light: np.ndarray, sigma: float, scale: float, channels: int = 3) -> np.ndarray:
    """``light`` (working pixels: the sum of ``channels`` channels, each unclipped with noise ``sigma``
    by :func:`unclip`) as it would have come out unclipped with ``scale`` times that sigma: each
    channel taken as ``light / channels``, clipped again (``f`` at ``sigma``) and unclipped at
    ``scale sigma``.  Places above ``REACH`` sigma are unchanged.  How the measurement states what
    a JPEG's noise sigma leaves open (``measure``: the sigma read from its blocks, :func:`block_noise`).

    ``f`` and its inverse hold for the mean light of an area, not for a noisy pixel: an image
    (2-D) is moved, pixel by pixel, by the change of its ``WINDOW`` x ``WINDOW`` area's mean, as
    :func:`unclip` moves it (taken pixel by pixel, the curvature of ``f`` on each pixel's noise took
    light off the dark places: hard case 13's far views 0.029 for 0.048 at the right sigma, 0.042
    with the areas' means); a 1-D ``light`` holds such means already."""
    import cv2

    if not (sigma > 0 and scale > 0) or scale == 1.0:
        return light
    t, table = _inverse_table()
    full = np.asarray(light, np.float64)
    x = (cv2.blur(full, (WINDOW, WINDOW), borderType=cv2.BORDER_REFLECT) if full.ndim == 2 else full) / channels
    clipped = sigma * _clipped_mean(np.clip(x / sigma, LOWEST, None))
    u = clipped / (scale * sigma)
    wider = np.where(u < table[-1], scale * sigma * np.interp(u, table, t), clipped)  # f(t) = t far above 0
    near = x < REACH * max(sigma, scale * sigma)
    return np.where(near, full + channels * (wider - x), full).astype(np.asarray(light).dtype)


def block_read_sigma(noise) -> float:
    """The mean noise sigma of the channels (linear light, per channel) where the photos were
    unclipped (:func:`unclip`) with a sigma read without the sensor's sites (a camera JPEG: from
    its blocks' spread, :func:`block_noise`, which leaves it open by ``SIGMA_RANGE``); 0 where
    none was needed or the sites were found."""
    if noise is None or any(tuple(sites) != ALL_PHASES for sites in noise.sites):
        return 0.0
    return float(np.mean(noise.sigma))


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


def block_noise(black: np.ndarray, block: int = MEAN_BLOCK) -> BlockNoise | None:
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
        m = black[:hh * block, :ww * block, k].reshape(hh, block, ww, block).mean(axis=(1, 3), dtype=np.float64)
        # each direction's steps less their median (a slope of the light moves them all alike)
        steps = np.concatenate([d.ravel() - np.median(d) for d in (m[:, 1:] - m[:, :-1], m[1:] - m[:-1])])
        spread = 1.4826 * float(np.median(np.abs(steps))) / np.sqrt(2.0)  # of one block mean
        mean = float(np.median(m))
        if not (spread > 0 and mean > 0):
            return None
        # of one site; a photo whose pixels are each a site (no demosaicing) shows it pixel to pixel
        pixel = float(np.std(np.diff(black[:, :, k], axis=1), dtype=np.float64)) / np.sqrt(2.0)
        s = max(spread * np.sqrt(shares[k] * block * block), pixel)
        a = float(np.interp(s / mean, ratio[::-1], A_GRID[::-1]))  # ratio beyond the grid: its end
        sigma = mean / float(np.interp(a, A_GRID, f1))
        sigmas.append(sigma)
        means.append(mean)
        lights.append(a * sigma)
    return BlockNoise(np.asarray(sigmas), np.asarray(means), np.asarray(lights))
