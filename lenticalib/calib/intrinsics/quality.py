"""How good a camera solve is: residuals, noise, coverage, projection uncertainty; and against a truth.

Every number is in camera pixels unless it says otherwise; distances in mm (the board's unit).

Projection uncertainty (mrcal's ``projection_uncertainty``, method ``mean-pcam``): the standard
deviation of where a fixed point would project if the calibration were repeated with fresh pixel
noise of the observed size (the noise estimate comes from the residuals).  Reported in the worst
direction, on a grid over the image, for points at the *working distance* (the median distance
of the board centres in the photos) and at infinity.  It measures how well the data pin the
model down, not whether the lens model fits (that shows in the residuals).

Truth comparison (:func:`compare_to_truth`, for simulated sets): a grid of pixels is unprojected
with the true model to points at the working distance (camera frame), carried into each board's
frame by the true pose and back out by the solved pose, averaged over the boards (the same
"mean-pcam" reference mrcal's uncertainty uses: the solved camera frame is only defined
relative to the boards), and projected with the solved model.  The difference, normalised by
the predicted 2 x 2 covariance, is a Mahalanobis distance: a correct uncertainty gives values
below 3 almost everywhere (chi-square with 2 degrees of freedom: 98.9 %).
"""

from __future__ import annotations

import numpy as np

from .solve import COVERAGE_GRID, Solve, coverage, import_mrcal

UNCERTAINTY_GRID = (40, 30)  # points across, down
WEAK_CORNER_PX = 0.1  # 1-sigma at an image corner (either distance) above which the report asks for photos there
IMAGE_CORNERS = {"top_left": "top-left", "top_right": "top-right", "bottom_left": "bottom-left",
                 "bottom_right": "bottom-right"}


def residual_stats(solve: Solve, photos: list[str] | None = None) -> dict:
    """Residual statistics of a solve (inlier corners unless said otherwise).

    Keys: ``rms_px`` (per coordinate, as mrcal reports it), ``worst_px`` (largest inlier
    residual length), ``noise_px`` (the observed pixel noise: standard deviation of the inlier
    residual coordinates, what mrcal propagates), ``corners`` (observed: a ChArUco corner not
    identified in a photo is not counted), ``outliers`` (observed corners the solve rejected),
    ``per_frame`` (list of {photo, rms_px, outliers}).
    """
    r, inlier, observed = solve.residuals, solve.inlier, solve.observed
    lengths = np.linalg.norm(r, axis=-1)
    per_frame = []
    for k in range(r.shape[0]):
        rk = r[k][inlier[k]]
        per_frame.append({"photo": photos[k] if photos else k,
                          "rms_px": round(float(np.sqrt(np.mean(rk * rk))), 4) if rk.size else None,
                          "outliers": int((observed[k] & ~inlier[k]).sum())})
    kept = r[inlier]
    return {"rms_px": round(solve.rms, 5), "worst_px": round(float(lengths[inlier].max()), 4),
            "noise_px": round(float(np.std(kept)), 5), "corners": int(observed.sum()),
            "outliers": int((observed & ~inlier).sum()), "per_frame": per_frame}


def board_centres(optimization_inputs: dict) -> np.ndarray:
    """Camera-frame positions of every board's centre, float64 ``(Nframes, 3)`` mm."""
    mrcal = import_mrcal()
    oi = optimization_inputs
    rows, cols = oi["observations_board"].shape[1:3]
    s = oi["calibration_object_spacing"]
    centre = np.array([(cols - 1) * s / 2, (rows - 1) * s / 2, 0.0])
    return mrcal.transform_point_rt(oi["rt_ref_frame"], centre)


def working_distance(optimization_inputs: dict) -> float:
    """The median distance (mm) from the camera to the board centres."""
    return float(np.median(np.linalg.norm(board_centres(optimization_inputs), axis=-1)))


def pixel_grid(imagersize, shape=UNCERTAINTY_GRID) -> np.ndarray:
    """A regular grid of pixel coordinates spanning the whole image, float64 ``(ny, nx, 2)``:
    the first and last points are the centres of the corner pixels."""
    w, h = imagersize
    xs, ys = np.linspace(0.0, w - 1.0, shape[0]), np.linspace(0.0, h - 1.0, shape[1])
    return np.stack(np.meshgrid(xs, ys), axis=-1)


def uncertainty_map(model, distance: float | None, shape=UNCERTAINTY_GRID) -> tuple[np.ndarray, np.ndarray]:
    """Worst-direction projection standard deviation (px) on :func:`pixel_grid`.

    ``distance`` mm from the camera, or None for points at infinity.  Returns (grid ``(ny, nx, 2)``,
    stdev ``(ny, nx)``).
    """
    mrcal = import_mrcal()
    q = pixel_grid(model.imagersize(), shape)
    v = mrcal.unproject(q, *model.intrinsics(), normalize=True)
    p = v * (1.0 if distance is None else distance)
    stdev = mrcal.projection_uncertainty(p, model, atinfinity=distance is None, what="worstdirection-stdev")
    return q, np.asarray(stdev, np.float64)


