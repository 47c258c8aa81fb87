"""ChArUco corners located once more in views rectified with a first camera model.

``cv2.cornerSubPix`` takes the board's edges inside its window for straight lines through the
corner.  A strongly distorted lens bends them, most near the image's edges, and the corner found
is pulled along the bend.  The pull depends on where in the image the corner lies, so it is the
same in every photo: the solve takes it into the lens model, and the cross-validation cannot see
it (both halves of the photos share it).  Measured on the simulator's wide-angle lens at 3000 x 2000
(``tools/bench_camera.py`` set wide-charuco, seed 1, 14 photos, detected against true corners):
the corners beyond 3/4 of the half-diagonal were off by -0.10 px radially on average (0.13 px RMS);
located again in views rectified with the model solved from them, by +0.01 px (0.04 px RMS), the
inner corners unchanged (0.024 px RMS).

Procedure (:func:`refine_rectified`), per identified corner: the direction the model gives it;
a pinhole view of focal ``fx`` (the model's) looking along that direction, its x axis level with
the image's rows; the photo resampled into the view around the corner (bilinear, edge pixels
repeated outside the photo); the clean window of :func:`.corners.charuco_windows` measured on the
neighbouring corners as that view sees them; ``cv2.cornerSubPix`` there; the result projected
back through the model.  A straight board edge is straight in a pinhole view, so the window sees
the lines the refinement assumes, whatever the lens.  The corners dropped by the first pass
(window leaving the photo or too small) stay dropped; a corner whose new window would leave the
photo, or whose refinement wanders off by a window, is dropped too; one whose new window is under
``MIN_CHARUCO_WINDOW`` px (squares at the limit, where a window so small sees no bend) keeps its
first location.  At 1500 x 1000 (the same lens, 10 photos) the corners showed no such bias
(+0.01 px beyond 3/4 of the half-diagonal) and the pass changes nothing measurable (0.035 px RMS
before and after).
"""

from __future__ import annotations

import numpy as np

from ...core.imageio import read_image
from .corners import MIN_CHARUCO_WINDOW, _local_axes, charuco_windows, grey8
from .solve import import_mrcal

PATCH_MARGIN = 4  # pixels of the rectified patch beyond twice the window


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
    corners     float64 ``(rows, cols, 2)`` pixels, NaN where not identified
    board       the ChArUco :class:`~.board.Board`
    lensmodel, intrinsics   the mrcal model solved from the first corners

    RETURNED VALUE
    float64 ``(rows, cols, 2)`` pixels, NaN where not identified or now dropped.
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
    for i, j in np.argwhere(seen):
        rot = _view(rays[i, j])
        local = rays @ rot  # every corner's ray in this view's frame
        with np.errstate(invalid="ignore", divide="ignore"):
            grid = f * local[..., :2] / local[..., 2:3]
        axes = _local_axes(grid)
        win = int(charuco_windows(grid, board, axes=axes)[i, j])
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
