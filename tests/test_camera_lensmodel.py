"""The lens-model choice by hold-out prediction and the ChArUco corner refinement (issue 23).

Fixed seeds, small synthetic data; each test fails when the property it guards is broken.
"""

import math

import numpy as np
import pytest

from lenticalib.calib.intrinsics.board import Board
from lenticalib.calib.intrinsics.charuco_corners import MIN_CHARUCO_WINDOW, _refine_charuco, charuco_windows
from lenticalib.calib.intrinsics.solve import OPENCV5, OPENCV8, Solve, calibrate, choose

from .synthetic_boards import board_observations


def _solve(name, residuals, n):
    inlier = np.ones(residuals.shape[:3], bool)
    oi = {"intrinsics": np.zeros((1, n)), "do_optimize_intrinsics_core": True,
          "observations_board": np.ones(residuals.shape[:3] + (3,))}
    return Solve(name, oi, residuals, inlier, 0.0)


def test_a_richer_model_must_predict_the_held_out_photos_better_not_just_fit_its_own():
    rng = np.random.default_rng(0)
    noise = rng.normal(0, 0.02, (20, 6, 11, 2))
    five = _solve(OPENCV5, noise, 9)
    eight = _solve(OPENCV8, noise * 0.9, 12)  # 10 % lower residuals: the BIC alone would take it
    assert choose(five, eight)[0] is eight
    held = rng.uniform(0.9, 1.1, 20)  # per-photo squared errors of the model solved on the other half
    no_better = held * rng.uniform(0.97, 1.03, 20)
    winner, first, second = choose(five, eight, holdout=[held, no_better])
    assert winner is five and abs(second["holdout_t"]) < 2
    better = held * 0.9 * rng.uniform(0.97, 1.03, 20)  # every photo predicted better
    winner, first, second = choose(five, eight, holdout=[held, better])
    assert winner is eight and second["holdout_t"] > 2 and second["holdout_rms_px"] < first["holdout_rms_px"]


def _synthetic_corners(intrinsics, seed, noise=0.05):
    """Corners of a 10 x 7 board of 20 mm squares seen by an OPENCV8 camera of ``intrinsics``, with
    Gaussian noise of ``noise`` px, and the board."""
    q, board, _ = board_observations(OPENCV8, intrinsics, seed)
    return q + np.random.default_rng(seed).normal(0, noise, q.shape), board


@pytest.mark.parametrize("distortion, expected", [
    # an OPENCV5 lens (no rational terms): the three extra terms do not predict better
    ((-0.2, 0.05, 0.001, -0.001, 0.0, 0.0, 0.0, 0.0), OPENCV5),
    # a rational lens whose distortion no polynomial in r^2, r^4, r^6 follows across the field
    ((2.0, 0.0, 0.0, 0.0, 0.0, 2.5, 0.0, 0.0), OPENCV8),
])
@pytest.mark.parametrize("seed", [1, 2])
def test_the_lens_model_is_chosen_by_how_well_it_predicts_photos_it_was_not_solved_on(distortion, expected, seed):
    corners, board = _synthetic_corners([500, 500, 600, 400, *distortion], seed)
    cal = calibrate(corners, board, (1200, 800))
    assert cal.lensmodel == expected, cal.choice
    assert "not solved on" in cal.choice and all("holdout_rms_px" in r for r in cal.candidates)


def _grid(side: float, roll_deg: float, rows=5, cols=6) -> np.ndarray:
    a = math.radians(roll_deg)
    ex, ey = side * np.array([math.cos(a), math.sin(a)]), side * np.array([-math.sin(a), math.cos(a)])
    ii, jj = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    return 300.0 + jj[..., None] * ex + ii[..., None] * ey


def test_the_charuco_window_stays_off_the_markers_of_a_rolled_board():
    board = Board(6, 5, 20.0, kind="print", pattern="charuco", dictionary="DICT_4X4_50", marker_mm=12.0)
    gap = (1 - 12.0 / 20.0) / 2  # markers start 0.2 of a square from a corner
    square = charuco_windows(_grid(60.0, 0.0), board)
    assert (square == math.floor(gap * 60.0)).all()
    # rolled by 45 degrees the window's corners reach along the board's axes: sqrt(2) smaller
    rolled = charuco_windows(_grid(60.0, 45.0), board)
    assert (rolled == math.floor(gap * 60.0 / math.sqrt(2))).all()