def _at_points(stdev: np.ndarray) -> dict:
    ny, nx = stdev.shape
    pick = {"centre": stdev[ny // 2, nx // 2], "top_left": stdev[0, 0], "top_right": stdev[0, -1],
            "bottom_left": stdev[-1, 0], "bottom_right": stdev[-1, -1]}
    out = {k: round(float(v), 4) for k, v in pick.items()}
    out["median"] = round(float(np.median(stdev)), 4)
    out["worst"] = round(float(stdev.max()), 4)
    return out


def weak_corner_keys(uncertainty: dict, limit: float = WEAK_CORNER_PX) -> list[str]:
    """The keys of :data:`IMAGE_CORNERS` whose 1-sigma uncertainty (``quality``'s ``uncertainty``:
    the worse of the working distance and infinity) exceeds ``limit`` px, worst first."""
    sigma = {key: max(uncertainty["at_working_distance"][key], uncertainty["at_infinity"][key])
             for key in IMAGE_CORNERS}
    return sorted((key for key in IMAGE_CORNERS if sigma[key] > limit), key=lambda k: -sigma[k])


def weak_corners(uncertainty: dict, limit: float = WEAK_CORNER_PX, distance_mm: float | None = None) -> list[str]:
    """One line of advice per image corner of :func:`weak_corner_keys`, worst first: the model there
    is an extrapolation the photos barely constrain.  Each line gives the corner's 1-sigma at both
    distances, labelled (``distance_mm``: the working distance, mm; None says "the working
    distance"), as the summary line above it does."""
    near_name = "the working distance" if distance_mm is None else f"{distance_mm:.0f} mm"
    lines = []
    for key in weak_corner_keys(uncertainty, limit):
        near, far = uncertainty["at_working_distance"][key], uncertainty["at_infinity"][key]
        lines.append(f"the {IMAGE_CORNERS[key]} corner of the image is known to {near:.2f} px at {near_name} and "
                     f"{far:.2f} px at infinity (1 sigma): add photos with the board reaching into it, tilted, "
                     f"to pin the lens there")
    return lines


def quality(model, solve: Solve, photos: list[str] | None = None, cross_validation: dict | None = None) -> dict:
    """Everything the report shows of a solve, as JSON-ready numbers (see the module docstring).

    Keys: ``residuals`` (:func:`residual_stats`), ``working_distance_mm``, ``coverage`` (share of
    an 8 x 6 cell grid holding corners), ``uncertainty`` {``at_working_distance``, ``at_infinity``}
    each with the worst-direction stdev at the centre, the four image corners, the median and the
    worst of the grid; and, not JSON, ``_maps`` (grid and both stdev maps, for the figures).
    With ``cross_validation`` (:func:`.crossval.cross_validation`) every uncertainty is mrcal's
    times its ``scale``, and the dict is kept under that key.
    """
    distance = working_distance(solve.optimization_inputs)
    scale = (cross_validation or {}).get("scale", 1.0)
    q, near = uncertainty_map(model, distance)
    _, far = uncertainty_map(model, None)
    near, far = near * scale, far * scale
    obs = solve.optimization_inputs["observations_board"]
    return {"residuals": residual_stats(solve, photos), "working_distance_mm": round(distance, 2),
            "coverage": round(coverage(obs[..., :2], model.imagersize(), COVERAGE_GRID), 3),
            "uncertainty": {"at_working_distance": _at_points(near), "at_infinity": _at_points(far)},
            "cross_validation": cross_validation or {"scale": 1.0, "skipped": "not run"},
            "_maps": {"grid": q, "near": near, "far": far, "distance": distance}}


def compare_to_truth(model, truth_model, rt_cam_board_truth: np.ndarray, distance: float | None,
                     shape=UNCERTAINTY_GRID) -> dict:
    """How far the solved ``model`` projects from the truth, in pixels and in predicted sigmas.

    ARGUMENTS
    model                the solved ``mrcal.cameramodel`` (with optimisation inputs)
    truth_model          the true ``mrcal.cameramodel`` (intrinsics only are used)
    rt_cam_board_truth   float64 ``(Nframes, 6)``: the true board pose of every frame of the solve,
                         in the solve's frame order (mrcal rt: Rodrigues rad, translation mm)
    distance             mm, or None for points at infinity

    RETURNED VALUE
    dict with ``grid`` (ny, nx, 2) pixels, ``error`` (ny, nx, 2) solved - true projection px,
    ``normalised`` (ny, nx) Mahalanobis distance with the predicted covariance, ``stdev`` (ny, nx)
    predicted worst-direction stdev px.
    """
    mrcal = import_mrcal()
    oi = model.optimization_inputs()
    rt_fit = oi["rt_ref_frame"]
    rt_true = np.asarray(rt_cam_board_truth, np.float64)
    if rt_true.shape != rt_fit.shape:
        raise ValueError(f"truth poses of shape {rt_true.shape} do not match the solve's {rt_fit.shape}")
    q = pixel_grid(model.imagersize(), shape)
    v = mrcal.unproject(q, *truth_model.intrinsics(), normalize=True)
    if distance is None:
        # directions: rotate into each board frame with the true pose, out with the solved one
        p_board = mrcal.rotate_point_r(-rt_true[:, None, None, :3], v[None])
        p_fit = np.mean(mrcal.rotate_point_r(rt_fit[:, None, None, :3], p_board), axis=0)
    else:
        p_board = mrcal.transform_point_rt(mrcal.invert_rt(rt_true)[:, None, None, :], v[None] * distance)
        p_fit = np.mean(mrcal.transform_point_rt(rt_fit[:, None, None, :], p_board), axis=0)
    error = mrcal.project(p_fit, *model.intrinsics()) - q
    cov = mrcal.projection_uncertainty(p_fit, model, atinfinity=distance is None, what="covariance")
    normalised = np.sqrt(np.einsum("...i,...ij,...j->...", error, np.linalg.inv(cov), error))
    stdev = np.sqrt(np.linalg.eigvalsh(cov)[..., -1])
    return {"grid": q, "error": error, "normalised": normalised, "stdev": stdev}
