"""Board corners in photos: chessboards with OpenCV's ``findChessboardCornersSB`` (labelled the same
way in every photo), ChArUco boards with OpenCV's aruco module (every corner identified).

Detection runs on an 8-bit grey image (:func:`grey8`: camera JPEGs as they are, 16-bit linear
PNGs from a raw converter scaled to their 99.5th percentile and given an sRGB-like curve) with
``findChessboardCornersSB(CALIB_CB_EXHAUSTIVE | CALIB_CB_NORMALIZE_IMAGE)``; each corner is then
refined by ``cv2.cornerSubPix`` in a window of ``SUBPIX_WINDOW`` times the smallest square side
seen in that photo (measured on simulated 1280 x 960 JPEGs of tilted printed boards, 24 photos,
1584 corners: 0.018 px RMS per coordinate and 0.18 s per photo, against 0.06 px and 0.68 s with
SB's own ``CALIB_CB_ACCURACY`` refinement), and located finally by fitting a blurred corner with
curved lines and uneven light to every pixel of that window (:func:`.corner_model.fit_corners`).
``cornerSubPix`` alone takes the board's lines for straight: through a distorting lens they
bend inside the window and pull the corner (0.005-0.017 px outward at
3000 x 2000, up to 0.3 px inward on a cut board near a wide-angle lens's image corners), and it
weighs the edge pixels only (0.011-0.020 px RMS on the bench's sets, 0.005-0.010 px with the
fit).  After a first solve the pipeline locates every corner once more in views rectified with
that model (:mod:`.rectified`).

A chessboard partly outside the photo (:func:`locate_chessboard`): when the whole board is not
found, ``findChessboardCornersSBWithMeta`` with ``CALIB_CB_LARGER`` searches for the largest block
of corners, starting from several smallest blocks (``PART_SIZES``; each start finds different
blocks, the largest consistent one is kept), on the photo and on copies scaled by
``PART_SCALES`` (measured: on a 3000 x 2000 photo with 200 px squares cut by two edges, the
full-size searches grew a block of 8 corners, the quarter-size ones 21); corners found on a
smaller copy are scaled back and refined on the photo itself.  That search can return corners
it made up (inside a square, or a real corner under another label, near the photo's edge):
those are dropped (:func:`.partial.consistent`), a block whose cells are not single squares in
checker order (or whose rows skip corners) is refused (:func:`.partial.checkered`), and the
block is placed into the board's grid
(:func:`.partial.place`: the pose absorbs where, a quarter turn is told by the board's counts and
edges).  A photo needs ``MIN_CHESSBOARD_CORNERS`` such corners on ``MIN_GRID`` rows and columns.
The corners not in the photo are NaN, as for a ChArUco board.

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

ChArUco boards: :mod:`.charuco_corners` (every corner identified by its markers, so a partial
board is still a labelled observation).

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
from ...core.files.imageio import read_image
from . import corner_model
from .corner_model import SUBPIX_LIMITS, axes, fit_corners, sample_bilinear

FLAGS_NAMES = ("CALIB_CB_EXHAUSTIVE", "CALIB_CB_NORMALIZE_IMAGE")
SUBPIX_WINDOW = 0.35  # cornerSubPix half-window, as a share of the smallest square side in the photo
PART_SIZES = ((3, 3), (5, 3), (3, 5), (5, 4), (4, 5))  # smallest blocks the searches for a part of a board start from
PART_SCALES = (1.0, 0.5, 0.25)  # photo scales the part searches run at (each finds different blocks)
PART_MIN_SQUARE_PX = 24.0  # a part search at a smaller scale runs only while the photo's squares stay this large there
NOT_FOUND = "no chessboard found (at least 3 x 3 of its inner corners must be in the photo, sharp)"
MIN_GRID = 3  # rows and columns of inner corners a partly visible chessboard must show, at least
MIN_CHESSBOARD_CORNERS = 12  # inner corners a photo of part of a chessboard must show, at least
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


def unmirror(corners: np.ndarray) -> np.ndarray:
    """A ``(rows, cols, 2)`` grid (NaN: not seen) labelled so that going along a row and then down a
    column turns clockwise in the image (the board seen from its front): a mirrored labelling has
    its columns flipped.  The turn is that of the fitted axes (:func:`axes`)."""
    along, down = axes(corners)
    return corners[:, ::-1] if along[0] * down[1] - along[1] * down[0] < 0 else corners


def orient(corners: np.ndarray, grey: np.ndarray, symmetric: bool) -> np.ndarray:
    """The corners relabelled so that [0, 0] is the board's top-left inner corner as drawn.

    ARGUMENTS
    corners     float64 ``(rows, cols, 2)`` as the detector ordered them
    grey        the uint8 grey image they were found in
    symmetric   whether the board looks the same after a half turn (see the module docstring)
    """
    c = unmirror(corners)
    if symmetric:
        turned = c[::-1, ::-1]
        return c if (c[0, -1] - c[0, 0])[0] >= (turned[0, -1] - turned[0, 0])[0] else turned
    rows, cols = c.shape[:2]
    centres = 0.25 * (c[:-1, :-1] + c[1:, :-1] + c[:-1, 1:] + c[1:, 1:])  # inner squares
    values = sample_bilinear(grey, centres.reshape(-1, 2))
    ii, jj = np.meshgrid(np.arange(rows - 1), np.arange(cols - 1), indexing="ij")
    black = ((ii + jj) % 2 == 0).ravel()  # as drawn: the square inside corner (i, j) is black for even i + j
    ok = np.isfinite(values)
    if not (ok & black).any() or not (ok & ~black).any():
        return c
    # dark where expected black: keep; else the grid is labelled from the opposite corner
    return c if values[ok & black].mean() < values[ok & ~black].mean() else c[::-1, ::-1]


def square_side(corners: np.ndarray) -> float:
    """The shortest distance (px) between neighbouring corners of a ``(rows, cols, 2)`` grid (NaN
    corners, not seen, left out)."""
    return float(min(np.nanmin(np.linalg.norm(np.diff(corners, axis=0), axis=-1), initial=np.inf),
                     np.nanmin(np.linalg.norm(np.diff(corners, axis=1), axis=-1), initial=np.inf)))


def _subpix(grey: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """``cv2.cornerSubPix`` on a ``(r, c, 2)`` grid in a half-window of ``SUBPIX_WINDOW`` times its
    smallest square; a corner whose window would leave the image (OpenCV pads with the edge pixels,
    which pulls it) comes back NaN."""
    import cv2

    win = int(np.clip(SUBPIX_WINDOW * square_side(corners), *SUBPIX_LIMITS))
    h, w = grey.shape

    def clear(q):
        border = np.minimum.reduce([q[..., 0], q[..., 1], w - 1 - q[..., 0], h - 1 - q[..., 1]])
        return border >= win + 1

    out = np.full(corners.shape, np.nan)
    keep = clear(corners)
    if keep.any():
        refined = cv2.cornerSubPix(grey, corners[keep].reshape(-1, 1, 2).astype(np.float32), (win, win), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-5))
        out[keep] = refined.reshape(-1, 2)
    out[~clear(out)] = np.nan
    return fit_corners(grey, out, win, curved=True) if corner_model.FIT_MODEL else out


def _part_blocks(grey: np.ndarray, flags: int, scale: float):
    """Yield the consistent blocks (:func:`.partial.consistent`, photo pixels) that the part
    searches from every PART_SIZES start find on the photo scaled by ``scale`` (area-averaged);
    none at a scale where the block's squares would be under PART_MIN_SQUARE_PX."""
    import cv2

    from .partial import consistent

    small = grey if scale == 1.0 else cv2.resize(grey, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    for size in PART_SIZES:
        found, corners, meta = cv2.findChessboardCornersSBWithMeta(small, size, flags | cv2.CALIB_CB_LARGER)
        if not found or corners is None or meta is None or np.asarray(meta).ndim != 2:
            continue
        b = np.asarray(corners, np.float64).reshape(*np.asarray(meta).shape, 2)
        b = (b + 0.5) / scale - 0.5  # pixel centres at integers on both scales
        if scale != 1.0 and scale * np.nanmedian(np.linalg.norm(np.diff(b, axis=1), axis=-1)) < PART_MIN_SQUARE_PX:
            continue
        yield consistent(grey, b)


def locate_chessboard(grey: np.ndarray, cols: int, rows: int,
                      symmetric: bool = False) -> tuple[np.ndarray | None, str | None]:
    """The board's inner corners in a uint8 grey image, the whole board or the part in the photo:
    (float64 ``(rows, cols, 2)`` pixels with NaN where a corner is not in the photo, None), or
    (None, why not).  A whole board is labelled by :func:`orient`; a part by :func:`.partial.place`
    (a sub-grid of at least ``MIN_GRID`` x ``MIN_GRID`` corners, found with ``CALIB_CB_LARGER``).
    The labelling is worked out on the detector's corners, then carried over to the refined ones
    (:func:`_subpix`: NaN where too near the photo's edge)."""
    import cv2

    from .partial import checkered, junctions, median_step, place

    flags = 0
    for name in FLAGS_NAMES:
        flags |= getattr(cv2, name)
    found, corners = cv2.findChessboardCornersSB(grey, (int(cols), int(rows)), flags=flags)
    part = not (found and corners is not None)
    if not part:
        block = np.asarray(corners, np.float64).reshape(rows, cols, 2)
    else:
        block, most = None, 0
        for scale in PART_SCALES:
            for b in _part_blocks(grey, flags, scale):
                n = int(np.isfinite(b[..., 0]).sum())
                if n > most and min(b.shape[:2]) >= MIN_GRID and checkered(grey, b):
                    block, most = b, n
        if block is None:
            return None, NOT_FOUND
    if not part:
        labelled = orient(block, grey, symmetric)
    else:
        labelled, why = place(grey, unmirror(block), rows, cols)
        if labelled is None:
            return None, why
    refined = _subpix(grey, block)
    if part:
        refined[~junctions(grey, refined, median_step(block))] = np.nan
    source = {tuple(p): k for k, p in enumerate(block.reshape(-1, 2)) if np.isfinite(p).all()}  # relabelled, not moved
    out = np.full((rows, cols, 2), np.nan)
    seen = np.isfinite(labelled[..., 0])
    out[seen] = refined.reshape(-1, 2)[[source[tuple(p)] for p in labelled[seen]]]
    return out, None


def find_corners(grey: np.ndarray, cols: int, rows: int, symmetric: bool = False) -> np.ndarray | None:
    """The board's inner corners in a uint8 grey image (:func:`locate_chessboard`): float64
    ``(rows, cols, 2)`` pixels, NaN where not in the photo, or None."""
    return locate_chessboard(grey, cols, rows, symmetric)[0]


def chessboard_shortfall(corners: np.ndarray) -> str | None:
    """Why the corners (``(rows, cols, 2)``, NaN = not seen) of a partly visible chessboard are too
    few to use, or None: at least :data:`MIN_CHESSBOARD_CORNERS`, on ``MIN_GRID`` rows and columns."""
    seen = np.isfinite(corners[..., 0])
    n = int(seen.sum())
    lines = min(np.count_nonzero(seen.any(axis=1)), np.count_nonzero(seen.any(axis=0)))
    if n < MIN_CHESSBOARD_CORNERS or lines < MIN_GRID:
        return (f"only {n} of the chessboard's {seen.size} inner corners in the photo, at least "
                f"{MIN_CHESSBOARD_CORNERS} on {MIN_GRID} rows and columns are needed (show more of the board)")
    return None


def detect_photo(path: str, cols: int, rows: int, symmetric: bool = False, board=None) -> PhotoCorners:
    """Read one photo (EXIF orientation applied) and find the board in it (a worker's task).
    ``board``: a ChArUco :class:`~.board.Board` (then ``cols``, ``rows``, ``symmetric`` are its own)."""
    image = read_image(path, camera_orientation=True)
    size = (int(image.shape[1]), int(image.shape[0]))
    if board is not None and board.charuco:
        from .charuco_corners import charuco_shortfall, find_charuco_corners

        corners = find_charuco_corners(grey8(image), board)
        why = charuco_shortfall(corners)
        return PhotoCorners(str(path), size, None if why else corners, why)
    corners, why = locate_chessboard(grey8(image), cols, rows, symmetric)
    why = why or chessboard_shortfall(corners)
    if why:
        return PhotoCorners(str(path), size, None, why)
    side = square_side(corners)
    if side < MIN_SQUARE_PX:
        return PhotoCorners(str(path), size, None, f"board squares only {side:.0f} px across in places (corners "
                            f"need >= {MIN_SQUARE_PX:.0f} px): take it closer or less tilted")
    return PhotoCorners(str(path), size, corners)


def detect_photos(paths: list[str | os.PathLike], board, jobs: int = 2,
                  progress: Callable[[], None] | None = None) -> list[PhotoCorners]:
    """Find ``board`` in every photo of ``paths`` (in that order) with ``jobs`` worker threads.
    A ChArUco board's corners come with NaN for the corners not identified
    (:func:`.charuco_corners.find_charuco_corners`).

    ``progress`` is called once per finished photo.  An unreadable photo raises the
    :class:`~lenticalib.core.errors.ImageError` of :func:`lenticalib.core.files.imageio.read_image`.  Threads, not
    processes: OpenCV releases the GIL in decoding, the corner search and the refinement, and
    threads need no ``__main__`` guard in a caller's script.
    """
    paths = [str(Path(p)) for p in paths]
    args = (board.cols, board.rows, board.symmetric, board if getattr(board, "charuco", False) else None)
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
