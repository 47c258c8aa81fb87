"""The mrcal solve of one camera: a stationary camera, a moving board, one frame per photo.

Procedure (after mrcal's own ``mrcal-calibrate-cameras``):

1. observations ``(Nframes, rows, cols, 3)``: (x, y, weight 1); a corner not identified in a
   photo (NaN, from a ChArUco board cut by the frame) is (-1, -1, -1), which mrcal ignores; the
   camera is the reference (extrinsics index -1), so every frame pose is ``rt_cam_board``.
2. a focal-length estimate from the board homographies (``cv2.initCameraMatrix2D``), then
   ``mrcal.seed_stereographic``; pre-solves with ``LENSMODEL_STEREOGRAPHIC``: the geometry only, then
   the geometry and the core (fx, fy, cx, cy).
3. each candidate lens model: the stereographic core expanded with (near-)zero distortions,
   optimised with outlier rejection and regularisation, then once more with the board's warp
   (``calobject_warp``) free.  For a splined model the core stays at the pre-solve's value (the
   spline absorbs it), as mrcal does.
4. the lens model, chosen by the data (:func:`choose`): ``LENSMODEL_OPENCV5`` and
   ``LENSMODEL_OPENCV8`` always; ``LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=12_Ny=..._fov_x_deg=...``
   (the field of view from the OPENCV8 solution, 10 % wider) too when there are at least
   ``SPLINE_MIN_FRAMES`` frames and the corners cover at least ``SPLINE_MIN_COVERAGE`` of the
   image (cells of an 8 x 6 grid).  With at least ``2 * holdout.MIN_FRAMES_PER_HALF`` frames,
   the model that predicts best the corners of photos it was not solved on is kept
   (:func:`choose`, :func:`.holdout.holdout_rss`): each candidate solved on the even frames
   predicts the odd ones (their board poses fitted, nothing else) and the other way round; a
   richer model replaces a simpler one only when its prediction errors are lower by more than
   ``HOLDOUT_T`` standard errors of the photo-by-photo differences.  A richer model that only
   fits the noise, or bends where the corners of one half do not reach, predicts no better and
   loses; a lens the simpler model cannot follow makes every photo's prediction better and wins.
   With fewer frames, the lowest Bayesian information criterion
   ``BIC = n ln(RSS / n) + k ln(n)`` over the corners that every solve kept (n measurements,
   k free intrinsics, the shared board poses cancel).  Why: measured with
   ``tools/bench_camera.py`` on the simulated 90-degree lens with ChArUco boards at 3000 x 2000
   (wide-charuco, seed 1, an OPENCV5 camera), the BIC took OPENCV8 for a 2 % lower residual RMS
   and its model was 1.02 px off the truth at the worst point of the image, OPENCV5's 0.32 px
   (corners of the time; the hold-out picks OPENCV5 there).
   The hold-out costs two half-size solves per candidate.  ``lensmodel=`` forces one model.

Output: an ``mrcal.cameramodel`` holding its optimisation inputs (so mrcal's tools can show
its residuals and uncertainty), written by mrcal with a note of how it was made, atomically.
"""

from __future__ import annotations

import dataclasses
import math
import re
import time
from typing import Callable

import numpy as np

from ...core.errors import CalibrationError, InputError
from .holdout import (MIN_FRAMES_PER_HALF, board_residuals, frame_indices, halves, holdout_rss,  # noqa: F401
                      import_mrcal, optimize_quietly)

OPENCV8 = "LENSMODEL_OPENCV8"
OPENCV5 = "LENSMODEL_OPENCV5"
SPLINE_KNOTS_X = 12
SPLINE_MIN_FRAMES = 20
SPLINE_MIN_COVERAGE = 0.7
COVERAGE_GRID = (8, 6)
HOLDOUT_T = 2.0  # standard errors by which a richer model must predict held-out photos better
PROGRESS_STEPS = 7  # messages calibrate() sends at most: seeding, three candidates, their three hold-outs
LENSMODEL_PATTERNS = (r"LENSMODEL_(PINHOLE|STEREOGRAPHIC|OPENCV4|OPENCV5|OPENCV8|OPENCV12)",
                      r"LENSMODEL_SPLINED_STEREOGRAPHIC_order=[23]_Nx=\d+_Ny=\d+_fov_x_deg=\d+(\.\d+)?")


