"""Predicting held-out photos, and the mrcal calls the solve shares with it.

:func:`holdout_rss`: how well a lens model solved on one half of the photos (even or odd frames,
:func:`halves`) predicts the other half's corners, the board poses refitted with the intrinsics held
(:mod:`.solve` uses it to choose the model, :mod:`.crossval` names it).  :func:`import_mrcal`,
:func:`optimize_quietly`, :func:`board_residuals` and :func:`frame_indices` are the mrcal calls both
make; units are pixels throughout.
"""

from __future__ import annotations

import contextlib
import os
import tempfile

import numpy as np

from ...core.errors import BackendUnavailableError
from ..camera.model_file import MRCAL_INSTALL

MIN_FRAMES_PER_HALF = 5


def import_mrcal():
    """The ``mrcal`` module, or a one-line BackendUnavailableError saying how to get it."""
    try:
        import mrcal
    except ImportError as exc:
        raise BackendUnavailableError(f"calibrating a camera needs mrcal, which is not available ({exc})",
                                      source="mrcal", hint=MRCAL_INSTALL) from None
    return mrcal


@contextlib.contextmanager
def _quiet_c_stderr():
    """Hold back what mrcal's C code prints on stderr during a solve ("Threw out some outliers ...":
    the outliers are counted and reported by us)."""
    import sys

    try:
        fd = sys.stderr.fileno()
    except (AttributeError, ValueError, OSError):  # a replaced sys.stderr (tests): nothing to redirect
        yield
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    try:
        with tempfile.TemporaryFile() as sink:
            os.dup2(sink.fileno(), fd)
            try:
                yield
            finally:
                os.dup2(saved, fd)
    finally:
        os.close(saved)


def optimize_quietly(mrcal, **inputs) -> dict:
    """``mrcal.optimize(**inputs)`` (solves the ``optimization_inputs`` dict in place) with mrcal's C-level
    stderr chatter silenced; returns mrcal's stats dict.  Shared with crossval's refits."""
    with _quiet_c_stderr():
        return mrcal.optimize(**inputs)


def board_residuals(optimization_inputs: dict) -> np.ndarray:
    """Projected minus observed corners of every board observation, float64 ``(Nframes, rows, cols, 2)``
    pixels, computed afresh (outliers included, so two solves can be compared on the same corners)."""
    mrcal = import_mrcal()
    oi = optimization_inputs
    obs = oi["observations_board"]
    rows, cols = obs.shape[1:3]
    points = mrcal.ref_calibration_object(cols, rows, oi["calibration_object_spacing"],
                                          calobject_warp=oi.get("calobject_warp"))
    frames = oi["rt_ref_frame"][oi["indices_frame_camintrinsics_camextrinsics"][:, 0]]
    p_cam = mrcal.transform_point_rt(frames[:, None, None, :], points)
    q = mrcal.project(p_cam, oi["lensmodel"], oi["intrinsics"][0])
    return q - obs[..., :2]


def frame_indices(n: int) -> np.ndarray:
    """mrcal's ``indices_frame_camintrinsics_camextrinsics`` of ``n`` frames of the one camera, which
    is the reference: int32 ``(n, 3)`` rows (frame, 0, -1)."""
    return np.stack([np.arange(n), np.zeros(n, int), -np.ones(n, int)], axis=1).astype(np.int32)


def halves(n: int) -> list[np.ndarray]:
    """Frame indices of the two halves of ``n`` photos: even and odd frames."""
    return [np.arange(i, n, 2) for i in (0, 1)]


def holdout_rss(mrcal, solve, half_solves, keep: np.ndarray) -> np.ndarray:
    """Per photo, the sum of squared errors (px^2) with which ``solve``'s lens model, solved on the
    other half, predicts the photo's corners (module docstring).

    ARGUMENTS
    solve        the full solve (:class:`~.solve.Solve`): its board poses start each photo's pose fit
    half_solves  the two :class:`~.solve.Solve` of the model on the even and the odd frames
    keep         bool ``(Nframes, rows, cols)``: the corners to predict and to fit the poses to
                 (those every full solve kept: a misread corner weighs on no candidate)

    RETURNED VALUE
    float64 ``(Nframes,)``; NaN for a photo with fewer than 4 corners in ``keep``.
    """
    oi_full = solve.optimization_inputs
    rss = np.full(len(keep), np.nan)
    for held, trained in zip(halves(len(keep))[::-1], half_solves):
        oi = dict(trained.optimization_inputs)
        obs = oi_full["observations_board"][held].copy()
        obs[..., 2] = np.where(keep[held], 1.0, -1.0)
        oi.update(observations_board=obs, rt_ref_frame=oi_full["rt_ref_frame"][held].copy(),
                  indices_frame_camintrinsics_camextrinsics=frame_indices(len(held)),
                  intrinsics=trained.optimization_inputs["intrinsics"].copy(),
                  do_optimize_intrinsics_core=False, do_optimize_intrinsics_distortions=False,
                  do_optimize_calobject_warp=False, do_optimize_frames=True,
                  do_apply_outlier_rejection=False, do_apply_regularization=False)
        optimize_quietly(mrcal, **oi)
        r = board_residuals(oi)
        sq = np.where(keep[held], np.sum(r * r, axis=-1), 0.0).sum(axis=(1, 2))
        rss[held] = np.where(keep[held].sum(axis=(1, 2)) >= 4, sq, np.nan)
    return rss
