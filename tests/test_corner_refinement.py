"""Chessboard corners located again in views rectified with a camera model (:mod:`lenticalib.calib.intrinsics.rectified`).

A noiseless chessboard through a strongly distorting lens, rendered exactly (each pixel's ray
through the lens onto the board), so any error left is the locator's own; the rectifying model
is the true lens.  Both passes are checked against plain ``cv2.cornerSubPix``, which the bend
pulls: the first pass's model fit with curved lines (:mod:`lenticalib.calib.intrinsics.corner_model`)
and the rectified view's fit with straight ones.
"""

import numpy as np
import pytest

from lenticalib.calib.intrinsics.board import Board
from lenticalib.calib.intrinsics.corners import find_corners
from lenticalib.calib.intrinsics.rectified import CHESSBOARD_MAX_WINDOW, CHESSBOARD_WINDOW, refine_rectified, windows

SIZE = (1200, 800)
K = np.array([[700.0, 0.0, 599.5], [0.0, 700.0, 399.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.32, 0.11, 0.0, 0.0, -0.015])  # OpenCV k1 k2 p1 p2 k3: strong barrel
COLS, ROWS, SQUARE = 11, 6, 0.16  # inner corners; square side in normalised (z = 1) units
LENS = ("LENSMODEL_OPENCV5", np.array([700.0, 700.0, 599.5, 399.5, *DIST[:4], DIST[4]]))  # the same lens, mrcal's
BOARD = Board(cols=COLS, rows=ROWS, square_mm=20.0, kind="print")


def _render():
    """(uint8 grey image, true corners (ROWS, COLS, 2)): the board fronto-parallel at z = 1, its
    corner (0, 0) at normalised (-0.8, -0.4), ink edges ramped over 0.04 of a square, blurred."""
    import cv2

    w, h = SIZE
    x0, y0 = -0.8, -0.4
    jj, ii = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    und = cv2.undistortPoints(np.stack([jj.ravel(), ii.ravel()], 1).reshape(-1, 1, 2), K, DIST,
                              criteria=(3, 100, 1e-13)).reshape(h, w, 2)
    u = (und[..., 0] - x0) / SQUARE + 1.0  # square coordinates: square (ku, kv) is black for even ku + kv
    v = (und[..., 1] - y0) / SQUARE + 1.0
    soft = 0.02

    def ramp(t):
        return np.clip(0.5 + 0.5 * t / soft, 0.0, 1.0)

    total = np.zeros_like(u)  # share of black ink, the soft squares summed as the simulator does
    ku0, kv0 = np.floor(u + 0.5) - 1, np.floor(v + 0.5) - 1
    for a in (0, 1):
        for b in (0, 1):
            ku, kv = ku0 + a, kv0 + b
            ok = ((ku + kv) % 2 == 0) & (ku >= 0) & (ku <= COLS) & (kv >= 0) & (kv <= ROWS)
            total += np.where(ok, ramp(u - ku) * ramp(ku + 1 - u) * ramp(v - kv) * ramp(kv + 1 - v), 0.0)
    reflect = 0.85 - 0.8 * np.clip(total, 0.0, 1.0)
    img = cv2.GaussianBlur(reflect.astype(np.float32), (0, 0), 1.0)
    grey = np.clip(img * 255 + 0.5, 0, 255).astype(np.uint8)
    jc, ic = np.meshgrid(np.arange(COLS), np.arange(ROWS))
    pts = np.stack([x0 + jc * SQUARE, y0 + ic * SQUARE, np.ones_like(jc, dtype=np.float64)], -1).reshape(-1, 1, 3)
    q, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, DIST)
    return grey, q.reshape(ROWS, COLS, 2)


def _radial_bias(found, truth):
    """(mean radial error (px, + outward), RMS error per coordinate) of the corners found beyond
    0.35 of the half-diagonal."""
    centre = K[:2, 2]
    d = truth - centre
    r = np.linalg.norm(d, axis=-1)
    far = np.isfinite(found[..., 0]) & (r > 0.35 * np.hypot(*SIZE) / 2)
    e = found - truth
    return float(np.mean(np.sum(e[far] * d[far], -1) / r[far])), float(np.sqrt(np.mean(e[far] ** 2)))


@pytest.fixture(scope="module")
def rendered():
    return _render()


