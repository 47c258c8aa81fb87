"""Board corners refined where the board's lines are straight: ``cv2.cornerSubPix`` in a locally rectified patch.

Why.  ``cornerSubPix`` finds the point that every image gradient in its window points away from
(or along to): exact for an ink corner whose two lines are straight, whatever their angle, the
blur or the tone curve (such a corner is point-symmetric).  Through a distorting lens the lines
bend within the window, both halves of a line to the same side, and the point moves toward that
side: measured with ``tools/bench_corners.py`` on the simulator's sets at 3000 x 2000 (a window of
0.35 of a square), +0.005 px outward near the centre, +0.01 to +0.014 px at mid-radius, and on
the corners of boards cut by the frame near the image corners of the wide-angle lens -0.13 px.
The solve cannot average such an error away: it is the same in every photo at that radius.

How.  Around each corner the board's own corners give the map from board squares to pixels: a
cubic in (u, v) (squares along a row and down a column) fitted to the corner's neighbours within
``NEIGHBOURS`` rows and columns (one more for a corner on the edge of what is seen; at least
``MIN_NEIGHBOURS`` of them, on four rows and four columns), pinned at the corner's current
position.  (A quadratic from the eight nearest left -0.08 px at the wide lens's image corners
where the cubic leaves -0.04 px, seed 1.)  The image is resampled through that map (``cv2.remap``, bicubic) into
a patch in which the board's lines are straight and square to the patch's axes, one patch pixel
about one image pixel; ``cornerSubPix`` runs there with the same window, and its answer is mapped
back.  Twice, re-centred.  A corner without enough neighbours keeps its plain ``cornerSubPix``
position; one whose patch would leave the image is dropped (NaN), as a plain window would be.

Shapes: corners float64 ``(rows, cols, 2)`` pixels, NaN where not seen; the same comes back.
"""

from __future__ import annotations

import numpy as np

NEIGHBOURS = 2  # rows and columns either side whose corners fit the local map
MIN_NEIGHBOURS = 12  # neighbours the cubic map needs (10 unknowns per coordinate, pinned: 9)
PASSES = 2
BORDER_PX = 2  # patch pixels beyond the window that cornerSubPix reads


def _terms(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Cubic map terms without the constant: (n, 9) of u, v, u^2, u v, v^2, u^3, u^2 v, u v^2, v^3."""
    return np.stack([u, v, u * u, u * v, v * v, u ** 3, u * u * v, u * v * v, v ** 3], axis=-1)


def local_map(corners: np.ndarray, i: int, j: int, centre: np.ndarray) -> np.ndarray | None:
    """Coefficients (9, 2) of the cubic map from square offsets (u, v) about corner (i, j) to pixel
    offsets from ``centre``, fitted to its seen neighbours within ``NEIGHBOURS`` rows and columns,
    or (a corner on the edge of what is seen) one more; None with too few of them."""
    for reach in (NEIGHBOURS, NEIGHBOURS + 1):
        coef = _fit(corners, i, j, centre, reach)
        if coef is not None:
            return coef
    return None


def _fit(corners: np.ndarray, i: int, j: int, centre: np.ndarray, reach: int) -> np.ndarray | None:
    rows, cols = corners.shape[:2]
    di, dj = np.meshgrid(np.arange(-reach, reach + 1), np.arange(-reach, reach + 1), indexing="ij")
    ii, jj = i + di.ravel(), j + dj.ravel()
    keep = (ii >= 0) & (ii < rows) & (jj >= 0) & (jj < cols) & ~((ii == i) & (jj == j))
    ii, jj = ii[keep], jj[keep]
    seen = np.isfinite(corners[ii, jj, 0])
    ii, jj = ii[seen], jj[seen]
    if len(ii) < MIN_NEIGHBOURS or len(set(ii.tolist())) < 4 or len(set(jj.tolist())) < 4:
        return None
    terms = _terms((jj - j).astype(np.float64), (ii - i).astype(np.float64))
    coef, *_ = np.linalg.lstsq(terms, corners[ii, jj] - centre, rcond=None)
    return coef


def refine(grey: np.ndarray, corners: np.ndarray, window: np.ndarray) -> np.ndarray:
    """The ``corners`` (rows, cols, 2; NaN: not seen) refined in rectified patches (module
    docstring); ``window`` the cornerSubPix half-window (px) of each corner, (rows, cols) int."""
    import cv2

    image = grey.astype(np.float32)
    h, w = grey.shape
    out = corners.copy()
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-5)
    for _ in range(PASSES):
        current = out.copy()  # every map of a pass from the same corners
        for i, j in zip(*np.nonzero(np.isfinite(current[..., 0]))):
            centre = current[i, j]
            coef = local_map(current, i, j, centre)
            if coef is None:
                continue
            side = float(np.sqrt(np.linalg.norm(coef[0]) * np.linalg.norm(coef[1])))  # px per square
            win = int(window[i, j])
            half = win + BORDER_PX + 1
            s = 1.0 / side  # squares per patch pixel
            a = np.arange(-half, half + 1, dtype=np.float64) * s
            uu, vv = np.meshgrid(a, a)
            mapped = centre + _terms(uu, vv) @ coef
            if not (mapped.min() >= 1 and mapped[..., 0].max() <= w - 2 and mapped[..., 1].max() <= h - 2):
                out[i, j] = np.nan  # the photo's edge within the window: not located reliably
                continue
            patch = cv2.remap(image, mapped[..., 0].astype(np.float32), mapped[..., 1].astype(np.float32),
                              cv2.INTER_CUBIC)
            found = cv2.cornerSubPix(patch, np.array([[[half, half]]], np.float32), (win, win), (-1, -1),
                                     criteria).reshape(2).astype(np.float64)
            u, v = (found - half) * s
            if max(abs(u), abs(v)) * side > 0.5 * win:  # ran off: keep the plain position
                continue
            out[i, j] = centre + _terms(np.array(u), np.array(v)) @ coef
    return out
