"""Synthetic chessboard observations with a known camera (mrcal's synthetic data), for the camera tests."""

import numpy as np


def board_observations(lensmodel: str, intrinsics, seed: int, frames: int = 14, size=(1200, 800)):
    """(float64 (frames, 7, 10, 2) exact corner pixels, the board, the true mrcal cameramodel): a
    10 x 7 board of 20 mm squares about 220 mm in front of a camera of ``lensmodel`` and
    ``intrinsics``, in poses drawn with ``seed``, every corner in view."""
    import mrcal

    from lenticalib.calib.intrinsics.board import Board

    truth = mrcal.cameramodel(intrinsics=(lensmodel, np.array(intrinsics, float)), imagersize=size)
    np.random.seed(seed)  # mrcal.synthesize_board_observations draws from numpy's global generator
    q, _ = mrcal.synthesize_board_observations(
        [truth], object_width_n=10, object_height_n=7, object_spacing=20.0, calobject_warp=np.zeros(2),
        rt_ref_boardcenter=np.array([0, 0, 0, 0, 0, 220.0]),
        rt_ref_boardcenter__noiseradius=np.array([0.6, 0.6, 0.3, 200, 130, 40.0]), Nframes=frames,
        which="all-cameras-must-see-full-board")
    return q[:, 0], Board(10, 7, 20.0, kind="print"), truth