def check_lensmodel(name: str) -> str:
    """``name`` if it is a lens model this calibration can fit; InputError naming ``lensmodel`` otherwise."""
    if not any(re.fullmatch(p, name or "") for p in LENSMODEL_PATTERNS):
        raise InputError(f"unknown lens model {name!r}", source="lensmodel",
                         hint="use LENSMODEL_OPENCV8, LENSMODEL_OPENCV5, LENSMODEL_OPENCV4, LENSMODEL_PINHOLE, "
                              "LENSMODEL_STEREOGRAPHIC or "
                              "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=12_Ny=9_fov_x_deg=70")
    return name


@dataclasses.dataclass
class Solve:
    """One lens model's solve: its ``optimization_inputs`` (mrcal's dict, solved in place) and the
    ``residuals`` float64 ``(Nframes, rows, cols, 2)`` px (projected - observed, every corner, outliers
    included), ``inlier`` bool ``(Nframes, rows, cols)``."""

    lensmodel: str
    optimization_inputs: dict
    residuals: np.ndarray
    inlier: np.ndarray
    seconds: float

    @property
    def observed(self) -> np.ndarray:
        """bool ``(Nframes, rows, cols)``: the corners seen in the photos (not the (-1, -1) of a
        ChArUco corner that was not identified); ``observed & ~inlier`` are the outliers."""
        obs = self.optimization_inputs["observations_board"]
        return (obs[..., 0] >= 0) & (obs[..., 1] >= 0)

    @property
    def rms(self) -> float:
        """RMS of the inlier residuals per coordinate (px), as mrcal reports it."""
        r = self.residuals[self.inlier]
        return float(np.sqrt(np.mean(r * r))) if r.size else float("nan")

    @property
    def n_intrinsics(self) -> int:
        """Free intrinsics: the core (unless locked) plus the distortion parameters."""
        oi = self.optimization_inputs
        n = oi["intrinsics"].shape[-1]
        return n if oi.get("do_optimize_intrinsics_core", True) else n - 4


@dataclasses.dataclass
class Calibration:
    """The chosen solve (``solve``), every candidate tried (``candidates``: dicts of lensmodel, rms,
    outliers, free intrinsics, BIC), why the model was chosen (``choice``) and the seconds taken."""

    solve: Solve
    candidates: list[dict]
    choice: str
    seconds: float

    @property
    def lensmodel(self) -> str:
        return self.solve.lensmodel

    def cameramodel(self):
        """The ``mrcal.cameramodel`` of the chosen solve (camera 0, with its optimisation inputs)."""
        mrcal = import_mrcal()
        return mrcal.cameramodel(optimization_inputs=self.solve.optimization_inputs, icam_intrinsics=0)


def board_observations(corners: np.ndarray) -> np.ndarray:
    """mrcal's ``observations_board`` of ``corners`` (float64 ``(Nframes, rows, cols, 2)`` px, NaN:
    not seen): ``(Nframes, rows, cols, 3)`` x, y, weight 1; a corner not seen is (-1, -1, -1),
    which mrcal ignores."""
    observations = np.concatenate([np.asarray(corners, np.float64), np.ones(corners.shape[:3] + (1,))], axis=-1)
    observations[~np.isfinite(corners).all(axis=-1)] = -1.0
    return observations


def covered_cells(observations: np.ndarray, imagersize: tuple[int, int], grid=COVERAGE_GRID) -> set[tuple[int, int]]:
    """The cells ``(column, row)`` of a ``grid`` (nx, ny) over the image holding at least one observed
    corner (corners that are NaN or negative, i.e. not identified, are left out)."""
    w, h = imagersize
    q = observations.reshape(-1, observations.shape[-1])[:, :2]
    q = q[np.all(np.isfinite(q), axis=1) & np.all(q >= 0, axis=1)]
    cx = np.clip((q[:, 0] + 0.5) / w * grid[0], 0, grid[0] - 1).astype(int)
    cy = np.clip((q[:, 1] + 0.5) / h * grid[1], 0, grid[1] - 1).astype(int)
    return set(zip(cx.tolist(), cy.tolist()))


