"""Board corners in photos: chessboards with OpenCV's ``findChessboardCornersSB`` (labelled the same
way in every photo), ChArUco boards with OpenCV's aruco module (every corner identified).

Detection runs on an 8-bit grey image (:func:`grey8`: camera JPEGs as they are, 16-bit linear
PNGs from a raw converter scaled to their 99.5th percentile and given an sRGB-like curve) with
``findChessboardCornersSB(CALIB_CB_EXHAUSTIVE | CALIB_CB_NORMALIZE_IMAGE)``; each corner is then
refined by ``cv2.cornerSubPix`` in a window of ``SUBPIX_WINDOW`` times the smallest square side
seen in that photo (measured on simulated 1280 x 960 JPEGs of tilted printed boards, 24 photos,
1584 corners: 0.018 px RMS per coordinate and 0.18 s per photo, against 0.06 px and 0.68 s with
SB's own ``CALIB_CB_ACCURACY`` refinement), and located finally by fitting a blurred corner with
curved lines and uneven light to every pixel of that window (:func:`fit_corners`,
:mod:`.corner_model`).  ``cornerSubPix`` alone takes the board's lines for straight: through a
distorting lens they bend inside the window and pull the corner (0.005-0.017 px outward at
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

ChArUco boards (:func:`find_charuco_corners`): ``cv2.aruco.CharucoDetector`` with the board's
dictionary and geometry finds the markers (refining their edges to find more; down to a perimeter
of ``MIN_MARKER_PERIMETER_RATE`` of the photo's width: OpenCV's default, 3 %, left out the whole
far boards of two photos of 28 of the bench's wide-angle set, squares 28-30 px at 3000 x 2000;
the larger dimension, as OpenCV counts it), and every inner corner next to at least one found
marker (``minMarkers`` 1: a board cut by the frame keeps the corners of its cut rows whose other
marker is outside) is located by OpenCV and refined once
more (:func:`_refine_charuco`: ``cornerSubPix``, then the model fit) in the largest window that misses the markers
(:func:`charuco_windows`: mapped through the corner's local image axes, so that a rolled or
foreshortened board's markers stay out; a square window of 0.2 of the shortest square side
reached into the markers of rolled boards and put corners up to 1 px off, 0.050 px RMS on the
simulator's wide-angle set at 3000 x 2000, 0.029 px with the mapped window).  A corner whose
window would leave the image is dropped (OpenCV pads the image by replicating its edge, which
pulls such corners by up to a pixel), and so is one whose window is under
``MIN_CHARUCO_WINDOW`` px (small squares: 0.8 px RMS at 3 px, 0.07 px at 4 px, simulated at
800 x 600).  After a first solve the pipeline locates them once more without the lens's
curvature (:mod:`.rectified`).  Each
such corner carries its id, hence its row and column: the corners are returned in the same
``(rows, cols, 2)`` array with NaN where a corner was not identified (outside the photo, hidden,
or too blurred), so a board cut by the frame is still a labelled observation.  A photo needs at
least ``MIN_CHARUCO_CORNERS`` identified corners, on two rows and two columns at least.

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
FIT_MODEL = True  # False: cornerSubPix's corners as the last step, what plain OpenCV gives (a benchmark's baseline)
CHARUCO_WINDOW = 1.0  # cornerSubPix half-window, as a share of the clean chessboard around a corner
MIN_CHARUCO_CORNERS = 10  # identified corners a photo of a ChArUco board needs to be used
PART_SIZES = ((3, 3), (5, 3), (3, 5), (5, 4), (4, 5))  # smallest blocks the searches for a part of a board start from
PART_SCALES = (1.0, 0.5, 0.25)  # photo scales the part searches run at (each finds different blocks)
PART_MIN_SQUARE_PX = 24.0  # a part search at a smaller scale runs only while the photo's squares stay this large there
NOT_FOUND = "no chessboard found (at least 3 x 3 of its inner corners must be in the photo, sharp)"
MIN_GRID = 3  # rows and columns of inner corners a partly visible chessboard must show, at least
MIN_CHESSBOARD_CORNERS = 12  # inner corners a photo of part of a chessboard must show, at least
MIN_SQUARE_PX = 10.0  # smallest square side (px) whose corners are located reliably
MIN_MARKER_PERIMETER_RATE = 0.01  # smallest marker perimeter the detector looks at, share of the photo's size
MIN_CHARUCO_WINDOW = 4  # smallest clean half-window (px) in which a ChArUco corner is located reliably


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


def axes(block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(step along a row, step down a column) of ``block`` (r, c, 2; NaN: none), px: the linear part
    of an affine map fitted from labels to pixels."""
    rows, cols = np.indices(block.shape[:2])
    ok = np.isfinite(block[..., 0])
    terms = np.stack([np.ones(ok.sum()), rows[ok], cols[ok]], axis=1).astype(np.float64)
    coef, *_ = np.linalg.lstsq(terms, block[ok], rcond=None)
    return coef[2], coef[1]


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
    values = _sample(grey, centres.reshape(-1, 2))
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
    return fit_corners(grey, out, win, curved=True) if FIT_MODEL else out


