"""Outliers of a camera solve are corners seen and rejected, never the corners a photo did not show
(issue 23: a board cut by the frame left its unseen corners counted, and drawn, as outliers).

Fixed seeds, small synthetic data; each test fails when the property it guards is broken.
"""

import numpy as np
from matplotlib.figure import Figure

from lenticalib.calib.intrinsics.board import Board
from lenticalib.calib.intrinsics.quality import quality
from lenticalib.calib.intrinsics.report import _residuals_figure
from lenticalib.calib.intrinsics.solve import OPENCV5, calibrate

SIZE = (1200, 800)


def _cut_boards_with_one_misread_corner():
    """Corners of a 10 x 7 board (20 mm squares) in 12 photos by an OPENCV5 camera, 0.03 px noise;
    the last two columns of four photos not seen (NaN: cut by the frame), one corner 3 px off."""
    import mrcal

    model = mrcal.cameramodel(intrinsics=(OPENCV5, np.array([600, 600, 600, 400, -0.2, 0.05, 0.001, -0.001, 0.0])),
                              imagersize=SIZE)
    np.random.seed(3)  # mrcal.synthesize_board_observations draws from numpy's global generator
    q, _ = mrcal.synthesize_board_observations(
        [model], object_width_n=10, object_height_n=7, object_spacing=20.0, calobject_warp=np.zeros(2),
        rt_ref_boardcenter=np.array([0, 0, 0, 0, 0, 260.0]),
        rt_ref_boardcenter__noiseradius=np.array([0.5, 0.5, 0.3, 150, 100, 40.0]), Nframes=12,
        which="all-cameras-must-see-full-board")
    corners = q[:, 0] + np.random.default_rng(3).normal(0, 0.03, q[:, 0].shape)
    corners[:4, :, -2:] = np.nan
    corners[6, 3, 4] += (3.0, 0.0)
    return corners, Board(10, 7, 20.0, kind="print")


def test_unseen_corners_of_a_cut_board_are_not_counted_or_drawn_as_outliers():
    corners, board = _cut_boards_with_one_misread_corner()
    cal = calibrate(corners, board, SIZE, lensmodel=OPENCV5)
    s = cal.solve
    rejected = s.observed & ~s.inlier
    assert rejected[6, 3, 4]  # the misread corner is rejected ...
    assert cal.candidates[0]["outliers"] == int(rejected.sum()) < 4  # ... and the 56 unseen ones are not counted
    fig = Figure(figsize=(16, 6))
    _residuals_figure(fig, {"cal": cal, "qual": quality(cal.cameramodel(), s)})
    marked = np.concatenate([np.column_stack(line.get_data()) for ax in fig.axes for line in ax.get_lines()
                             if line.get_label() == "outliers"])
    assert len(marked) == rejected.sum() and np.all(marked >= 0)  # no cross at (-1, -1) for an unseen corner
