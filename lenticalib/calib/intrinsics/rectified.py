"""Board corners located once more in views rectified with a first camera model: chessboard and ChArUco.

``cv2.cornerSubPix`` takes the board's edges inside its window for straight lines through the
corner.  A strongly distorted lens bends them, most near the image's edges, and the corner found
is pulled along the bend.  The pull depends on where in the image the corner lies, so it is the
same in every photo: the solve takes it into the lens model, and the cross-validation cannot see
it (both halves of the photos share it).  Measured on the simulator's wide-angle lens at 3000 x 2000
(``tools/bench_camera.py``, detected against true corners): ChArUco (set wide-charuco, seed 1,
14 photos) the corners beyond 3/4 of the half-diagonal were off by -0.10 px radially on average
(0.13 px RMS); located again here, by +0.01 px (0.04 px RMS), the inner corners unchanged
(0.024 px RMS).  Chessboard (set wide, seed 2, 26 photos): the corners of cut boards beyond 0.8
of the half-diagonal were off by -0.15 px (up to -0.33 px plain, -0.27 px after a refinement in
patches straightened with a cubic fitted to the neighbouring corners: on the cut side of a cut
board that fit extrapolates, and the bend there is strongest), here by +0.01 px (seed 1: -0.13
px first pass, -0.02 px here; measured with a window of 0.6 of a square, the true model).

Procedure (:func:`refine_rectified`), per corner: the direction the model gives it; a pinhole
view of focal ``fx`` (the model's) looking along that direction, its x axis level with the
image's rows; the photo resampled into the view around the corner (bilinear, edge pixels
repeated outside the photo); the window measured on the neighbouring corners as that view sees
them (:func:`windows`: a ChArUco board's largest window that misses the markers,
:func:`.charuco_corners.charuco_windows`; a chessboard's ``CHESSBOARD_WINDOW`` of a square, the
board's other lines a square away, at most ``CHESSBOARD_MAX_WINDOW`` px); ``cv2.cornerSubPix``
there, then the blurred-corner model with straight lines and uneven light fitted to every pixel
of the window (:func:`.corner_model.fit_windows`, ``curved=False``, every view of a photo at
once); the result projected back through the model.  A straight board edge is straight in a
pinhole view, so the window sees the lines the refinement assumes, whatever the lens and wherever the corner
lies on what the photo shows of the board.  The corners dropped by the first pass (window leaving
the photo or too small) stay dropped; a corner whose new window would leave the photo, or whose
refinement wanders off by a window, is dropped too; one whose new window is under
``MIN_CHARUCO_WINDOW`` px (squares at the limit, where a window so small sees no bend) keeps its
first location.  At 1500 x 1000 (the same lens, ChArUco, 10 photos) the corners showed no such
bias (+0.01 px beyond 3/4 of the half-diagonal) and the pass changes nothing measurable (0.035 px
RMS before and after).

The chessboard's window.  In the view the lines are straight, so the window can reach toward the
next lines: 0.6 of a square (at most 50 px; the wide lens's cut boards have squares of 100-150 px)
gave the wide set of seed 2 (``tools/bench_camera.py``) a model 0.23 px off at worst, the truth
within 3 sigma on 99 % of the image; 0.35 (the first pass's share) at most 50 px 0.37 px and
42 %, at most 25 px 0.38 px (the first solve's model, OPENCV5 forced).  On the phone set of seed 1
(blur, noise, a tone curve; 8 photos rectified with the true model) 0.6 gave 0.045 px RMS per
coordinate against 0.032 px with 0.35, but the model was as far off with either (0.44 and
0.45 px): that set's loss against the earlier straightening is not the window's.  With
``cornerSubPix`` as the last step the pass itself lost there (``tools/bench_corners.py
--rectified``, true model: 0.023 px RMS per coordinate for the first pass, 0.031 px and up to
+0.013 px outward here); with the model fit as the last step it is the better one on every set
(phone 2: 0.010 px first pass, 0.005 px here; wide 2 0.007 and 0.004 px; strong 3 0.007 and
0.003 px; mild 2 0.007 and 0.003 px).

Uneven light.  The model's light varies linearly across the window.  Held even, the straight fit
in these large windows was pulled toward the brighter side: wide 2's rectified corners (true
model) solved to a model 0.331 px off the truth at the worst image point, with 10 corners
rejected as outliers; with the light fitted, 0.020 px and none rejected (the same photos' true
corners: 0.021 px).
"""