def _subpix_only(grey, corners):
    """The first pass's corners moved by ``cv2.cornerSubPix`` alone in the first pass's window,
    without the model fit that follows it there: what the bend pulls."""
    import cv2

    from lenticalib.calib.intrinsics.corners import SUBPIX_LIMITS, SUBPIX_WINDOW, square_side

    win = int(np.clip(SUBPIX_WINDOW * square_side(corners), *SUBPIX_LIMITS))
    out = corners.copy()
    seen = np.isfinite(corners[..., 0])
    out[seen] = cv2.cornerSubPix(grey, corners[seen].reshape(-1, 1, 2).astype(np.float32), (win, win), (-1, -1),
                                 (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-5)).reshape(-1, 2)
    return out


def test_corners_on_bent_lines_are_located_in_rectified_views_without_the_bend_pulling_them(rendered):
    grey, truth = rendered
    first = find_corners(grey, COLS, ROWS)
    assert first is not None and np.isfinite(first).all()
    plain = _subpix_only(grey, first)
    again = refine_rectified(grey, first, BOARD, *LENS)
    bias_plain, rms_plain = _radial_bias(plain, truth)
    bias_first, rms_first = _radial_bias(first, truth)
    bias, rms = _radial_bias(again, truth)
    assert abs(bias_plain) > 0.02  # the bend pulls plain cornerSubPix (what this guards against)
    print(f"radial bias {bias_plain:+.4f} -> first {bias_first:+.4f}, rectified {bias:+.4f} px; "
          f"rms {rms_plain:.4f} -> {rms_first:.4f}, {rms:.4f} px")
    assert np.isfinite(again).all()
    # the first pass's curved fit and the rectified view's straight fit both take the bend out
    for b, r in ((bias_first, rms_first), (bias, rms)):
        assert abs(b) < 0.15 * abs(bias_plain) and r < 0.3 * rms_plain, (bias_plain, b, rms_plain, r)


def test_a_chessboard_cut_by_the_frame_is_located_again_on_its_cut_side_too(rendered):
    """The photo cut 1000 px wide: the board's last two columns are outside, so the corners of the
    cut side have neighbours on one side only (a map fitted to the neighbouring corners would
    extrapolate there); the model-rectified view needs none."""
    grey, truth = rendered
    cut = np.ascontiguousarray(grey[:, :1000])
    first = find_corners(cut, COLS, ROWS)
    assert first is not None
    seen = np.isfinite(first[..., 0])
    assert 40 <= seen.sum() < COLS * ROWS and not seen[:, -1].any()
    plain = _subpix_only(cut, first)
    again = refine_rectified(cut, first, BOARD, *LENS)
    assert (np.isfinite(again[..., 0]) == seen).all()  # every window of this board stays in the photo
    edge = seen & ~np.roll(seen, -1, axis=1)  # the last seen column: the cut side
    e_plain, e_first, e_again = plain[edge] - truth[edge], first[edge] - truth[edge], again[edge] - truth[edge]
    bias_plain, _ = _radial_bias(plain, truth)
    for found, e in ((first, e_first), (again, e_again)):
        bias, _ = _radial_bias(found, truth)
        assert abs(bias) < 0.15 * abs(bias_plain), (bias_plain, bias)
        assert np.abs(e).max() < 0.02 < np.abs(e_plain).max(), (e_plain, e)


def test_chessboard_windows_reach_a_share_of_the_square_along_its_shorter_side():
    """A grid of 40 x 20 px squares (foreshortened): the window is CHESSBOARD_WINDOW of the shorter
    side, so the board's next lines stay out of it; large squares are capped."""
    from lenticalib.calib.intrinsics.corner_model import local_axes

    jj, ii = np.meshgrid(np.arange(COLS, dtype=np.float64), np.arange(ROWS, dtype=np.float64))
    for sx, sy, want in ((40.0, 20.0, int(CHESSBOARD_WINDOW * 20)), (400.0, 300.0, CHESSBOARD_MAX_WINDOW)):
        grid = np.stack([sx * jj, sy * ii], axis=-1)
        grid[0, 0] = np.nan
        win = windows(grid, BOARD, local_axes(grid))
        assert win[0, 0] == 0 and (win[np.isfinite(grid[..., 0])] == want).all(), (sx, sy, np.unique(win))