def fit_corners(grey: np.ndarray, corners: np.ndarray, win: int | np.ndarray, curved: bool) -> np.ndarray:
    """Every corner of a ``(rows, cols, 2)`` grid (NaN: not seen) located once more by
    :func:`.corner_model.fit_corner` in a half-window of ``win`` px (one for all, or an int
    ``(rows, cols)`` array), the lines' directions from its neighbours (:func:`corner_axes`).  Where
    the fit fails (no corner-like contrast, a crisp digital image with no blur to fit, a fit that
    wanders more than ``corner_model.MAX_SHIFT``) the corner keeps its location in ``corners``."""
    from .corner_model import fit_windows

    axes = corner_axes(corners)
    wins = np.broadcast_to(np.asarray(win), corners.shape[:2])
    out = corners.copy()
    ok = np.isfinite(corners[..., 0]) & np.isfinite(axes[..., 0, 0]) & np.isfinite(axes[..., 0, 1])
    fitted = fit_windows(grey, corners[ok], axes[ok][:, :, 0], axes[ok][:, :, 1], wins[ok], curved)
    done = np.isfinite(fitted[:, 0])
    rows = np.argwhere(ok)[done]
    out[rows[:, 0], rows[:, 1]] = fitted[done]
    return out


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


def charuco_detector(board):
    """A ``cv2.aruco.CharucoDetector`` of the ChArUco ``board`` (:class:`~.board.Board`): its squares,
    square and marker size (mm) and dictionary; markers refined to find more of them."""
    import cv2

    aruco = cv2.aruco
    dictionary = aruco.getPredefinedDictionary(getattr(aruco, board.dictionary))
    cboard = aruco.CharucoBoard((board.cols + 1, board.rows + 1), float(board.square_mm), float(board.marker_mm),
                                dictionary)
    charuco = aruco.CharucoParameters()
    charuco.tryRefineMarkers = True
    charuco.minMarkers = 1  # a corner next to one readable marker: the board's edge rows at the image edge
    markers = aruco.DetectorParameters()
    markers.minMarkerPerimeterRate = MIN_MARKER_PERIMETER_RATE
    return aruco.CharucoDetector(cboard, charuco, markers, aruco.RefineParameters())


