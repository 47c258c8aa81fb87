"""A chessboard seen only in part: its visible sub-grid placed into the board's grid.

Why a part is enough.  The board is flat and periodic: any ``r x c`` block of its inner corners
is the same ``r x c`` grid of ``square_mm`` squares.  A photo's board pose is solved per photo, so
labelling the visible block as rows ``i0 .. i0 + r - 1`` and columns ``j0 .. j0 + c - 1`` of the
board, with the wrong ``i0, j0``, or turned by a half or a quarter turn, only changes that photo's
pose: the intrinsics see the same observation.  A mirrored labelling is not a pose (it is fixed
first, as for a whole board, :func:`.corners.orient`).

The board's warp.  mrcal's ``calobject_warp`` is a parabola along each board axis centred on the
board, so a block placed ``k`` squares off its true place sees the same curvature plus a tilt and
an offset, which the pose absorbs to first order; a quarter turn would swap the two axes'
curvatures.  So the placement follows the board where the photo shows it (:func:`board_edges`):
a side of the block whose next square row is followed by bright paper, inside the photo, is the
board's outer row there, and fixes the offset on that axis; an axis with no edge in view gets the
block centred (the error then is at most half the missing rows, second order in the warp).  The
quarter turn is the one that fits the board's counts and its edges; when both fit, the one whose
rows run most nearly left to right in the image (as for a symmetric board).

Shapes: a block is float64 ``(r, c, 2)`` pixels, [i, j] the corner on row i, column j as the
detector ordered it after the handedness fix; the placed grid is ``(rows, cols, 2)`` with NaN
where a corner was not seen.
"""

from __future__ import annotations

import numpy as np

from .corner_model import axes, sample_bilinear

EDGE_PAPER_AT = 1.3  # squares beyond a block's outer corner row where paper shows if it is the board's edge
EDGE_MARGIN_PX = 3.0  # such a sample must be this far inside the photo to count
PREDICT_TOLERANCE = 0.5  # a corner this far (share of a step) from where its neighbours put it is not the board's
JUNCTION_RADIUS = 0.3  # the patch compared with its half turn, in steps to the next corner
JUNCTION_SYMMETRY = 0.6  # correlation a corner's patch has with its half turn, at least
CHECKER_CONTRAST = 0.3  # share of the ink contrast between the dark and the bright cells of a block, at least


def _outward(block: np.ndarray, t: float) -> np.ndarray:
    """Points ``t`` squares beyond row 0 of ``block`` (c, 2): extrapolated along each column, quadratic
    when the block has three rows or more (the lens bends the columns)."""
    p0, p1 = block[0], block[1]
    out = p0 + t * (p0 - p1)
    if len(block) >= 3:
        out = out + 0.5 * t * (t + 1.0) * (block[2] - 2.0 * p1 + p0)
    return out


def side_is_edge(grey: np.ndarray, block: np.ndarray) -> bool:
    """Whether row 0 of ``block`` (r, c, 2) is the board's outer row of inner corners: the squares
    beyond it are followed, ``EDGE_PAPER_AT`` squares out, by paper as bright as the block's white
    squares, at every sample inside the photo, two neighbouring samples at least (were the board to
    go on, one of two neighbouring squares there would be dark).  A sample past the photo's edge
    is left out, not taken as a board going on: requiring all of them inside left the edge of a
    block running into the photo's corner unseen, and the block centred one square off.  False
    when the board goes on or the photo ends first."""
    if block.shape[0] < 2 or block.shape[1] < 3:
        return False
    paper = _outward(block, EDGE_PAPER_AT)
    paper = 0.5 * (paper[:-1] + paper[1:])  # between two columns: the middle of the square beyond
    h, w = grey.shape
    m = EDGE_MARGIN_PX
    inside = np.all(paper >= m, axis=1) & (paper[:, 0] <= w - 1 - m) & (paper[:, 1] <= h - 1 - m)
    if not (inside[:-1] & inside[1:]).any():  # two neighbouring squares' samples: one dark if the board goes on
        return False
    paper = paper[inside]
    centres = 0.25 * (block[:-1, :-1] + block[1:, :-1] + block[:-1, 1:] + block[1:, 1:]).reshape(-1, 2)
    inner = sample_bilinear(grey, centres)
    inner = inner[np.isfinite(inner)]
    if inner.size < 2:
        return False
    dark, bright = np.percentile(inner, 25), np.percentile(inner, 75)
    if bright - dark < 20:
        return False
    values = sample_bilinear(grey, paper)
    return bool(np.all(values > dark + 0.6 * (bright - dark)))


