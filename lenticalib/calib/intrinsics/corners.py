"""Chessboard corners in photos: OpenCV's ``findChessboardCornersSB``, labelled the same way in every photo.

Detection runs on an 8-bit grey image (:func:`grey8`: camera JPEGs as they are, 16-bit linear
PNGs from a raw converter scaled to their 99.5th percentile and given an sRGB-like curve) with
``findChessboardCornersSB(CALIB_CB_EXHAUSTIVE | CALIB_CB_NORMALIZE_IMAGE)``; each corner is then
refined by ``cv2.cornerSubPix`` in a window of ``SUBPIX_WINDOW`` times the smallest square side
seen in that photo.  Measured on simulated 1280 x 960 JPEGs of tilted printed boards (24 photos,
1584 corners): corner error 0.018 px RMS per coordinate and 0.18 s per photo, against 0.06 px and
0.68 s with SB's own ``CALIB_CB_ACCURACY`` refinement.

Corners: float64 ``(rows, cols, 2)`` camera pixel coordinates, OpenCV's (and mrcal's) convention:
(0, 0) is the centre of the top-left pixel.  [i, j] is board corner (row i, column j), i.e. board
point ``(j s, i s, 0)`` (:mod:`.board`).

Labelling (:func:`orient`).  The detector may return the grid starting at any of its corners and
running either way.  First the handedness: the board is seen from its front, so going along a
row (+x) and then down a column (+y) turns clockwise in the image (x right, y down) -- a
mirrored labelling is flipped back.  Then the half turn: on a board with one odd and one even
number of squares the square diagonally inside corner (i, j) is black when i + j is even, as
drawn; the labelling whose inner squares correlate with that is kept.  A symmetric board (both
counts odd or both even) cannot be told apart after a half turn; then the labelling whose first
row runs most nearly left to right in the image is kept (so such boards must not be photographed
rolled by more than 90 degrees).

Too small to use (:data:`MIN_SQUARE_PX`).  A photo where some square of the board is less than
10 pixels across is not used: there the detector and the refinement (whose window cannot shrink
below 2 px) place corners up to a pixel off, consistently enough that the solve's outlier
rejection keeps most of them.  Measured on the simulator's wide-angle set at 3000 x 2000
(``tools/bench_camera.py``, 22 photos): two photos with 4.5 and 6.4 px squares had corner errors
of 0.35 and 0.6 px RMS (0.02 px elsewhere); with them the solve rejected 123 corners and the truth
lay within 3 sigma nowhere, without them 5 corners and 60 % of the image.

Photos are processed in a process pool of ``jobs`` workers (:func:`detect_photos`).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Callable

import numpy as np

from ...core.colour import srgb_encode
from ...core.imageio import read_image

FLAGS_NAMES = ("CALIB_CB_EXHAUSTIVE", "CALIB_CB_NORMALIZE_IMAGE")
SUBPIX_WINDOW = 0.35  # cornerSubPix half-window, as a share of the smallest square side in the photo
SUBPIX_LIMITS = (2, 25)  # pixels
MIN_SQUARE_PX = 10.0  # smallest square side (px) whose corners are located reliably


@dataclasses.dataclass
class PhotoCorners:
    """What one photo gave: ``corners`` (rows, cols, 2) float64 pixels or None, ``size`` (w, h) of the
    photo, and ``reason`` why no corners were found (None when they were)."""

    path: str
    size: tuple[int, int]
    corners: np.ndarray | None
    reason: str | None = None


def grey8(image: np.ndarray) -> np.ndarray:
    """An RGB photo (uint8, uint16 or float32 ``(h, w, 3)``) as uint8 grey ``(h, w)`` for the detector.

    8-bit images are taken as encoded (camera JPEGs); 16-bit and float images are taken as linear
    light (raw converter output): scaled so the 99.5th percentile is white, then encoded with the
    sRGB curve.
    """
    import cv2

    if image.ndim == 2:
        image = image[:, :, None].repeat(3, axis=2)
    if image.dtype == np.uint8:
        return cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY)
    linear = cv2.cvtColor(np.ascontiguousarray(image.astype(np.float32)), cv2.COLOR_RGB2GRAY)
    level = float(np.percentile(linear, 99.5))
    v = np.clip(linear / level, 0.0, 1.0) if level > 0 else np.zeros_like(linear)
    enc = srgb_encode(v)
    return np.clip(enc * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _sample(grey: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Bilinear grey values at pixel coordinates ``points`` (n, 2); NaN outside the image."""
    from scipy.ndimage import map_coordinates

    h, w = grey.shape
    inside = (points[:, 0] >= 0) & (points[:, 0] <= w - 1) & (points[:, 1] >= 0) & (points[:, 1] <= h - 1)
    values = np.full(len(points), np.nan)
    if inside.any():
        values[inside] = map_coordinates(grey.astype(np.float64), [points[inside, 1], points[inside, 0]], order=1)
    return values


