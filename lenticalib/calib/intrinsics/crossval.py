"""Cross-validation of a camera calibration: is mrcal's uncertainty as large as the real error?

mrcal's projection uncertainty assumes independent corner noise of the size the residuals show.
Photos of a board shown through a lens sheet break that assumption a little (the sheet samples
the board once per lens, so a photo's corner errors share a pattern), and so may a real camera's
processing.  The check: solve the two halves of the photos (even and odd frames) separately with
the chosen lens model, and compare the two models' projections where the corners were observed
(``mrcal.projection_diff``, after the rotation that best lines up their frames) with what their
own uncertainties predict for that difference (``Var_0 + Var_1``), for points at infinity: there
two cameras differ by a rotation only, which ``projection_diff`` fits, while at a finite distance
the unknown translation between the halves' frames would dominate the comparison.  With honest uncertainties the
squared Mahalanobis distance averages 2 (two coordinates); the scale

    k = max(1, sqrt(mean(d^T (C_0 + C_1)^-1 d) / 2))

is how much the reported uncertainty must grow to be honest.  It is written into the camera
model's note (``lenticalib-uncertainty-scale: k``), read back by
:func:`lenticalib.calib.camera.model_file.load_camera_model`, and applied to every uncertainty
lenticalib derives from the model (the report's maps, intrinsics draws, camera poses).  mrcal's
own tools do not read it.

The same split chooses the lens model (:func:`holdout_rss`, used by
:func:`lenticalib.calib.intrinsics.solve.choose`): each candidate model is solved on one half
and predicts the corners of the other half's photos (only their board poses are fitted, the
intrinsics and the board's warp stay those of the half that was solved), and the other way
round.  A richer model is kept only when it predicts the photos it was not solved on
significantly better, photo by photo: it cannot win by fitting the noise of its own photos, nor
by bending where the corners of one half do not reach but those of the other do.

The corner locator's own error is common to both halves, so the split cannot see it.  Where a
chessboard's corners were located twice (first in the photo, then in views rectified with the
first model, :mod:`.rectified`), the models solved from the two corner sets differ by that
error's effect; :func:`locator_difference` measures it against the kept model's uncertainty
and :func:`with_locator_term` adds it to the scale (``k^2 = k_cv^2 + mean(d^T C^-1 d) / 2``: the
covariance grown by the difference's own outer product, spread over the observed region).
"""

from __future__ import annotations

import numpy as np

from .holdout import MIN_FRAMES_PER_HALF
from .solve import calibrate, import_mrcal

GRID = 24  # cells across the image


def cross_validation(corners: np.ndarray, board, imagersize: tuple[int, int], lensmodel: str) -> dict:
    """The scale ``k`` (module docstring) and how it was found.

    ARGUMENTS
    corners      float64 ``(Nframes, rows, cols, 2)`` pixels, the photos the full solve used (NaN:
                 a ChArUco corner not identified)
    board        the board; imagersize (width, height) pixels; lensmodel the chosen model

    RETURNED VALUE
    dict: ``scale`` (>= 1), ``mean_squared_mahalanobis`` (2 when honest), ``points`` compared,
    ``frames`` per half, ``median_difference_px``, or ``{"scale": 1.0, "skipped": why}`` with too few frames.
    """
    n = len(corners)
    if n < 2 * MIN_FRAMES_PER_HALF:
        return {"scale": 1.0, "skipped": f"{n} photos: cross-validation needs >= {2 * MIN_FRAMES_PER_HALF}"}
    mrcal = import_mrcal()
    halves = [calibrate(corners[i::2], board, imagersize, lensmodel=lensmodel).cameramodel() for i in (0, 1)]
    compared = _compared_where_observed(mrcal, halves, corners)
    if compared is None:
        return {"scale": 1.0, "skipped": "too few grid points where corners were observed"}
    q0, diff, rt10 = compared
    v0 = mrcal.unproject(q0, *halves[0].intrinsics(), normalize=True)
    v1 = mrcal.rotate_point_R(rt10[:3, :], v0)
    cov0 = mrcal.projection_uncertainty(v0, halves[0], what="covariance", atinfinity=True)
    cov1 = mrcal.projection_uncertainty(v1, halves[1], what="covariance", atinfinity=True)
    total = cov0 + cov1
    d2 = np.einsum("ni,nij,nj->n", diff, np.linalg.inv(total), diff)
    mean = float(np.mean(d2))
    return {"scale": max(1.0, float(np.sqrt(mean / 2.0))), "mean_squared_mahalanobis": mean,
            "median_difference_px": float(np.median(np.linalg.norm(diff, axis=1))),
            "points": len(q0), "frames": [len(corners[0::2]), len(corners[1::2])], "at": "infinity"}