def board_edges(grey: np.ndarray, block: np.ndarray) -> dict[str, bool]:
    """Which sides of ``block`` (r, c, 2) are the board's edges: ``top`` (row 0), ``bottom``,
    ``left`` (column 0), ``right`` (:func:`side_is_edge`)."""
    return {"top": side_is_edge(grey, block), "bottom": side_is_edge(grey, block[::-1]),
            "left": side_is_edge(grey, block.transpose(1, 0, 2)),
            "right": side_is_edge(grey, block.transpose(1, 0, 2)[::-1])}


def median_step(block: np.ndarray) -> float:
    """Median distance (px) between neighbouring corners of ``block`` (r, c, 2; NaN: none)."""
    d = np.concatenate([np.linalg.norm(np.diff(block, axis=a), axis=-1).ravel() for a in (0, 1)])
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size else float("nan")


def _supported(block: np.ndarray, ok: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """(predicted, agreed) bool (r, c): whether some prediction of each corner along ``axis`` from two
    neighbours in ``ok`` exists, and whether one lies within ``PREDICT_TOLERANCE`` of the step used
    (halved for the midpoint of the two neighbours either side)."""
    b = np.moveaxis(np.where(ok[..., None], block, np.nan), axis, 0)
    n = b.shape[0]
    predicted = np.zeros(b.shape[:2], bool)
    agreed = np.zeros(b.shape[:2], bool)
    for k in range(n):
        guesses = []
        if k >= 2:
            guesses.append((2 * b[k - 1] - b[k - 2], b[k - 1] - b[k - 2], 1.0))
        if k + 2 < n:
            guesses.append((2 * b[k + 1] - b[k + 2], b[k + 1] - b[k + 2], 1.0))
        if 1 <= k < n - 1:
            guesses.append((0.5 * (b[k - 1] + b[k + 1]), 0.5 * (b[k + 1] - b[k - 1]), 0.5))
        for guess, step, share in guesses:
            there = np.isfinite(guess[:, 0])
            miss = np.linalg.norm(guess - b[k], axis=-1)
            predicted[k] |= there
            agreed[k] |= there & (miss <= share * PREDICT_TOLERANCE * np.linalg.norm(step, axis=-1))
    return np.moveaxis(predicted, 0, axis), np.moveaxis(agreed, 0, axis)


def consistent(grey: np.ndarray, block: np.ndarray) -> np.ndarray:
    """``block`` (r, c, 2) with NaN for the corners that are not the board's, and without outer rows
    and columns left empty.  With ``CALIB_CB_LARGER`` the detector's grid can hold corners it made
    up: inside a square (:func:`junctions` rejects those), or a real corner under the wrong label.
    A kept corner must agree with its neighbours along each axis where it has two (a lens and a tilt
    bend a board's lines smoothly: the next corner is the last step on, or midway between two, to
    within ``PREDICT_TOLERANCE`` of a step); corners that do not are dropped until all agree."""
    ok = np.isfinite(block[..., 0]) & junctions(grey, block, median_step(block))
    while True:
        keep = ok.copy()
        any_prediction = np.zeros(ok.shape, bool)
        for axis in (0, 1):
            predicted, agreed = _supported(block, ok, axis)
            keep &= agreed | ~predicted
            any_prediction |= predicted
        keep &= any_prediction
        if (keep == ok).all():
            break
        ok = keep
    out = np.where(ok[..., None], block, np.nan)
    keep_r, keep_c = np.nonzero(ok.any(axis=1))[0], np.nonzero(ok.any(axis=0))[0]
    if keep_r.size == 0:
        return out[:0, :0]
    return out[keep_r[0]:keep_r[-1] + 1, keep_c[0]:keep_c[-1] + 1]


def checkered(grey: np.ndarray, block: np.ndarray) -> bool:
    """Whether the cells of ``block`` (r, c, 2) are single squares in a checker order: their centres
    fall into a dark and a bright class by the parity of (i + j), the classes apart by at least
    ``CHECKER_CONTRAST`` of the ink contrast seen a quarter of a cell in from the cell corners.  (With
    ``CALIB_CB_LARGER`` the detector can return every other corner along an axis: then the cell
    centres land on corners, mid-grey; or skip corners, refused by :func:`_wide_sides`.)"""
    a, b, c, d = block[:-1, :-1], block[:-1, 1:], block[1:, :-1], block[1:, 1:]
    centres = sample_bilinear(grey, (0.25 * (a + b + c + d)).reshape(-1, 2)).reshape(a.shape[:2])
    quarters = np.concatenate([sample_bilinear(grey, (0.625 * p + 0.125 * (a + b + c + d - p)).reshape(-1, 2))
                               for p in (a, b, c, d)])
    quarters = quarters[np.isfinite(quarters)]
    i, j = np.indices(centres.shape)
    known = np.isfinite(centres)
    even, odd = centres[known & ((i + j) % 2 == 0)], centres[known & ((i + j) % 2 == 1)]
    if quarters.size < 4 or even.size < 2 or odd.size < 2:
        return False
    contrast = np.percentile(quarters, 95) - np.percentile(quarters, 5)
    gap = max(odd.min() - even.max(), even.min() - odd.max())
    return bool(contrast > 0 and gap >= CHECKER_CONTRAST * contrast and _wide_sides(grey, block) == 0)


def _wide_sides(grey: np.ndarray, block: np.ndarray) -> int:
    """How many sides of ``block``'s cells (r, c, 2) span two or three squares of the board instead
    of one: a junction at the side's midpoint, or at both its thirds (looked at with a patch of
    JUNCTION_RADIUS of half, or a third of, the side).  With ``CALIB_CB_LARGER`` the detector can
    skip corners along a row, evenly (cells three squares wide still alternate in colour, so
    :func:`checkered`'s parity test cannot tell) or not (steps of 1, 1, 2, 2 squares, which
    :func:`consistent` takes for a smooth bend); measured on bench strong seed 2, photo 10.  On a
    single square's side those points lie on the line between a dark and a bright square, which a
    half turn about them swaps."""
    a = np.concatenate([block[:, :-1].reshape(-1, 2), block[:-1].reshape(-1, 2)])
    b = np.concatenate([block[:, 1:].reshape(-1, 2), block[1:].reshape(-1, 2)])
    keep = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    a, b = a[keep], b[keep]
    if len(a) == 0:
        return 0
    side = np.linalg.norm(b - a, axis=1)
    halves = junctions(grey, (0.5 * (a + b))[:, None], (side / 2)[:, None])[:, 0]
    thirds = junctions(grey, np.stack([a + (b - a) / 3, a + 2 * (b - a) / 3], axis=1),
                       np.repeat((side / 3)[:, None], 2, axis=1)).all(axis=1)
    return int(np.sum(halves | thirds))


def junctions(grey: np.ndarray, block: np.ndarray, step) -> np.ndarray:
    """bool (r, c): which corners of ``block`` (r, c, 2; NaN: none) look like where two squares of
    each colour meet: the image within ``JUNCTION_RADIUS`` of a ``step`` (px; one for all, or one
    per corner, (r, c)) around the corner correlates by at least ``JUNCTION_SYMMETRY`` with itself
    turned by a half turn about the corner (an ink corner seen through any lens, tilt and blur is
    locally point-symmetric; a point inside a square or on one edge is not)."""
    import cv2

    ok = np.zeros(block.shape[:2], bool)
    steps = np.broadcast_to(np.asarray(step, np.float64), block.shape[:2])
    image = grey.astype(np.float32)
    for i, j in zip(*np.nonzero(np.isfinite(block[..., 0]) & np.isfinite(steps))):
        r = max(3, int(round(JUNCTION_RADIUS * steps[i, j])))
        patch = cv2.getRectSubPix(image, (2 * r + 1, 2 * r + 1), tuple(float(x) for x in block[i, j]))
        a = patch - patch.mean()
        b = a[::-1, ::-1]
        norm = float(np.sqrt(np.sum(a * a) * np.sum(b * b)))
        ok[i, j] = norm > 0 and float(np.sum(a * b)) / norm >= JUNCTION_SYMMETRY
    return ok


def _offset(n: int, total: int, first: bool, last: bool) -> int | None:
    """Where a block of ``n`` rows starts in the board's ``total``; None when its edges disagree."""
    if n > total or (first and last and n != total):
        return None
    if first:
        return 0
    if last:
        return total - n
    return (total - n) // 2


def place(grey: np.ndarray, block: np.ndarray, rows: int, cols: int) -> tuple[np.ndarray | None, str | None]:
    """The block (r, c, 2) placed into a board of ``rows`` x ``cols`` inner corners (module
    docstring): ((rows, cols, 2) with NaN where not seen, None) or (None, why it cannot be this board)."""
    options = []
    for quarter in (0, 1, 2, 3):
        b = np.rot90(block, quarter, axes=(0, 1))  # a rotation of the labels: handedness kept
        r, c = b.shape[:2]
        if r > rows or c > cols:
            continue
        edges = board_edges(grey, b)
        i0 = _offset(r, rows, edges["top"], edges["bottom"])
        j0 = _offset(c, cols, edges["left"], edges["right"])
        if i0 is None or j0 is None:
            continue
        along = axes(b)[0]
        options.append((-along[0] / (np.linalg.norm(along) + 1e-12), quarter, b, i0, j0))
    if not options:
        r, c = block.shape[:2]
        return None, (f"a chessboard of at least {max(r, c)} x {min(r, c)} inner corners, not this board's "
                      f"{cols} x {rows}")
    _, _, b, i0, j0 = min(options, key=lambda o: (o[0], o[1]))
    out = np.full((rows, cols, 2), np.nan)
    out[i0:i0 + b.shape[0], j0:j0 + b.shape[1]] = b
    return out, None
