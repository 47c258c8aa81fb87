"""ChArUco board corners in photos: OpenCV's aruco module identifies them, each is refined in the
largest window that misses the markers, then located by the corner fit (:mod:`.corner_model`).

``cv2.aruco.CharucoDetector`` with the board's dictionary and geometry finds the markers
(refining their edges to find more; down to a perimeter of ``MIN_MARKER_PERIMETER_RATE`` of the
photo's width: OpenCV's default, 3 %, left out the whole far boards of two photos of 28 of the
bench's wide-angle set, squares 28-30 px at 3000 x 2000; the larger dimension, as OpenCV counts
it), and every inner corner next to at least one found marker (``minMarkers`` 1: a board cut by
the frame keeps the corners of its cut rows whose other marker is outside) is located by OpenCV
and refined once more (:func:`_refine_charuco`: ``cornerSubPix``, then the model fit) in the
largest window that misses the markers (:func:`charuco_windows`: mapped through the corner's
local image axes, so that a rolled or foreshortened board's markers stay out; a square window of
0.2 of the shortest square side reached into the markers of rolled boards and put corners up to
1 px off, 0.050 px RMS on the simulator's wide-angle set at 3000 x 2000, 0.029 px with the mapped
window).  A corner whose window would leave the image is dropped (OpenCV pads the image by
replicating its edge, which pulls such corners by up to a pixel), and so is one whose window is
under ``MIN_CHARUCO_WINDOW`` px (small squares: 0.8 px RMS at 3 px, 0.07 px at 4 px, simulated at
800 x 600).  After a first solve the pipeline locates them once more without the lens's
curvature (:mod:`.rectified`).  Each such corner carries its id, hence its row and column: the
corners are returned in a ``(rows, cols, 2)`` array with NaN where a corner was not identified
(outside the photo, hidden, or too blurred), so a board cut by the frame is still a labelled
observation.  A photo needs at least ``MIN_CHARUCO_CORNERS`` identified corners, on two rows and
two columns at least.  Pixel convention and labels as :mod:`.corners`.
"""

from __future__ import annotations

import numpy as np

from . import corner_model
from .corner_model import SUBPIX_LIMITS, fit_corners, local_axes

CHARUCO_WINDOW = 1.0  # cornerSubPix half-window, as a share of the clean chessboard around a corner
MIN_CHARUCO_CORNERS = 10  # identified corners a photo of a ChArUco board needs to be used
MIN_MARKER_PERIMETER_RATE = 0.01  # smallest marker perimeter the detector looks at, share of the photo's size
MIN_CHARUCO_WINDOW = 4  # smallest clean half-window (px) in which a ChArUco corner is located reliably


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


def charuco_windows(corners: np.ndarray, board, axes: np.ndarray | None = None) -> np.ndarray:
    """The ``cv2.cornerSubPix`` half-window (px, int) of each identified ChArUco corner: the
    largest image-aligned square window that stays inside the clean chessboard around the corner
    (the markers start ``gap = (1 - marker/square) / 2`` of a square away), mapped through the
    corner's local image axes (:func:`local_axes`, so a rolled or foreshortened board gets a window
    that still misses its markers), times ``CHARUCO_WINDOW``; at most ``SUBPIX_LIMITS[1]``.  A
    corner without an identified neighbour gets the median window.  int ``(rows, cols)``, 0 where
    not identified.  ``axes``: float64 ``(rows, cols, 2, 2)``, the local axes (as :func:`local_axes`
    returns them) in another view of the corners (:mod:`.rectified`); None: from ``corners``."""
    seen = np.isfinite(corners[..., 0])
    win = np.zeros(seen.shape, int)
    axes = local_axes(corners) if axes is None else axes
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
    return fit_corners(grey, out, win, curved=True) if corner_model.FIT_MODEL else out


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
