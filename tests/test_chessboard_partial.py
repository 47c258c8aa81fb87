"""A chessboard running off the photo: its visible block of corners is used, placed into the board's grid.

Fixed seeds, small simulated photos; each test fails when the property it guards breaks.
"""

import numpy as np
import pytest

from lenticalib.calib.intrinsics.board import print_board
from lenticalib.calib.intrinsics.corners import MIN_CHESSBOARD_CORNERS, detect_photo
from lenticalib.sim.board_poses import board_poses, inside_mask, project_camera
from lenticalib.sim.boards import calibration_camera, photograph_print_board

RESOLUTION = (1500, 1000)


def _photos(tmp_path, lens, seed, count, cut, board=None):
    """``count`` JPEGs of a printed board by the simulator's camera; (paths, true corners (rows, cols, 2)
    each, NaN where a corner is outside the photo)."""
    camera = calibration_camera(seed, RESOLUTION, lens=lens)
    board = board or print_board()
    points = board.object_points().reshape(-1, 3)
    paths, truths = [], []
    for k, pose in enumerate(board_poses(camera, board, count, seed, cut=cut)):
        path = tmp_path / f"{lens}-{seed}-{k}.jpg"
        path.write_bytes(photograph_print_board(camera, board, pose, np.random.default_rng([seed, k])))
        paths.append(path)
        p = pose.to_camera(points)
        q = project_camera(camera, p)
        # the lens polynomial folds rays from outside the field back into the frame: those are not seen
        xn, yn = camera.normalized(q[:, 0], q[:, 1])
        folded = np.hypot(xn - p[:, 0] / p[:, 2], yn - p[:, 1] / p[:, 2]) > 1e-6
        q[folded | ~inside_mask(camera, board, pose, margin=0.0)] = np.nan
        truths.append(q.reshape(board.rows, board.cols, 2))
    return paths, truths


def _relabelling(found, truth):
    """The rigid relabelling (quarter turns and a shift of whole squares) that takes the found
    corners' labels to the true ones, from each found corner's nearest true corner; None if there is none."""
    seen = np.argwhere(np.isfinite(found[..., 0]))
    labels = np.argwhere(np.isfinite(truth[..., 0]))
    points = truth[np.isfinite(truth[..., 0])]
    nearest = labels[np.argmin(np.linalg.norm(found[tuple(seen.T)][:, None] - points[None], axis=-1), axis=1)]
    for turn in ([[1, 0], [0, 1]], [[0, -1], [1, 0]], [[-1, 0], [0, -1]], [[0, 1], [-1, 0]]):
        shift = nearest - seen @ np.array(turn).T
        if (shift == shift[0]).all():
            return np.array(turn), shift[0]
    return None


@pytest.mark.parametrize("lens, seed", [("wide", 1), ("strong", 2)])
def test_a_cut_chessboard_gives_its_corners_in_view_as_a_block_of_the_board(tmp_path, lens, seed):
    board = print_board()
    paths, truths = _photos(tmp_path, lens, seed, 5, cut=1.0)
    used = placed = 0
    for path, truth in zip(paths, truths):
        inside = np.isfinite(truth[..., 0])
        assert not inside.all()  # the board runs off the photo
        found = detect_photo(str(path), board.cols, board.rows, board.symmetric)
        if found.corners is None:  # OpenCV's search for a larger pattern can miss a part: refused, not misread
            assert "no chessboard found" in found.reason or "only" in found.reason
            continue
        used += 1
        seen = np.isfinite(found.corners[..., 0])
        assert MIN_CHESSBOARD_CORNERS <= seen.sum() < seen.size
        # a block of the board: every corner where the true corner of a shifted (or turned) label is
        relabel = _relabelling(found.corners, truth)
        assert relabel is not None, path.name
        turn, shift = relabel
        where = np.argwhere(seen) @ turn.T + shift
        error = np.linalg.norm(found.corners[seen] - truth[tuple(where.T)], axis=-1)
        assert error.max() < 0.3 and np.sqrt(np.mean(error ** 2)) < 0.1, (path.name, error.max())
        placed += bool((turn == np.eye(2)).all() and not shift.any())  # the board's edges in view placed it
    assert used >= 3 and placed >= 2, (used, placed)


def test_whole_boards_are_found_whole_as_before(tmp_path):
    board = print_board()
    paths, truths = _photos(tmp_path, "mild", 3, 2, cut=0.0)
    for path, truth in zip(paths, truths):
        found = detect_photo(str(path), board.cols, board.rows, board.symmetric)
        assert found.corners is not None and np.isfinite(found.corners).all()
        assert np.abs(found.corners - truth).max() < 0.2


def test_a_photo_of_another_board_or_of_no_board_is_refused(tmp_path):
    import cv2

    board = print_board()
    other = print_board().__class__(cols=7, rows=4, square_mm=30.0, kind="print")  # wholly in view, smaller
    (path,), _ = _photos(tmp_path, "mild", 4, 1, cut=0.0, board=other)
    found = detect_photo(str(path), board.cols, board.rows, board.symmetric)
    assert found.corners is None and "not this board's 11 x 6" in found.reason
    blank = tmp_path / "wall.png"
    noise = np.random.default_rng(0).normal(128, 20, (400, 600)).clip(0, 255).astype(np.uint8)
    cv2.imwrite(str(blank), cv2.GaussianBlur(noise, (0, 0), 2))
    found = detect_photo(str(blank), board.cols, board.rows, board.symmetric)
    assert found.corners is None and "no chessboard found" in found.reason


