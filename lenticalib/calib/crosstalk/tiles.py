"""Photo tiles for the tone curve: the tile side for a photo, each tile's mean and largest code, code histograms.

A photo (uint8 (h, w, c)) is cut into ``tile`` x ``tile`` pixel tiles on a (h // tile, w // tile)
grid (the last partial row and column of tiles dropped); :mod:`.tone` compares the photos tile by
tile (``docs/crosstalk.md``).
"""

from __future__ import annotations

import numpy as np

TILE_PER_WIDTH = 200  # tiles across the photo (about): 8 photo pixels at 1600 wide


def tile_size(width: int) -> int:
    """Side of the tiles (photo pixels) for photos ``width`` pixels wide: at least 4."""
    return max(4, int(round(width / TILE_PER_WIDTH)))


def tile_means(image: np.ndarray, tile: int) -> np.ndarray:
    """float32 (h // tile, w // tile): mean code of each tile over its pixels and channels (uint8 (h, w, c) in)."""
    h, w, c = image.shape
    hh, ww = h // tile, w // tile
    blocks = image[:hh * tile, :ww * tile].reshape(hh, tile, ww, tile, c)
    return blocks.mean(axis=(1, 3, 4), dtype=np.float32)


def tile_max(image: np.ndarray, tile: int) -> np.ndarray:
    """uint8 (h // tile, w // tile): the largest code of each tile over its pixels and channels."""
    h, w, c = image.shape
    hh, ww = h // tile, w // tile
    return image[:hh * tile, :ww * tile].reshape(hh, tile, ww, tile, c).max(axis=(1, 3, 4))


def tile_histograms(image: np.ndarray, tile: int, picked: np.ndarray):
    """scipy CSR (len(picked), 256): the share of each code in the ``picked`` tiles (flat tile indices
    of the (h // tile, w // tile) grid), over their ``tile`` x ``tile`` pixels and all channels."""
    from scipy.sparse import csr_matrix

    h, w, c = image.shape
    ww = w // tile
    ty, tx = np.divmod(picked, ww)
    dy, dx = np.mgrid[0:tile, 0:tile]
    rows = (ty[:, None, None] * tile + dy[None]).reshape(len(picked), -1)
    cols = (tx[:, None, None] * tile + dx[None]).reshape(len(picked), -1)
    codes = image[rows, cols].reshape(len(picked), -1).astype(np.int64)
    index = np.repeat(np.arange(len(picked)), codes.shape[1])
    data = np.full(codes.size, 1.0 / codes.shape[1], np.float64)
    return csr_matrix((data, (index, codes.ravel())), shape=(len(picked), 256))
