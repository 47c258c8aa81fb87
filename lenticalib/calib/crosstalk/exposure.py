"""Each crosstalk photo's exposure, from the registration frame every pattern carries (``docs/crosstalk.md``).

Frames and units: *frame pixels* (the photo area-averaged by ``factor``, about ``WIDTH`` across);
light linear through a tone table (units of its code 255), summed over the three channels.

A phone's exposure drifts by a few per cent from photo to photo even when the user tried to lock
it, and the tone curve's relations (:mod:`.tone`: ``half-0 + half-1 = white + black`` and the
levels) hold only in light at one exposure: a 4 % drift moves their sum as much as a power error
of 0.05 does.  Every pattern shows the same evenly lit registration frame (``FRAME_LEVEL`` on all
subpixels), so the frame's light in photo ``k`` is its exposure ``e_k`` times the same light, plus
what the panel's inside throws onto it: the camera's veiling glare, the panel's own scatter and
the blur of the inside's edge (a white photo puts 3-7 % of the frame's light onto the frame, a
band photo almost none; read as exposure, white comes out that much too bright).  That light
has no shape a model can be trusted with (on the bench a steep spill across the frame's inner
half on top of a wide halo; a one-Gaussian halo fitted beside the exposures took white's 2-11 %
off), but it is smooth where the frame meets the bezel, while the frame's own light steps down
there.  So the exposure is read on that step: across the frame's outer edge, from ``INNER`` of
the frame's width inside it to ``OUTER`` outside, in ``SECTORS`` sectors around the panel, each
photo's light averaged in bins of the signed distance ``d`` to the edge (the frame's texture, the
lens sheet's moire, averages out along the edge: read pixel by pixel against another photo's
texture, a shake of a fifth of a pixel took 2-3 % off a photo's scale), and fitted in each sector as

    L_k(d) = a_ks + b_ks d + h_ks [d < 0]

leaving out ``GAP_PIXELS`` on either side of the edge (its blur and the shake): ``a + b d`` is
whatever smooth light falls there, ``h_ks`` the step.  A photo's exposure over black's is the sum of
its steps over black's; its 1-sigma the spread of the sectors' ratios over sqrt(sectors).  Pixels
crushed to black or clipped in any photo are left out (no light can be read there); with fewer
than half the sectors read, or the sectors' steps disagreeing with one scale per photo by more
than ``MAX_RESIDUAL`` of the step (0.003-0.015 on the bench), there is no estimate: hard case 3,
whose S-curve crushes the bezel to codes 0-20, read anyway gave exposures up to 20 % off.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .photometry import lit_region, working


WIDTH = 1000  # frame pixels across the photo (about)
FRAME_SHARE = 1.0 / 38.0  # the frame's width over the inside's height (FRAME_FRACTION / (1 - 2 FRAME_FRACTION))
INNER = 0.6  # the pixels used: this share of the frame's width inside its outer edge (the inside's spill beyond)
OUTER = 1.0  # ... and this share of it outside
SECTORS = 32  # sectors around the panel, each with its own smooth light
MIN_PIXELS = 400  # pixels across the outer edge at least (fewer: no estimate)
CODE_RANGE = (8, 247)  # codes between which each channel of a pixel is read (its mean over the pixel's photo pixels)
MAX_RESIDUAL = 0.05  # relative RMS of the sectors' steps about one scale per photo above which there is no estimate
DRIFT_RANGE = (0.006, 0.012)  # RMS drift over which the exposures go from ignored to undone (Exposures.applied)
BIN = 0.5  # frame pixels: the bins of the distance to the edge the light is averaged in
GAP_PIXELS = 4.0  # photo pixels on either side of the edge left out (its blur and the shake)


@dataclasses.dataclass(frozen=True)
class Exposures:
    """``relative``: each photo's exposure over white's, with its 1-sigma ``sigma`` (from the
    spread of the sectors); ``rms``: the fit's residual over the frame's light; ``pixels``: frame
    pixels used; ``factor``: photo pixels per frame pixel."""

    relative: dict[str, float]
    sigma: dict[str, float]
    rms: float
    pixels: int
    factor: int

    def drift(self) -> float:
        """RMS of the exposures about their median (relative)."""
        values = np.array(list(self.relative.values()))
        return float(np.sqrt(np.mean((values / np.median(values) - 1.0) ** 2)))

    def applied_weight(self) -> float:
        """0..1: how much of the measured drift is undone, rising over ``DRIFT_RANGE`` (an exposure
        that held reads a few tenths of a per cent of drift through an imperfect tone curve, which
        undone would only add that error)."""
        lo, hi = DRIFT_RANGE
        return float(np.clip((self.drift() - lo) / (hi - lo), 0.0, 1.0))

    def applied(self) -> dict[str, float]:
        """The exposures the photos are divided by: ``1 + weight (relative - 1)``."""
        weight = self.applied_weight()
        return {k: 1.0 + weight * (v - 1.0) for k, v in self.relative.items()}

    def to_dict(self) -> dict:
        return {"relative_to_white": {k: round(v, 5) for k, v in self.relative.items()},
                "drift_rms": round(self.drift(), 5), "applied_weight": round(self.applied_weight(), 3),
                "sigma": {k: round(v, 5) for k, v in self.sigma.items()},
                "relative_residual": round(self.rms, 5), "pixels": self.pixels, "photo_pixels_per_pixel": self.factor}


@dataclasses.dataclass(frozen=True)
class FrameEdge:
    """Where the frame's outer edge is read, found once for a set of photos: ``factor`` photo pixels
    per frame pixel; ``used`` bool (h, w) the frame pixels read; ``index`` (n,) each used pixel's
    bin; ``counts``, ``d``, ``sector`` per bin: pixels, mean signed distance (frame pixels, +
    outside), sector."""

    factor: int
    used: np.ndarray
    index: np.ndarray
    counts: np.ndarray
    d: np.ndarray
    sector: np.ndarray


def _light(image: np.ndarray, table: np.ndarray, factor: int) -> np.ndarray:
    """float32 (h, w): the light of uint8 (uint16) RGB ``image`` through ``table`` (256 (65536)
    entries), summed over the channels, in frame pixels."""
    return working(table[image].sum(axis=2), factor)


def _edge(black: np.ndarray, white: np.ndarray):
    """(signed distance (frame pixels, + outside) to the frame's outer edge, sector index, frame
    width) or None: the panel's inside is where white clearly exceeds black, the frame the ring
    around it that is bright in the black photo."""
    import cv2

    inside = lit_region(white - black, blur=3)
    if inside is None:
        return None
    rows, cols = np.nonzero(inside)
    frame = max(3.0, FRAME_SHARE * (rows.max() - rows.min() + 1))
    beyond = cv2.distanceTransform((~inside).astype(np.uint8), cv2.DIST_L2, 5)
    near = (beyond > 0) & (beyond < 1.6 * frame)
    smooth = cv2.blur(black.astype(np.float32), (3, 3))
    if near.sum() < MIN_PIXELS:
        return None  # the panel fills the photo: no frame to be seen
    high, low = np.percentile(smooth[near], [90, 5])
    if not high > 2 * max(low, 0.0):
        return None  # nothing bright around the inside: no frame
    panel = inside | (near & (smooth > 0.5 * (high + low)))
    panel = cv2.morphologyEx(panel.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(panel, connectivity=8)
    panel = (labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))).astype(np.uint8)
    signed = cv2.distanceTransform(1 - panel, cv2.DIST_L2, 5) - cv2.distanceTransform(panel, cv2.DIST_L2, 5)
    yy, xx = np.indices(black.shape)
    angle = np.arctan2(yy - rows.mean(), xx - cols.mean())
    sector = np.minimum(((angle + math.pi) / (2 * math.pi) * SECTORS).astype(np.int64), SECTORS - 1)
    return signed, sector, frame


def frame_edge(images: dict[str, np.ndarray], table: np.ndarray,
               code_range: tuple[int, int] = CODE_RANGE) -> FrameEdge | None:
    """Where the frame's outer edge of uint8 RGB photos ``images`` ((h, w, 3), all the same size,
    "black" and "white" among them, linearised through ``table``) can be read; None where it
    cannot (no frame, or fewer than ``MIN_PIXELS`` readable pixels)."""
    table = np.asarray(table, np.float64)
    factor = max(1, int(round(images["white"].shape[1] / WIDTH)))
    found = _edge(_light(images["black"], table, factor), _light(images["white"], table, factor))
    if found is None:
        return None
    signed, sector, frame = found
    readable = np.ones(signed.shape, bool)
    lo, hi = code_range
    for v in images.values():
        means = working(v, factor)[:signed.shape[0], :signed.shape[1]]
        readable &= np.all((means >= lo) & (means <= hi), axis=2)
    used = readable & (signed >= -max(2.0, INNER * frame)) & (signed <= max(3.0, OUTER * frame))
    if used.sum() < MIN_PIXELS:
        return None
    # the frame's texture (the lens sheet's moire) averaged out along the edge: the light of each
    # sector in bins of the distance (a photo shaken by a fifth of a pixel against another keeps the
    # step but not the texture, which would take its scale down by 2-3 %)
    d, s = signed[used], sector[used]
    key = s * 10_000 + np.round(d / BIN).astype(np.int64) + 5_000
    keys, index, counts = np.unique(key, return_inverse=True, return_counts=True)
    return FrameEdge(factor, used, index, counts, np.bincount(index, d, keys.size) / counts, keys // 10_000)


def measure_exposures(images: dict[str, np.ndarray], table: np.ndarray, edge: FrameEdge | None = None) -> Exposures | None:
    """Each photo's exposure over white's, from uint8 RGB photos ``images`` ((h, w, 3), all the
    same size, "black" and "white" among them) linearised through ``table`` (float (256,)), read
    where ``edge`` says (default: :func:`frame_edge` of the photos); None where the frame's outer
    edge cannot be read (see :func:`frame_edge`), or the sectors disagree by more than ``MAX_RESIDUAL``."""
    table = np.asarray(table, np.float64)
    edge = frame_edge(images, table) if edge is None else edge
    if edge is None:
        return None
    names = list(images)
    bins = edge.counts.size
    targets = np.stack([np.bincount(edge.index, _light(images[k], table, edge.factor)[edge.used], bins) / edge.counts
                        for k in names], axis=1)  # (bins, K)
    # each sector's step: the light on either side of the edge, the pixels of the step's own blur
    # and shake left out, as one line (whatever smooth light falls there) plus a step down at d = 0
    gap = max(GAP_PIXELS / edge.factor, 1.5)
    heights = np.full((SECTORS, len(names)), np.nan)
    for sector_index in range(SECTORS):
        sel = (edge.sector == sector_index) & (np.abs(edge.d) >= gap)
        if np.count_nonzero(sel & (edge.d < 0)) < 2 or np.count_nonzero(sel & (edge.d > 0)) < 2:
            continue
        weight = np.sqrt(edge.counts[sel])[:, None]
        a = np.stack([np.ones(sel.sum()), edge.d[sel], (edge.d[sel] < 0).astype(np.float64)], axis=1) * weight
        coef, *_ = np.linalg.lstsq(a, targets[sel] * weight, rcond=None)
        heights[sector_index] = coef[2]
    black = names.index("black")
    ok = np.all(np.isfinite(heights), axis=1) & (heights[:, black] > 0)
    if ok.sum() < SECTORS // 2:
        return None
    rho = heights[ok].sum(axis=0) / heights[ok, black].sum()
    white = float(rho[names.index("white")])
    if not white > 0:
        return None
    # the residual: how far the sectors' steps disagree with one scale per photo; the 1-sigma of
    # each photo's exposure from that disagreement (the sectors are independent reads)
    residual = heights[ok] - np.outer(heights[ok, black], rho)
    rms = float(np.sqrt(np.mean(residual ** 2))) / max(float(np.mean(heights[ok, black])), 1e-12)
    if not rms <= MAX_RESIDUAL:
        return None
    ratios = heights[ok] / heights[ok, black][:, None]
    sigma = np.std(ratios / ratios[:, [names.index("white")]], axis=0, ddof=1) / math.sqrt(ok.sum())
    return Exposures({k: float(r) / white for k, r in zip(names, rho)}, {k: float(v) for k, v in zip(names, sigma)},
                     rms, int(edge.used.sum()), edge.factor)


def measure_each(images: dict[str, np.ndarray], table: np.ndarray, names,
                 code_range: tuple[int, int] = CODE_RANGE) -> Exposures | None:
    """The exposures over white's of the photos ``names`` among RGB ``images`` (uint8, or uint16 with
    a 65536-entry ``table`` and its ``code_range``; with "black" and "white"), each read with black
    and white alone (:func:`measure_exposures` on its own readable frame pixels: photos that light
    the frame's inner side each in their own places, the band sweeps, follow one scale per photo
    over all of them less well, a relative residual of 0.055 against 0.03-0.036 one at a time);
    black's the mean of its reads.  None where any cannot be read."""
    relative, sigma, rms, pixels, factor, blacks = {}, {}, 0.0, None, 1, []
    for name in names:
        three = {k: images[k] for k in ("black", "white", name)}
        found = measure_exposures(three, table, frame_edge(three, table, code_range))
        if found is None:
            return None
        relative[name], sigma[name] = found.relative[name], found.sigma[name]
        blacks.append((found.relative["black"], found.sigma["black"]))
        rms, factor = max(rms, found.rms), found.factor
        pixels = found.pixels if pixels is None else min(pixels, found.pixels)
    if not blacks:
        return None
    relative["black"] = float(np.mean([b for b, _ in blacks]))
    sigma["black"] = float(np.sqrt(np.mean([s ** 2 for _, s in blacks])))
    relative["white"], sigma["white"] = 1.0, 0.0
    return Exposures(relative, sigma, rms, int(pixels), factor)
