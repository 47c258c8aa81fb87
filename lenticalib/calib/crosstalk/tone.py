"""The camera's tone curve, measured from the crosstalk photos themselves (``docs/crosstalk.md``).

A camera JPEG is not linear light, and not quite sRGB either: a camera's picture style bends the
curve by several per cent, which moves the measured view cone by a few hundredths.  The two half
patterns light complementary halves of the views, so in linear light, at every camera pixel,

    half-0 + half-1 = white + black

(each photo holds the panel's black level once).  Where the band of either half passes the camera
(the edges of its lit region, a view or two wide, swept across the panel) both halves are partly
lit, and the relation fixes how the curve bends between black and white.

The relation holds for the light of a pixel, not for its code: each photo is linearised pixel by
pixel with a candidate curve and averaged over small tiles (``tile`` x ``tile`` photo pixels, all
three channels) before the halves are compared.  Each tile's code histogram is kept (a sparse
matrix, tiles x 256 codes), so a tile's mean light under any curve is one matrix product.

The curve: ``L(c) = D(c) ** p``, with ``D`` the sRGB decoding of the 8-bit code ``c`` (linear light
in units of the camera's saturation) and ``p`` the fitted power (1 = plain sRGB); each half photo
also gets its own exposure (a camera whose exposure drifts).  ``p``'s 1-sigma is the spread of the
powers fitted to ``GROUPS`` strips of the panel, over the square root of their number, with a
floor for what a power cannot describe.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...core.colour import srgb_decode_lut

PHOTOS = ("black", "white", "half-0", "half-1")  # the photos the curve is measured on
TILE_PER_WIDTH = 200  # tiles across the photo (about): 8 photo pixels at 1600 wide
GROUPS = 8  # strips of rows of the panel fitted on their own, for the power's spread
MIN_TILES = 400  # tiles where both halves are partly lit, at least (fewer: no fit)
MAX_TILES = 40000  # tiles used at most (drawn with a fixed seed)
POWER_RANGE = (0.6, 1.6)
POWER_FLOOR = 0.01  # 1-sigma the power family leaves for any camera (its curve is not exactly sRGB ** p)
MAX_RESIDUAL = 0.15  # relative RMS of half-0 + half-1 - white - black above which the photos do not add up


@dataclasses.dataclass(frozen=True)
class ToneCurve:
    """A fitted tone curve ``L(c) = D(c) ** power``: ``sigma`` the power's 1-sigma; ``residual`` the
    relative RMS of the half relation at the best power; ``tiles`` how many tiles it rests on;
    ``groups`` the powers of the strips."""

    power: float
    sigma: float
    residual: float
    tiles: int
    groups: tuple[float, ...] = ()

    def lut(self) -> np.ndarray:
        """float32 (256,): the linear light of each 8-bit code."""
        return decode_lut(self.power)

    def to_dict(self) -> dict:
        return {"model": "sRGB decoding ** power", "power": round(self.power, 4), "power_sigma": round(self.sigma, 4),
                "half_residual": round(self.residual, 4), "tiles": self.tiles,
                "strip_powers": [round(p, 4) for p in self.groups]}


def tile_size(width: int) -> int:
    """Side of the tiles (photo pixels) for photos ``width`` pixels wide: at least 4."""
    return max(4, int(round(width / TILE_PER_WIDTH)))


def decode_lut(power: float = 1.0) -> np.ndarray:
    """float32 (256,): sRGB-decoded light of each 8-bit code, to the power ``power``."""
    return (srgb_decode_lut() ** power).astype(np.float32)


def tile_means(image: np.ndarray, tile: int) -> np.ndarray:
    """float32 (h // tile, w // tile): mean code of each tile over its pixels and channels (uint8 (h, w, c) in)."""
    h, w, c = image.shape
    hh, ww = h // tile, w // tile
    blocks = image[:hh * tile, :ww * tile].reshape(hh, tile, ww, tile, c)
    return blocks.mean(axis=(1, 3, 4), dtype=np.float32)


def tile_histograms(image: np.ndarray, tile: int, picked: np.ndarray):
    """scipy CSR (len(picked), 256): how many of each code the ``picked`` tiles hold (flat tile indices
    of the (h // tile, w // tile) grid), over their ``tile`` x ``tile`` pixels and all channels."""
    from scipy.sparse import csr_matrix

    h, w, c = image.shape
    hh, ww = h // tile, w // tile
    ty, tx = np.divmod(picked, ww)
    dy, dx = np.mgrid[0:tile, 0:tile]
    rows = (ty[:, None, None] * tile + dy[None]).reshape(len(picked), -1)
    cols = (tx[:, None, None] * tile + dx[None]).reshape(len(picked), -1)
    codes = image[rows, cols].reshape(len(picked), -1).astype(np.int64)
    index = np.repeat(np.arange(len(picked)), codes.shape[1])
    data = np.ones(codes.size, np.float32) / codes.shape[1]
    return csr_matrix((data, (index, codes.ravel())), shape=(len(picked), 256))


def _residual(power, hist, weights):
    """(relative RMS, gains (2,)) of ``a0 half-0 + a1 half-1 = white + black`` under ``D ** power``."""
    lut = decode_lut(power).astype(np.float64)
    means = {k: v @ lut for k, v in hist.items()}
    lit = means["white"] - means["black"]
    y = (means["white"] + means["black"]) / lit
    a = np.stack([means["half-0"] / lit, means["half-1"] / lit], axis=1)
    gains, *_ = np.linalg.lstsq(a * weights[:, None], y * weights, rcond=None)
    resid = (a @ gains - y) * weights
    return float(np.sqrt(np.mean(resid ** 2) / np.mean(weights ** 2))), gains


def _best_power(hist, weights) -> tuple[float, float]:
    from scipy.optimize import minimize_scalar

    grid = np.linspace(*POWER_RANGE, 21)
    values = [_residual(p, hist, weights)[0] for p in grid]
    i = int(np.argmin(values))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    best = minimize_scalar(lambda p: _residual(p, hist, weights)[0], bounds=(lo, hi), method="bounded",
                           options={"xatol": 1e-4})
    return float(best.x), float(best.fun)


def fit_tone_curve(images: dict[str, np.ndarray], tile: int) -> ToneCurve | None:
    """The tone curve from uint8 RGB photos ``images`` of "black", "white", "half-0", "half-1"
    (photo pixels, (h, w, 3)); ``tile``: side of the tiles in photo pixels.  None where the halves
    give too little to fit (fewer than ``MIN_TILES`` tiles where both are partly lit)."""
    means = {k: tile_means(v, tile) for k, v in images.items()}
    lit = means["white"] - means["black"]
    level = np.percentile(lit, 95)
    if not level > 0:
        return None
    white_max = tile_max(images["white"], tile)
    inside = (lit > 0.3 * level) & (white_max < 250)
    share0 = (means["half-0"] - means["black"]) / np.maximum(lit, 1e-6)
    share1 = (means["half-1"] - means["black"]) / np.maximum(lit, 1e-6)
    # in codes: a tile whose halves are each lit by 5-95 % of white's code (the bend shows there)
    mixed = inside & (share0 > 0.05) & (share1 > 0.05) & (share0 < 0.95) & (share1 < 0.95)
    picked = np.flatnonzero(mixed.ravel())
    if picked.size < MIN_TILES:
        return None
    if picked.size > MAX_TILES:
        picked = np.sort(np.random.default_rng(0).choice(picked, MAX_TILES, replace=False))
    hist = {k: tile_histograms(v, tile, picked) for k, v in images.items()}
    weights = np.ones(picked.size)
    power, residual = _best_power(hist, weights)
    rows = picked // lit.shape[1]
    edges = np.quantile(rows, np.linspace(0, 1, GROUPS + 1))
    group = np.clip(np.searchsorted(edges, rows, side="right") - 1, 0, GROUPS - 1)
    powers = []
    for g in range(GROUPS):
        sel = group == g
        if sel.sum() >= MIN_TILES // GROUPS:
            powers.append(_best_power({k: v[sel] for k, v in hist.items()}, weights[sel])[0])
    spread = float(np.std(powers, ddof=1)) / math.sqrt(len(powers)) if len(powers) > 2 else abs(power - 1.0)
    sigma = math.sqrt(spread ** 2 + POWER_FLOOR ** 2)
    return ToneCurve(power, sigma, residual, int(picked.size), tuple(powers))


def tile_max(image: np.ndarray, tile: int) -> np.ndarray:
    """uint8 (h // tile, w // tile): the largest code of each tile over its pixels and channels."""
    h, w, c = image.shape
    hh, ww = h // tile, w // tile
    return image[:hh * tile, :ww * tile].reshape(hh, tile, ww, tile, c).max(axis=(1, 3, 4))