def find_charuco_corners(grey: np.ndarray, board) -> np.ndarray:
    """The identified inner corners of a ChArUco ``board`` in a uint8 grey image: float64
    ``(rows, cols, 2)`` pixels, NaN where a corner was not identified (all NaN when none was).
    OpenCV's corner id k is row ``k // cols``, column ``k % cols``."""
    corners = np.full((board.rows, board.cols, 2), np.nan)
    found, ids, _, _ = charuco_detector(board).detectBoard(np.ascontiguousarray(grey))
    if ids is None or found is None or len(ids) == 0:
        return corners
    ids = np.asarray(ids, np.int64).ravel()
    q = np.asarray(found, np.float64).reshape(-1, 2)
    h, w = grey.shape
    keep = (ids >= 0) & (ids < board.rows * board.cols) & np.all(np.isfinite(q), axis=1)
    keep &= (q[:, 0] >= 0) & (q[:, 1] >= 0) & (q[:, 0] <= w - 1) & (q[:, 1] <= h - 1)
    corners[ids[keep] // board.cols, ids[keep] % board.cols] = q[keep]
    return _refine_charuco(grey, corners, board)


def _local_axes(corners: np.ndarray) -> np.ndarray:
    """Per corner of a ``(rows, cols, 2)`` grid (NaN = missing), the image vectors (px) of one square
    along the board's columns and rows: float64 ``(rows, cols, 2, 2)``, ``[..., :, 0]`` along +x,
    ``[..., :, 1]`` along +y; central differences where both neighbours are known, one-sided where
    one is, NaN where none is."""
    axes = np.full(corners.shape[:2] + (2, 2), np.nan)
    for k, axis in enumerate((1, 0)):
        fwd = np.full(corners.shape, np.nan)
        bwd = np.full(corners.shape, np.nan)
        d = np.diff(corners, axis=axis)
        if axis == 1:
            fwd[:, :-1], bwd[:, 1:] = d, d
        else:
            fwd[:-1], bwd[1:] = d, d
        both = np.isfinite(fwd[..., 0]) & np.isfinite(bwd[..., 0])
        v = np.where(np.isfinite(fwd), fwd, bwd)
        v[both] = 0.5 * (fwd[both] + bwd[both])
        axes[..., :, k] = v
    return axes


def corner_axes(corners: np.ndarray) -> np.ndarray:
    """:func:`_local_axes`, with the grid's own affine axes (:func:`axes`) for a corner that has no
    seen neighbour (a lone identified corner of a cut ChArUco board); NaN only where fewer than
    three corners are seen."""
    local = _local_axes(corners)
    lone = np.isfinite(corners[..., 0]) & ~(np.isfinite(local[..., 0, 0]) & np.isfinite(local[..., 0, 1]))
    if lone.any() and np.isfinite(corners[..., 0]).sum() >= 3:
        along, down = axes(corners)
        filled = local[lone]
        filled[:, :, 0] = np.where(np.isfinite(filled[:, :, 0]), filled[:, :, 0], along)
        filled[:, :, 1] = np.where(np.isfinite(filled[:, :, 1]), filled[:, :, 1], down)
        local[lone] = filled
    return local


def charuco_windows(corners: np.ndarray, board, axes: np.ndarray | None = None) -> np.ndarray:
    """The ``cv2.cornerSubPix`` half-window (px, int) of each identified ChArUco corner: the
    largest image-aligned square window that stays inside the clean chessboard around the corner
    (the markers start ``gap = (1 - marker/square) / 2`` of a square away), mapped through the
    corner's local image axes (:func:`_local_axes`, so a rolled or foreshortened board gets a window
    that still misses its markers), times ``CHARUCO_WINDOW``; at most ``SUBPIX_LIMITS[1]``.  A
    corner without an identified neighbour gets the median window.  int ``(rows, cols)``, 0 where
    not identified.  ``axes``: float64 ``(rows, cols, 2, 2)``, the local axes (as :func:`_local_axes`
    returns them) in another view of the corners (:mod:`.rectified`); None: from ``corners``."""
    seen = np.isfinite(corners[..., 0])
    win = np.zeros(seen.shape, int)
    axes = _local_axes(corners) if axes is None else axes
    ok = seen & np.all(np.isfinite(axes), axis=(-2, -1))
    gap = (1.0 - float(board.marker_mm) / float(board.square_mm)) / 2.0
    half = np.full(seen.shape, np.nan)
    if ok.any():
        inv = np.linalg.inv(np.where(ok[..., None, None], axes, np.eye(2)))  # px -> squares
        # the box corner (w, w), (w, -w) furthest from the corner in board squares: w * max |inv @ (1, +-1)|
        reach = np.maximum(np.abs(inv @ np.array([1.0, 1.0])).max(axis=-1),
                           np.abs(inv @ np.array([1.0, -1.0])).max(axis=-1))
        half[ok] = CHARUCO_WINDOW * gap / reach[ok]
    if not np.isfinite(half).any():
        return win
    half = np.where(np.isfinite(half), half, np.nanmedian(half))
    win[seen] = np.minimum(np.floor(half[seen]), SUBPIX_LIMITS[1]).astype(int)
    return win


def _refine_charuco(grey: np.ndarray, corners: np.ndarray, board) -> np.ndarray:
    """``cv2.cornerSubPix`` once more on the identified corners, each in its own window
    (:func:`charuco_windows`); a corner whose window would leave the image, or is smaller than
    ``MIN_CHARUCO_WINDOW`` (small or steeply foreshortened squares), is dropped."""
    import cv2

    seen = np.isfinite(corners[..., 0])
    if CHARUCO_WINDOW <= 0 or not seen.any():
        return corners
    win = charuco_windows(corners, board)
    seen &= win >= MIN_CHARUCO_WINDOW
    out = corners.copy()
    out[~seen] = np.nan
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-5)
    for w in np.unique(win[seen]):
        pick = seen & (win == w)
        refined = cv2.cornerSubPix(grey, corners[pick].reshape(-1, 1, 2).astype(np.float32), (int(w), int(w)),
                                   (-1, -1), criteria)
        out[pick] = refined.reshape(-1, 2)
    # a window that leaves the image sees OpenCV's replicated border, which pulls the corner: drop it
    h, w = grey.shape
    border = np.minimum.reduce([out[..., 0], out[..., 1], w - 1 - out[..., 0], h - 1 - out[..., 1]])
    out[seen & ~(border >= win + 1)] = np.nan
    return fit_corners(grey, out, win, curved=True) if FIT_MODEL else out