from __future__ import annotations

import math

import numpy as np

from ...core.files.imageio import read_image
from .charuco_corners import MIN_CHARUCO_WINDOW, charuco_windows
from .corner_model import corner_axes, fit_windows
from .corners import SUBPIX_LIMITS, grey8
from .solve import import_mrcal

PATCH_MARGIN = 4  # pixels of the rectified patch beyond twice the window
CHESSBOARD_WINDOW = 0.6  # a chessboard corner's cornerSubPix half-window in the view, share of a square
CHESSBOARD_MAX_WINDOW = 50  # pixels
BEND_T = 5.0  # the first corners' outward pull must stand this many standard errors clear ...
BEND_MIN_PX = 0.01  # ... and reach this many px at the half diagonal, for the rectified corners to be kept


def windows(grid: np.ndarray, board, axes: np.ndarray) -> np.ndarray:
    """The ``cv2.cornerSubPix`` half-window (px, int ``(rows, cols)``, 0 where not seen) of each
    corner of ``grid`` (float64 ``(rows, cols, 2)`` px in a view, NaN: not seen; ``axes`` its local
    axes, :func:`.corner_model.corner_axes`): a ChArUco board's clean window
    (:func:`.charuco_corners.charuco_windows`); a chessboard's ``CHESSBOARD_WINDOW`` of a square,
    mapped through the local axes (so a foreshortened board's next lines stay out), between
    ``SUBPIX_LIMITS[0]`` and ``CHESSBOARD_MAX_WINDOW`` px, the median where the axes are unknown."""
    if board.charuco:
        return charuco_windows(grid, board, axes=axes)
    seen = np.isfinite(grid[..., 0])
    win = np.zeros(seen.shape, int)
    ok = seen & np.all(np.isfinite(axes), axis=(-2, -1))
    if not ok.any():
        return win
    inv = np.linalg.inv(np.where(ok[..., None, None], axes, np.eye(2)))  # px -> squares
    reach = np.maximum(np.abs(inv @ np.array([1.0, 1.0])).max(axis=-1),
                       np.abs(inv @ np.array([1.0, -1.0])).max(axis=-1))
    half = np.where(ok, CHESSBOARD_WINDOW / np.where(ok, reach, 1.0), np.nan)
    half = np.where(np.isfinite(half), half, np.nanmedian(half))
    win[seen] = np.clip(np.floor(half[seen] + 1e-9), SUBPIX_LIMITS[0], CHESSBOARD_MAX_WINDOW).astype(int)
    return win


def _view(direction: np.ndarray) -> np.ndarray:
    """Rotation (3, 3), columns the view's x, y, z axes in the camera frame: z along ``direction``
    (unit), x level with the image's rows (perpendicular to the camera's y axis)."""
    x = np.cross([0.0, 1.0, 0.0], direction)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(direction, x), direction], axis=1)