def test_corners_the_detector_made_up_are_left_out(tmp_path):
    """OpenCV's search for a larger pattern can return made-up corners (inside a square, or a real
    corner under another label): they are dropped, the others kept."""
    from lenticalib.calib.intrinsics.corners import grey8
    from lenticalib.calib.intrinsics.partial import consistent
    from lenticalib.core.files.imageio import read_image

    (path,), (truth,) = _photos(tmp_path, "mild", 5, 1, cut=0.0)
    grey = grey8(read_image(path))
    block = truth[1:5, 2:9].copy()
    block[1, 3] += 0.35 * np.linalg.norm(block[1, 4] - block[1, 3]) * np.array([0.6, 0.8])  # inside a square
    block[3, 6] = truth[0, 0]  # a real corner, wrong label
    kept = consistent(grey, block)
    assert kept.shape == block.shape
    assert np.isnan(kept[1, 3]).all() and np.isnan(kept[3, 6]).all()
    assert np.isfinite(kept[..., 0]).sum() == block.shape[0] * block.shape[1] - 2


def test_a_block_reaching_the_photos_corner_is_placed_by_the_board_edge_in_view(tmp_path):
    """Beyond the board's outer row the paper shows where the photo does; a sample past the photo's
    edge must not hide that edge (bench phone 3, photo 11: the block was centred, one square off)."""
    from lenticalib.calib.intrinsics.corners import grey8
    from lenticalib.calib.intrinsics.partial import EDGE_MARGIN_PX, EDGE_PAPER_AT, _outward, place, side_is_edge
    from lenticalib.core.files.imageio import read_image

    board = print_board()
    (path,), (truth,) = _photos(tmp_path, "mild", 5, 1, cut=0.0)
    grey = grey8(read_image(path))
    block = truth[0:3, 0:8]  # the board's top rows, its top edge in view
    assert side_is_edge(grey, block)
    paper = _outward(block, EDGE_PAPER_AT)
    paper = 0.5 * (paper[:-1] + paper[1:])
    top = int(paper[:, 1].min()) + 4  # the photo cut just below one of the paper samples
    assert (paper[:, 1] - top > EDGE_MARGIN_PX + 1).sum() >= 3 and np.nanmin(block[..., 1]) > top + 10
    cropped = np.ascontiguousarray(grey[top:])
    moved = block - np.array([0.0, top])
    assert side_is_edge(cropped, moved)
    placed, why = place(cropped, moved, board.rows, board.cols)
    assert why is None
    assert np.array_equal(placed[0:3, 0:8], moved)


def _bench_photo(tmp_path, lens, seed, index):
    """Photo ``index`` of bench_camera's ``lens`` set, seed ``seed`` (3000 x 2000, boards cut by
    up to a quarter), as it simulates it; (path, true corners (rows, cols, 2), NaN outside the photo)."""
    camera = calibration_camera(seed, (3000, 2000), lens=lens)
    board = print_board()
    pose = board_poses(camera, board, 22, seed, cut=0.25)[index]
    path = tmp_path / f"board-{index + 1:02d}.jpg"
    path.write_bytes(photograph_print_board(camera, board, pose, np.random.default_rng([seed, index, 0x5107])))
    q = project_camera(camera, pose.to_camera(board.object_points().reshape(-1, 3)))
    q[~inside_mask(camera, board, pose, margin=0.0)] = np.nan
    return path, q.reshape(board.rows, board.cols, 2)


def test_a_large_board_cut_by_two_edges_is_found_by_the_searches_on_a_smaller_copy(tmp_path):
    """Bench mild seed 2, photo 06 (squares about 200 px, the board running off the right and the
    bottom): OpenCV's part searches on the full photo grow 8 corners at most (fewer than
    MIN_CHESSBOARD_CORNERS, refused), on a quarter-size copy 21.  The corners are the board's own,
    refined on the full photo, and its top-left corner is placed by the edges in view."""
    from lenticalib.calib.intrinsics.corners import grey8, locate_chessboard
    from lenticalib.core.files.imageio import read_image

    board = print_board()
    path, truth = _bench_photo(tmp_path, "mild", 2, 5)
    found, why = locate_chessboard(grey8(read_image(path)), board.cols, board.rows, board.symmetric)
    assert why is None, why
    seen = np.isfinite(found[..., 0])
    assert seen.sum() >= 20 and not np.isfinite(truth[..., 0]).all()
    error = np.linalg.norm(found[seen] - truth[seen], axis=-1)  # labelled as the board: no shift, no turn
    assert error.max() < 0.3, error.max()


def test_a_block_that_skips_corners_is_not_taken_for_single_squares(tmp_path):
    """Bench strong seed 2, photo 10: the part searches return blocks whose rows step 1, 1, 2, 2
    squares (a smooth bend to :func:`consistent`, alternating cells to the parity test): such a
    block was placed and misread.  Every large block found there skips corners, so the photo is
    refused (what is left is too small to place)."""
    from lenticalib.calib.intrinsics.corners import grey8
    from lenticalib.calib.intrinsics.partial import _wide_sides
    from lenticalib.core.files.imageio import read_image

    board = print_board()
    path, truth = _bench_photo(tmp_path, "strong", 2, 9)
    grey = grey8(read_image(path))
    found = detect_photo(str(path), board.cols, board.rows, board.symmetric)
    if found.corners is not None:  # a block used: the board's own corners, not a misreading
        seen = np.isfinite(found.corners[..., 0])
        assert np.linalg.norm(found.corners[seen] - truth[seen], axis=-1).max() < 0.3
    whole = truth[1:4, 1:6]  # single squares: no wide side; every other column: all wide
    assert _wide_sides(grey, whole) == 0
    assert _wide_sides(grey, truth[1:4, 1:6:2]) >= 4  # of its 6 row sides (one is enough to refuse a block)