def orient(corners: np.ndarray, grey: np.ndarray, symmetric: bool) -> np.ndarray:
    """The corners relabelled so that [0, 0] is the board's top-left inner corner as drawn.

    ARGUMENTS
    corners     float64 ``(rows, cols, 2)`` as the detector ordered them
    grey        the uint8 grey image they were found in
    symmetric   whether the board looks the same after a half turn (see the module docstring)
    """
    c = corners
    along, down = c[0, -1] - c[0, 0], c[-1, 0] - c[0, 0]
    if along[0] * down[1] - along[1] * down[0] < 0:  # mirrored labelling: flip the columns
        c = c[:, ::-1]
    if symmetric:
        turned = c[::-1, ::-1]
        return c if (c[0, -1] - c[0, 0])[0] >= (turned[0, -1] - turned[0, 0])[0] else turned
    rows, cols = c.shape[:2]
    centres = 0.25 * (c[:-1, :-1] + c[1:, :-1] + c[:-1, 1:] + c[1:, 1:])  # inner squares
    values = _sample(grey, centres.reshape(-1, 2))
    ii, jj = np.meshgrid(np.arange(rows - 1), np.arange(cols - 1), indexing="ij")
    black = ((ii + jj) % 2 == 0).ravel()  # as drawn: the square inside corner (i, j) is black for even i + j
    ok = np.isfinite(values)
    if not (ok & black).any() or not (ok & ~black).any():
        return c
    # dark where expected black: keep; else the grid is labelled from the opposite corner
    return c if values[ok & black].mean() < values[ok & ~black].mean() else c[::-1, ::-1]


def square_side(corners: np.ndarray) -> float:
    """The shortest distance (px) between neighbouring corners of a ``(rows, cols, 2)`` grid."""
    return float(min(np.linalg.norm(np.diff(corners, axis=0), axis=-1).min(),
                     np.linalg.norm(np.diff(corners, axis=1), axis=-1).min()))


def find_corners(grey: np.ndarray, cols: int, rows: int, symmetric: bool = False) -> np.ndarray | None:
    """The board's inner corners in a uint8 grey image: float64 ``(rows, cols, 2)`` pixels, or None."""
    import cv2

    flags = 0
    for name in FLAGS_NAMES:
        flags |= getattr(cv2, name)
    found, corners = cv2.findChessboardCornersSB(grey, (int(cols), int(rows)), flags=flags)
    if not found or corners is None:
        return None
    corners = np.asarray(corners, np.float64).reshape(rows, cols, 2)
    side = square_side(corners)
    win = int(np.clip(SUBPIX_WINDOW * side, *SUBPIX_LIMITS))
    refined = cv2.cornerSubPix(grey, corners.reshape(-1, 1, 2).astype(np.float32), (win, win), (-1, -1),
                               (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-5))
    corners = refined.reshape(rows, cols, 2).astype(np.float64)
    return np.ascontiguousarray(orient(corners, grey, symmetric))


def detect_photo(path: str, cols: int, rows: int, symmetric: bool = False) -> PhotoCorners:
    """Read one photo (EXIF orientation applied) and find the board in it (a worker's task)."""
    image = read_image(path, camera_orientation=True)
    size = (int(image.shape[1]), int(image.shape[0]))
    corners = find_corners(grey8(image), cols, rows, symmetric)
    if corners is None:
        return PhotoCorners(str(path), size, None, "board not found (all of it must be in the photo, sharp)")
    side = square_side(corners)
    if side < MIN_SQUARE_PX:
        return PhotoCorners(str(path), size, None, f"board squares only {side:.0f} px across in places (corners "
                            f"need >= {MIN_SQUARE_PX:.0f} px): take it closer or less tilted")
    return PhotoCorners(str(path), size, corners)


def detect_photos(paths: list[str | os.PathLike], board, jobs: int = 2,
                  progress: Callable[[], None] | None = None) -> list[PhotoCorners]:
    """Find ``board`` in every photo of ``paths`` (in that order) with ``jobs`` worker threads.

    ``progress`` is called once per finished photo.  An unreadable photo raises the
    :class:`~lenticalib.core.errors.ImageError` of :func:`lenticalib.core.imageio.read_image`.  Threads, not
    processes: OpenCV releases the GIL in decoding, the corner search and the refinement, and
    threads need no ``__main__`` guard in a caller's script.
    """
    paths = [str(Path(p)) for p in paths]
    args = (board.cols, board.rows, board.symmetric)
    if jobs <= 1 or len(paths) <= 1:
        results = []
        for p in paths:
            results.append(detect_photo(p, *args))
            if progress:
                progress()
        return results
    from concurrent.futures import ThreadPoolExecutor, as_completed

    results: list[PhotoCorners | None] = [None] * len(paths)
    pool = ThreadPoolExecutor(max_workers=min(jobs, len(paths)))
    try:
        futures = {pool.submit(detect_photo, p, *args): k for k, p in enumerate(paths)}
        for future in as_completed(futures):
            results[futures[future]] = future.result()
            if progress:
                progress()
    except BaseException:
        pool.shutdown(wait=True, cancel_futures=True)  # an unreadable photo or Ctrl-C: stop the rest
        raise
    pool.shutdown(wait=True)
    return results  # type: ignore[return-value]