def test_charuco_corners_too_small_to_refine_are_dropped():
    board = Board(6, 5, 20.0, kind="print", pattern="charuco", dictionary="DICT_4X4_50", marker_mm=12.0)
    grey = np.full((900, 900), 128, np.uint8)
    small = _grid(MIN_CHARUCO_WINDOW / 0.2 - 2, 0.0)  # clean window under MIN_CHARUCO_WINDOW px
    assert np.isnan(_refine_charuco(grey, small, board)).all()
    large = _grid(MIN_CHARUCO_WINDOW / 0.2 + 10, 0.0)
    assert np.isfinite(_refine_charuco(grey, large, board)).all()


def test_charuco_corners_located_in_rectified_views_lose_the_pull_of_the_lens_curvature():
    """A ChArUco board near an image corner of the simulator's wide-angle lens at 3000 x 2000: the
    bent edges pull the corners that ``cornerSubPix`` finds in the photo inward; the first pass's
    model fit with curved lines, and the location again in views rectified with the (here: true)
    model, are not pulled, and closer to the truth."""
    import cv2
    import mrcal

    from lenticalib.calib.intrinsics.board import print_board
    from lenticalib.calib.intrinsics.charuco_corners import find_charuco_corners
    from lenticalib.calib.intrinsics.corners import grey8
    from lenticalib.calib.intrinsics.rectified import refine_rectified
    from lenticalib.sim.board_poses import _place
    from lenticalib.sim.board_set import truth_cameramodel
    from lenticalib.sim.boards import calibration_camera, photograph_print_board

    camera = calibration_camera(1, (3000, 2000), lens="wide")
    board = print_board(pattern="charuco")
    lensmodel, intrinsics = truth_cameramodel(camera).intrinsics()
    pose = _place(camera, board, np.array([380.0, 1650.0]), 0.35, 0.3, 1.2, -0.2)
    jpeg = photograph_print_board(camera, board, pose, np.random.default_rng(0))
    grey = grey8(cv2.cvtColor(cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB))
    from lenticalib.calib.intrinsics import corner_model

    found = find_charuco_corners(grey, board)
    corner_model.FIT_MODEL = False
    try:
        plain = find_charuco_corners(grey, board)  # cornerSubPix's corners alone
    finally:
        corner_model.FIT_MODEL = True
    again = refine_rectified(grey, found, board, lensmodel, intrinsics)
    truth = mrcal.project(mrcal.transform_point_rt(pose.rt(), board.object_points()), lensmodel, intrinsics)
    out = truth - intrinsics[2:4]
    radius = np.linalg.norm(out, axis=-1)
    outer = radius > 0.7 * math.hypot(1500, 1000)

    def radial_and_rms(corners):
        ok = np.isfinite(corners[..., 0]) & outer
        e = corners[ok] - truth[ok]
        return float(np.mean(np.sum(e * out[ok], axis=-1) / radius[ok])), float(np.sqrt(np.mean(np.sum(e * e, -1)))), ok
    pull, rms, seen = radial_and_rms(plain)
    pull_first, rms_first, seen_first = radial_and_rms(found)
    pull_again, rms_again, seen_again = radial_and_rms(again)
    assert seen.sum() >= 8 and (seen_again == seen).all() and (seen_first == seen).all()
    assert pull < -0.03
    for p, r in ((pull_first, rms_first), (pull_again, rms_again)):
        assert abs(p) < 0.02 and r < 0.6 * rms, (pull, rms, p, r)


def test_charuco_markers_smaller_than_opencvs_default_minimum_are_read():
    """A ChArUco board of 30 px squares (18 px markers, a perimeter of 2.4 % of a 3000 px wide photo:
    OpenCV's default minimum is 3 %) is found, every corner at its place."""
    import cv2

    from lenticalib.calib.intrinsics.charuco_corners import find_charuco_corners

    board = Board(11, 6, 20.0, kind="print", pattern="charuco", dictionary="DICT_4X4_50", marker_mm=12.0)
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    drawn = cv2.aruco.CharucoBoard((12, 7), 20.0, 12.0, dictionary).generateImage((360, 210), marginSize=0)
    photo = np.full((2000, 3000), 200, np.uint8)
    photo[900:1110, 1300:1660] = cv2.GaussianBlur(drawn, (0, 0), 0.6)
    found = find_charuco_corners(photo, board)
    ii, jj = np.meshgrid(np.arange(6), np.arange(11), indexing="ij")
    expected = np.stack([1300 + 30 * (jj + 1) - 0.5, 900 + 30 * (ii + 1) - 0.5], axis=-1)
    assert np.isfinite(found).all() and np.abs(found - expected).max() < 0.2