def coverage(observations: np.ndarray, imagersize: tuple[int, int], grid=COVERAGE_GRID) -> float:
    """Share of the cells of a ``grid`` (nx, ny) over the image holding an observed corner (:func:`covered_cells`)."""
    return len(covered_cells(observations, imagersize, grid)) / (grid[0] * grid[1])


def _focal_estimate(corners: np.ndarray, board, imagersize) -> float:
    import cv2

    obj = board.object_points().reshape(-1, 3).astype(np.float32)
    seen = [np.isfinite(c[..., 0]).ravel() for c in corners]
    try:
        k = cv2.initCameraMatrix2D([obj[m] for m in seen if m.sum() >= 4],
                                   [c.reshape(-1, 1, 2)[m].astype(np.float32) for c, m in zip(corners, seen)
                                    if m.sum() >= 4], tuple(int(v) for v in imagersize))
        f = 0.5 * (k[0, 0] + k[1, 1])
    except cv2.error:
        f = float("nan")
    w = imagersize[0]
    return float(f) if math.isfinite(f) and 0.2 * w < f < 20 * w else float(w)


def _seed(mrcal, observations, indices, imagersizes, spacing, focal):
    """Stereographic seed and its two pre-solves (geometry; geometry + core)."""
    intrinsics, rt_cam_ref, rt_ref_frame = mrcal.seed_stereographic(
        imagersizes=imagersizes, focal_estimate=focal, indices_frame_camera=indices[:, :2],
        observations=observations, object_spacing=spacing)
    common = dict(intrinsics=intrinsics, rt_cam_ref=rt_cam_ref, rt_ref_frame=rt_ref_frame,
                  observations_board=observations, indices_frame_camintrinsics_camextrinsics=indices,
                  lensmodel="LENSMODEL_STEREOGRAPHIC", imagersizes=imagersizes,
                  do_optimize_intrinsics_distortions=False, do_optimize_calobject_warp=False,
                  calibration_object_spacing=spacing, do_apply_outlier_rejection=False,
                  do_apply_regularization=False, verbose=False)
    optimize_quietly(mrcal, **common, do_optimize_intrinsics_core=False)
    optimize_quietly(mrcal, **common, do_optimize_intrinsics_core=True)
    return intrinsics, rt_ref_frame


def _solve_model(mrcal, lensmodel, seed, observations, indices, imagersizes, spacing) -> Solve:
    start = time.perf_counter()
    core, rt_ref_frame = seed
    n_new = mrcal.lensmodel_num_params(lensmodel) - core.shape[-1]
    rng = np.random.default_rng(0)  # mrcal breaks exact symmetry with tiny random distortions
    extra = (rng.random((1, n_new)) - 0.5) * 2e-6
    if re.search(r"OPENCV(8|12)", lensmodel):
        extra[:, 5:8] *= 1e-3  # the rational denominator starts at ~0 (see mrcal-calibrate-cameras)
    splined = lensmodel.startswith("LENSMODEL_SPLINED_STEREOGRAPHIC")
    oi = dict(intrinsics=np.concatenate([core.copy(), extra], axis=-1), rt_cam_ref=np.zeros((0, 6)),
              rt_ref_frame=rt_ref_frame.copy(), points=None, observations_board=observations.copy(),
              indices_frame_camintrinsics_camextrinsics=indices, observations_point=None,
              indices_point_camintrinsics_camextrinsics=None, lensmodel=lensmodel, imagersizes=imagersizes,
              calobject_warp=None, do_optimize_intrinsics_core=not splined,
              do_optimize_intrinsics_distortions=lensmodel not in ("LENSMODEL_PINHOLE", "LENSMODEL_STEREOGRAPHIC"),
              do_optimize_extrinsics=False, do_optimize_frames=True, do_optimize_calobject_warp=False,
              calibration_object_spacing=spacing, do_apply_outlier_rejection=True,
              do_apply_regularization=True, verbose=False)
    optimize_quietly(mrcal, **oi)
    oi["calobject_warp"] = np.zeros(2)
    oi["do_optimize_calobject_warp"] = True
    optimize_quietly(mrcal, **oi)
    residuals = board_residuals(oi)
    return Solve(lensmodel, oi, residuals, oi["observations_board"][..., 2] > 0, time.perf_counter() - start)