def charuco_shortfall(corners: np.ndarray) -> str | None:
    """Why the identified corners (``(rows, cols, 2)``, NaN = missing) of one photo are too few to
    use, or None when they are enough (:data:`MIN_CHARUCO_CORNERS`, on two rows and two columns)."""
    seen = np.isfinite(corners[..., 0])
    n = int(seen.sum())
    if n < MIN_CHARUCO_CORNERS:
        return (f"only {n} of {seen.size} ChArUco corners identified, at least {MIN_CHARUCO_CORNERS} are needed "
                "(show more of the board, sharper)")
    if np.count_nonzero(seen.any(axis=1)) < 2 or np.count_nonzero(seen.any(axis=0)) < 2:
        return f"the {n} ChArUco corners identified lie on one line (show more of the board)"
    return None


def detect_photo(path: str, cols: int, rows: int, symmetric: bool = False, board=None) -> PhotoCorners:
    """Read one photo (EXIF orientation applied) and find the board in it (a worker's task).
    ``board``: a ChArUco :class:`~.board.Board` (then ``cols``, ``rows``, ``symmetric`` are its own)."""
    image = read_image(path, camera_orientation=True)
    size = (int(image.shape[1]), int(image.shape[0]))
    if board is not None and board.charuco:
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
    A ChArUco board's corners come with NaN for the corners not identified (:func:`find_charuco_corners`).

    ``progress`` is called once per finished photo.  An unreadable photo raises the
    :class:`~lenticalib.core.errors.ImageError` of :func:`lenticalib.core.imageio.read_image`.  Threads, not
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