def refine_rectified(grey: np.ndarray, corners: np.ndarray, board, lensmodel: str,
                     intrinsics: np.ndarray) -> np.ndarray:
    """The identified corners of one photo located again in rectified views (module docstring).

    ARGUMENTS
    grey        uint8 ``(h, w)`` grey photo
    corners     float64 ``(rows, cols, 2)`` pixels, NaN where not seen (or not identified)
    board       the :class:`~.board.Board` (chessboard or ChArUco)
    lensmodel, intrinsics   the mrcal model solved from the first corners

    RETURNED VALUE
    float64 ``(rows, cols, 2)`` pixels, NaN where not seen or now dropped.
    """
    import cv2

    mrcal = import_mrcal()
    seen = np.isfinite(corners[..., 0])
    out = np.full(corners.shape, np.nan)
    if not seen.any():
        return out
    f = float(intrinsics[0])
    rays = np.full(corners.shape[:2] + (3,), np.nan)
    rays[seen] = mrcal.unproject(np.ascontiguousarray(corners[seen]), lensmodel, intrinsics, normalize=True)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-5)
    h, w = grey.shape
    views = []  # per corner: (i, j), rotation, patch half-size, window, the patch's photo pixels
    patches, starts, along, down = [], [], [], []  # the fit's inputs, per corner as ``views``
    for i, j in np.argwhere(seen):
        rot = _view(rays[i, j])
        local = rays @ rot  # every corner's ray in this view's frame
        with np.errstate(invalid="ignore", divide="ignore"):
            grid = f * local[..., :2] / local[..., 2:3]
        axes = corner_axes(grid)
        win = int(windows(grid, board, axes)[i, j])
        if win < MIN_CHARUCO_WINDOW:  # squares at the limit: a window this small sees no bend either
            out[i, j] = corners[i, j]
            continue
        half = 2 * win + PATCH_MARGIN
        u = np.arange(-half, half + 1, dtype=np.float64)
        uu, vv = np.meshgrid(u, u)
        directions = np.stack([uu / f, vv / f, np.ones_like(uu)], axis=-1) @ rot.T
        q = mrcal.project(directions, lensmodel, intrinsics).astype(np.float32)
        patch = cv2.remap(grey, q[..., 0], q[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        found = cv2.cornerSubPix(patch, np.array([[[half, half]]], np.float32), (win, win), (-1, -1),
                                 criteria).reshape(2).astype(np.float64)
        if not np.all(np.abs(found - half) < win):
            continue  # wandered off: not the corner the first pass found
        views.append(((i, j), rot, half, win, q))
        patches.append(patch)
        starts.append(found)
        along.append(axes[i, j, :, 0])
        down.append(axes[i, j, :, 1])
    if not views:
        return out
    # the last step, every view of this photo at once: the model fit with straight lines
    fitted = fit_windows(patches, np.array(starts), np.array(along), np.array(down),
                         np.array([v[3] for v in views]), curved=False)
    for ((i, j), rot, half, win, q), start, found in zip(views, starts, fitted):
        if not np.isfinite(found).all():
            found = start  # no fit (a crisp image, no corner-like contrast): cornerSubPix's location
        p = mrcal.project(rot @ np.array([(found[0] - half) / f, (found[1] - half) / f, 1.0]), lensmodel, intrinsics)
        border = min(p[0], p[1], w - 1 - p[0], h - 1 - p[1])
        # a window that leaves the photo sees repeated edge pixels, which pull the corner: drop it
        reach = float(np.max(np.abs(q[half - win:half + win + 1, half - win:half + win + 1] - p), initial=0.0))
        if border >= reach + 1:
            out[i, j] = p
    return out


def refine_photos(paths: list[str], corners: np.ndarray, board, model, progress=None) -> np.ndarray:
    """:func:`refine_rectified` on every photo: ``corners`` float64 ``(Nframes, rows, cols, 2)`` of the
    photos ``paths`` (in that order), ``model`` the ``mrcal.cameramodel`` solved from them; the
    located corners, same shape.  ``progress`` is called once per photo."""
    lensmodel, intrinsics = model.intrinsics()
    out = np.empty_like(corners)
    for k, path in enumerate(paths):
        grey = grey8(read_image(path, camera_orientation=True))
        out[k] = refine_rectified(grey, corners[k], board, lensmodel, intrinsics)
        if progress:
            progress()
    return out



def bend_pull(first: np.ndarray, refined: np.ndarray, model) -> dict:
    """How the first corners sit against the rectified ones along the radius: ``first - refined``
    (both float ``(Nframes, rows, cols, 2)`` px, NaN where missing) projected on the direction away
    from the model's centre of projection, fitted as ``a (r / R)^2`` (``R`` the half diagonal).
    A barrel lens's bend pulls the first corners outward, more the further out (measured on the
    bench's strong lens: +0.004 px near the centre to +0.017 px at 0.7 of the half diagonal, the
    rectified corners within 0.003 px), and the solve absorbs the pull into the lens (lower
    residuals, a wrong model).  Returns {"pull_px": a, "t": a over its standard error, "corners": n}."""
    w, h = model.imagersize()
    cx, cy = model.intrinsics()[1][2:4]
    both = np.isfinite(first).all(axis=-1) & np.isfinite(refined).all(axis=-1)
    p, q = first[both], refined[both]
    offset = p - np.array([cx, cy])
    r = np.linalg.norm(offset, axis=1)
    keep = r > 1.0
    d = np.sum((p - q)[keep] * offset[keep] / r[keep, None], axis=1)
    x = (r[keep] / math.hypot(w / 2.0, h / 2.0)) ** 2
    if d.size < 20:
        return {"pull_px": 0.0, "t": 0.0, "corners": int(d.size)}
    a = float(np.dot(x, d) / np.dot(x, x))
    se = float(np.sqrt(np.sum((d - a * x) ** 2) / (d.size - 1) / np.dot(x, x)))
    return {"pull_px": round(a, 5), "t": round(a / max(se, 1e-12), 2), "corners": int(d.size)}