def spline_model_name(opencv: Solve, imagersize) -> str:
    """The splined model for this camera: ``SPLINE_KNOTS_X`` knots across, as many down as keep them
    square (plus one), over the OPENCV8 solution's horizontal field of view widened by 10 %."""
    mrcal = import_mrcal()
    w, h = imagersize
    oi = opencv.optimization_inputs
    cy = oi["intrinsics"][0, 3]
    v = mrcal.unproject(np.array([[-0.5, cy], [w - 0.5, cy]]), oi["lensmodel"], oi["intrinsics"][0], normalize=True)
    fov = math.degrees(math.acos(float(np.clip(v[0] @ v[1], -1.0, 1.0))))
    ny = int(math.ceil(SPLINE_KNOTS_X * h / w)) + 1
    return (f"LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx={SPLINE_KNOTS_X}_Ny={ny}_"
            f"fov_x_deg={int(math.ceil(min(fov * 1.1, 179.0)))}")


def choose(*solves: Solve, holdout: list[np.ndarray] | None = None) -> tuple:
    """The lens model to keep among ``solves`` (simplest first): (winner, candidate record of each
    solve, in order).

    ``holdout``: per solve, the per-photo squared errors with which the model solved on the other
    half of the photos predicts each photo's corners (:func:`.holdout.holdout_rss`).  Given, a
    richer solve replaces the one kept so far only when it predicts the photos better by more than
    ``HOLDOUT_T`` standard errors of the photo-by-photo differences.  None (too few photos to
    split): the lowest BIC over the corners every solve kept, the earlier (simpler) solve on a tie.
    """
    common = np.logical_and.reduce([s.inlier for s in solves])
    n = 2 * int(common.sum())
    records = []
    for s in solves:
        rss = float(np.sum(s.residuals[common] ** 2))
        bic = n * math.log(max(rss, 1e-300) / n) + s.n_intrinsics * math.log(n)
        records.append(_record(s, bic))
    if holdout is None:
        best = min(range(len(solves)), key=lambda k: (records[k]["bic"], k))
        return (solves[best], *records)
    counted = np.logical_and.reduce([np.isfinite(h) for h in holdout])
    corners = common.sum(axis=(1, 2))[counted]
    for r, h in zip(records, holdout):
        r["holdout_rms_px"] = round(float(np.sqrt(np.sum(h[counted]) / max(2 * corners.sum(), 1))), 5)
    best = 0
    for k in range(1, len(solves)):
        d = holdout[best][counted] - holdout[k][counted]  # > 0: solve k predicts that photo better
        t = float(np.mean(d) / (np.std(d, ddof=1) / math.sqrt(len(d)))) if len(d) > 1 and np.std(d) > 0 else 0.0
        records[k]["holdout_t"] = round(t, 2)
        if t > HOLDOUT_T:
            best = k
    return (solves[best], *records)


def _label(record: dict) -> str:
    return record["lensmodel"] if "SPLINED" not in record["lensmodel"] else "the splined model"


def _record(s: Solve, bic: float | None = None) -> dict:
    # outliers: corners seen and rejected, not the corners a photo did not show (a board cut by the frame)
    return {"lensmodel": s.lensmodel, "rms_px": round(s.rms, 5), "outliers": int((s.observed & ~s.inlier).sum()),
            "free_intrinsics": s.n_intrinsics, "bic": None if bic is None else round(bic, 2),
            "seconds": round(s.seconds, 2)}