def locator_difference(kept, other, corners: np.ndarray) -> dict:
    """How far the model solved from the other corner set lies from the kept one, in the kept
    one's sigmas (module docstring).

    ARGUMENTS
    kept, other  mrcal cameramodels with their optimization inputs: the model kept and the model
                 solved from the same photos' corners located the other way
    corners      float64 ``(Nframes, rows, cols, 2)`` pixels, the kept corners (their convex hull is
                 the region compared)

    RETURNED VALUE
    dict: ``mean_squared_mahalanobis`` (the mean of ``d^T C^-1 d`` at infinity over the grid points
    inside the hull, ``C`` the kept model's covariance), ``median_difference_px``,
    ``worst_difference_px``, ``points``; or ``{"skipped": why}`` with too few points.
    """
    mrcal = import_mrcal()
    compared = _compared_where_observed(mrcal, [kept, other], corners)
    if compared is None:
        return {"skipped": "too few grid points where corners were observed"}
    q0, diff, _ = compared
    v0 = mrcal.unproject(q0, *kept.intrinsics(), normalize=True)
    cov = mrcal.projection_uncertainty(v0, kept, what="covariance", atinfinity=True)
    d2 = np.einsum("ni,nij,nj->n", diff, np.linalg.inv(cov), diff)
    length = np.linalg.norm(diff, axis=1)
    return {"mean_squared_mahalanobis": float(np.mean(d2)), "median_difference_px": float(np.median(length)),
            "worst_difference_px": float(length.max()), "points": len(q0), "at": "infinity"}


def with_locator_term(check: dict, locator: dict) -> dict:
    """``check`` (:func:`cross_validation`'s dict) with ``locator`` kept under ``corner_locator``
    and the scale grown by it: ``sqrt(scale^2 + mean_squared_mahalanobis / 2)``."""
    out = dict(check, corner_locator=locator)
    if "mean_squared_mahalanobis" in locator:
        out["scale_cross_validation"] = check["scale"]
        out["scale"] = float(np.sqrt(check["scale"] ** 2 + locator["mean_squared_mahalanobis"] / 2.0))
    return out


def _compared_where_observed(mrcal, models, corners: np.ndarray):
    """``mrcal.projection_diff`` of two models at infinity (after the best-fit rotation) on a
    ``GRID``-wide grid, kept inside the convex hull of the observed ``corners``: (grid pixels of the
    first model (n, 2), differences (n, 2) px, ``rt10``), or None with fewer than 10 points."""
    _, diff, q0, rt10 = mrcal.projection_diff(models, gridn_width=GRID, distance=None)
    q0, diff = q0.reshape(-1, 2), diff.reshape(-1, 2)
    seen = _observed_region(corners, q0)
    if seen.sum() < 10:
        return None
    return q0[seen], diff[seen], rt10


def _observed_region(corners: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Grid points ``q`` (n, 2) inside the convex hull of every observed corner."""
    import cv2

    points = corners.reshape(-1, 2)
    points = points[np.all(np.isfinite(points), axis=1)].astype(np.float32)  # ChArUco: identified corners only
    hull = cv2.convexHull(points)
    return np.array([cv2.pointPolygonTest(hull, (float(x), float(y)), False) >= 0 for x, y in q])