def calibrate(corners: np.ndarray, board, imagersize: tuple[int, int], lensmodel: str | None = None,
              progress: Callable[[str], None] | None = None) -> Calibration:
    """Solve one camera from the board corners of several photos.

    ARGUMENTS
    corners      float64 ``(Nframes, rows, cols, 2)``: the corners of each photo (pixels), NaN
                 where a corner was not identified (ChArUco boards cut by the frame)
    board        the :class:`~.board.Board` (its ``square_mm`` sets the unit of the poses: mm)
    imagersize   (width, height) of the photos, pixels
    lensmodel    force this mrcal lens model; None: chosen by the data (module docstring)
    progress     called with a short message before each solve

    RETURNED VALUE
    :class:`Calibration`.  Raises CalibrationError when a solve fails.
    """
    mrcal = import_mrcal()
    start = time.perf_counter()
    n = len(corners)
    observations = board_observations(corners)
    indices = frame_indices(n)
    imagersizes = np.array([imagersize], dtype=np.int32)
    spacing = float(board.square_mm)
    say = progress or (lambda message: None)
    try:
        say("seeding")
        seed = _seed(mrcal, observations.copy(), indices, imagersizes, spacing,
                     _focal_estimate(corners, board, imagersize))
        if lensmodel is not None:
            say(f"solving {lensmodel}")
            solve = _solve_model(mrcal, lensmodel, seed, observations, indices, imagersizes, spacing)
            return Calibration(solve, [_record(solve)], "forced with --lensmodel", time.perf_counter() - start)
        solves = []
        for name in (OPENCV5, OPENCV8):
            say(f"solving {name}")
            solves.append(_solve_model(mrcal, name, seed, observations, indices, imagersizes, spacing))
        covered = coverage(corners, imagersize)
        spline_note = ""
        if n < SPLINE_MIN_FRAMES or covered < SPLINE_MIN_COVERAGE:
            spline_note = (f"; a splined model was not tried ({n} frames, corners in {100 * covered:.0f}% of the "
                           f"image; it needs >= {SPLINE_MIN_FRAMES} frames and >= {100 * SPLINE_MIN_COVERAGE:.0f}%)")
        else:
            say("solving splined model")
            solves.append(_solve_model(mrcal, spline_model_name(solves[1], imagersize), seed, observations, indices,
                                       imagersizes, spacing))
    except (RuntimeError, ValueError, np.linalg.LinAlgError) as exc:
        raise CalibrationError(f"the mrcal solve failed: {exc}", source="camera calibrate",
                               hint="check that the photos show the board sharply, from varied tilted views") from None
    holdout = None
    if n >= 2 * MIN_FRAMES_PER_HALF:
        keep = np.logical_and.reduce([s.inlier for s in solves])
        holdout = []
        try:
            for s in solves:
                say(f"cross-validating {s.lensmodel}")
                parts = [_solve_model(mrcal, s.lensmodel, (seed[0], seed[1][idx]), observations[idx],
                                      frame_indices(len(idx)), imagersizes, spacing) for idx in halves(n)]
                holdout.append(holdout_rss(mrcal, s, parts, keep))
        except (RuntimeError, ValueError, np.linalg.LinAlgError) as exc:
            raise CalibrationError(f"the mrcal solve of half the photos failed: {exc}", source="camera calibrate",
                                   hint="check that the photos show the board sharply, from varied tilted views") from None
    best, *records = choose(*solves, holdout=holdout)
    kept = int(np.logical_and.reduce([s.inlier for s in solves]).sum())
    if holdout is None:
        scores = ", ".join(f"{r['bic']:.1f} for {_label(r)} with {r['free_intrinsics']} intrinsics" for r in records)
        why = f"{best.lensmodel}: lowest BIC over the {kept} corners every solve kept ({scores}){spline_note}"
    else:
        scores = ", ".join(f"{r['holdout_rms_px']:.4f} px for {_label(r)}"
                           + (f" (t = {r['holdout_t']:.1f})" if "holdout_t" in r else "") for r in records)
        why = (f"{best.lensmodel}: predicts the corners of the photos it was not solved on best, each half of the "
               f"photos solved and the other predicted (RMS {scores}; a richer model must do better by more than "
               f"{HOLDOUT_T:g} standard errors, photo by photo){spline_note}")
    return Calibration(best, records, why, time.perf_counter() - start)
