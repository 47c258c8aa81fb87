"""A chessboard corner located by fitting a model of the image around it (the last step of every
corner's location).

``cv2.cornerSubPix`` finds the point where the image gradients in a window are orthogonal to the
lines from that point: it weighs the few pixels on the edges and, through a distorting lens, takes
the bent lines for straight ones.  Here every pixel of the window is fitted, in least squares, by a
blurred corner whose two lines may bend:

    I(p) = (m + A tanh(d1(p) / s) tanh(d2(p) / s)) (1 + g . (p - p0)),
    d_k(p) = n_k . (p - c) + kappa_k (t_k . (p - c))^2,

``c`` the corner (px), ``t_k = (cos a_k, sin a_k)`` the direction of line k and ``n_k`` its normal,
``kappa_k`` its curvature (1/px; held at 0 with ``curved=False``), ``s`` the blur (px), ``m`` and
``A`` the mean grey and half the contrast (A's sign tells which quadrants are dark), ``g`` the
light's gradient across the window (1/px, about the start point ``p0``): vignetting or a lamp to
one side makes one side's squares brighter than their opposites, which is not point-symmetric
and pulls a fit that holds the light even (0.05 px on the synthetic corners of
``tests/test_corner_model.py`` at 0.5 % per px).  The product
of two ``tanh`` is a blurred checker corner; the camera's tone curve, sharpening or a different
blur profile change its shape but not its point symmetry about ``c`` (for straight lines), so
they cost precision, not bias.  The bend of the lines under distortion is what ``kappa`` takes
up: to first order a line's curvature over a window, which moves a straight-line fit's corner
toward the concave side.

Measured against the simulator's true corners at 3000 x 2000 (``tools/bench_corners.py
--rectified``, the photos of ``tools/bench_camera.py --keep`` sets, the views rectified with the
true model; RMS per coordinate, and the mean radial error at 0.6-0.8 of the half diagonal, px,
+ outward, standard errors 0.0002-0.0011 px):

=========  ========================  ===========================  ============================
set        ``cornerSubPix`` alone    first pass (curved lines)    rectified view (straight)
=========  ========================  ===========================  ============================
mild 2     0.0100 px, +0.0009        0.007 px, +0.0011            0.003 px, +0.0011
strong 3   0.0114 px, +0.0167        0.007 px, -0.0006            0.003 px, -0.0008
wide 2     0.0141 px, +0.0078        0.007 px, -0.0008            0.004 px, -0.0012
phone 2    0.0198 px, +0.0038        0.010 px, -0.0009            0.005 px, +0.0004
=========  ========================  ===========================  ============================

(wide 2 at 0.8-1.0 of the half diagonal, the cut boards at the image corners: -0.178 +- 0.045 px
with ``cornerSubPix``, +0.012 +- 0.009 px in the first pass, +0.004 +- 0.005 px rectified).  A
straight-line fit in the photo itself is less noisy than the curved one but biased by the bend
(phone 2, light held even: 0.0070 px, -0.0064 px); in a view rectified with a solved lens model
(:mod:`.rectified`) the lines are straight, and it is the better one there.
"""

from __future__ import annotations

import numpy as np

FIT_MODEL = True  # False: the corners keep cornerSubPix's location, what plain OpenCV gives (a benchmark's baseline)
MAX_SHIFT = 1.0  # px: a fit that moves the corner further than this from its start is not that corner
MIN_CONTRAST = 8.0  # grey levels (of 255): |2 A| below this is no corner
SUBPIX_LIMITS = (2, 25)  # pixels: the least and most cornerSubPix half-window


def sample_bilinear(grey: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Bilinear grey values at pixel coordinates ``points`` (n, 2); NaN outside the image."""
    from scipy.ndimage import map_coordinates

    h, w = grey.shape
    inside = (points[:, 0] >= 0) & (points[:, 0] <= w - 1) & (points[:, 1] >= 0) & (points[:, 1] <= h - 1)
    values = np.full(len(points), np.nan)
    if inside.any():
        values[inside] = map_coordinates(grey.astype(np.float64), [points[inside, 1], points[inside, 0]], order=1)
    return values


def _model(params: np.ndarray, dx0: np.ndarray, dy0: np.ndarray, curved: bool):
    """Model values ``(n, P)`` and Jacobian ``(n, k, P)`` of ``n`` corners' parameters ``(n, k)``
    at their pixels' offsets ``dx0, dy0`` ``(n, P)`` from each start point."""
    col = [params[:, i:i + 1] for i in range(params.shape[1])]
    cx, cy, a1, a2, m, amp, s = col[:7]
    k1, k2 = (col[7], col[8]) if curved else (0.0, 0.0)
    gx, gy = col[-2], col[-1]
    dx, dy = dx0 - cx, dy0 - cy
    lines = []
    for a, k in ((a1, k1), (a2, k2)):
        ca, sa = np.cos(a), np.sin(a)
        e = ca * dx + sa * dy  # along the line
        d = ca * dy - sa * dx + k * e * e  # across it
        lines.append((np.tanh(d / s), d, e, ca, sa, k))
    (t1, d1, e1, c1, s1, k1), (t2, d2, e2, c2, s2, k2) = lines
    light = 1.0 + gx * dx0 + gy * dy0  # uneven light across the window
    core = m + amp * t1 * t2
    g1 = light * amp * t2 * (1.0 - t1 * t1) / s  # d I / d d1
    g2 = light * amp * t1 * (1.0 - t2 * t2) / s
    cols = [g1 * (s1 - 2 * k1 * e1 * c1) + g2 * (s2 - 2 * k2 * e2 * c2),  # d / d cx
            g1 * (-c1 - 2 * k1 * e1 * s1) + g2 * (-c2 - 2 * k2 * e2 * s2),  # d / d cy
            g1 * (-s1 * dy - c1 * dx + 2 * k1 * e1 * (c1 * dy - s1 * dx)),  # d / d a1
            g2 * (-s2 * dy - c2 * dx + 2 * k2 * e2 * (c2 * dy - s2 * dx)),  # d / d a2
            light, t1 * t2 * light, -(g1 * d1 + g2 * d2) / s]  # m, A, s
    if curved:
        cols += [g1 * e1 * e1, g2 * e2 * e2]
    cols += [core * dx0, core * dy0]
    return core * light, np.stack(np.broadcast_arrays(*cols), axis=1)


def _levenberg_marquardt(values, mask, dx0, dy0, p, curved, iterations=60):
    """Least squares of the masked residuals ``(model - values) * mask`` for every corner at once
    (``(n, P)`` each, parameters ``(n, k)``): Levenberg-Marquardt with Marquardt's diagonal
    scaling and a damping per corner.  Returns (parameters, converged ``(n,)`` bool)."""
    def residual(q, rows):
        """Masked residuals ``(m, P)`` and Jacobian ``(m, k, P)`` of the corners ``rows``."""
        value, jac = _model(q, dx0[rows], dy0[rows], curved)
        return (value - values[rows]) * mask[rows], jac * mask[rows][:, None]

    r, jac = residual(p, slice(None))
    cost = np.einsum("np,np->n", r, r)
    damping = np.full(len(p), 1e-3)
    done = np.zeros(len(p), bool)
    k = p.shape[1]
    for _ in range(iterations):
        live = ~done
        if not live.any():
            break
        jl, rl = jac[live], r[live]
        normal = jl @ jl.transpose(0, 2, 1)
        grad = (jl @ rl[..., None])[..., 0]
        diag = np.maximum(np.einsum("nkk->nk", normal), 1e-12)
        lhs = normal + damping[live, None, None] * diag[:, :, None] * np.eye(k)
        try:
            step = -np.linalg.solve(lhs, grad[..., None])[..., 0]
        except np.linalg.LinAlgError:
            break
        trial = p[live] + step
        r_new, jac_new = residual(trial, live)
        cost_new = np.einsum("np,np->n", r_new, r_new)
        better = np.isfinite(cost_new) & (cost_new <= cost[live])
        idx = np.flatnonzero(live)
        gain = cost[live] - cost_new
        ok = idx[better]
        p[ok] = trial[better]
        r[ok] = r_new[better]
        jac[ok] = jac_new[better]
        damping[ok] /= 3.0
        cost[ok] = cost_new[better]
        damping[idx[~better]] *= 4.0
        small = (better & (gain <= 1e-10 * cost_new + 1e-12)) | (np.abs(step[:, :2]).max(axis=1) < 1e-6)
        done[idx[small]] = True
        done[damping > 1e8] = True
    return p, done


def fit_windows(images, starts: np.ndarray, along: np.ndarray, down: np.ndarray, wins: np.ndarray,
                curved: bool = True) -> np.ndarray:
    """:func:`fit_corner` for many corners at once (one least-squares problem each, solved together).

    ARGUMENTS
    images        one ``(h, w)`` grey image (uint8 or float) holding every corner, or a sequence of
                  ``n`` images, one per corner (the rectified views of :mod:`.rectified`)
    starts        ``(n, 2)`` px, the corners' first locations
    along, down   ``(n, 2)`` px, the image vectors of one square along the board's rows and columns
    wins          ``(n,)`` int half-windows, px
    curved        as :func:`fit_corner`

    RETURNED VALUE
    float64 ``(n, 2)`` px, NaN where :func:`fit_corner` would give None.
    """
    starts = np.asarray(starts, np.float64).reshape(-1, 2)
    n = len(starts)
    out = np.full((n, 2), np.nan)
    wins = np.asarray(wins, int).reshape(n)
    per_corner = not isinstance(images, np.ndarray)
    rounded = np.round(starts).astype(int)
    inside = np.zeros(n, bool)
    for i in range(n):
        h, w = (images[i] if per_corner else images).shape
        x, y, r = rounded[i, 0], rounded[i, 1], wins[i]
        inside[i] = r >= 2 and x - r >= 0 and y - r >= 0 and x + r <= w - 1 and y + r <= h - 1
    pick = np.flatnonzero(inside)
    if not len(pick):
        return out
    top = int(wins[pick].max())
    u = np.arange(-top, top + 1)
    yy, xx = [a.ravel() for a in np.meshgrid(u, u, indexing="ij")]
    mask = ((np.abs(xx)[None] <= wins[pick, None]) & (np.abs(yy)[None] <= wins[pick, None])).astype(np.float64)
    values = np.zeros((len(pick), len(xx)))
    for row, i in enumerate(pick):
        image = images[i] if per_corner else images
        h, w = image.shape
        values[row] = image[np.clip(rounded[i, 1] + yy, 0, h - 1), np.clip(rounded[i, 0] + xx, 0, w - 1)]
    dx0 = (rounded[pick, 0:1] + xx[None] - starts[pick, 0:1]).astype(np.float64)  # offsets from the start
    dy0 = (rounded[pick, 1:2] + yy[None] - starts[pick, 1:2]).astype(np.float64)
    k = 11 if curved else 9
    p = np.zeros((len(pick), k))
    p[:, 2] = np.arctan2(along[pick, 1], along[pick, 0])
    p[:, 3] = np.arctan2(down[pick, 1], down[pick, 0])
    p[:, 5], p[:, 6] = 1.0, 1.5  # unit contrast and 1.5 px of blur, to shape the first guess
    shape, _ = _model(p, dx0, dy0, curved)
    mean = (values * mask).sum(axis=1) / mask.sum(axis=1)
    denom = (shape * shape * mask).sum(axis=1)
    good = denom > 0
    p[good, 4] = mean[good]
    p[good, 5] = ((values - mean[:, None]) * shape * mask).sum(axis=1)[good] / denom[good]
    p, converged = _levenberg_marquardt(values[good], mask[good], dx0[good], dy0[good], p[good], curved)
    cx, cy, amp, s = p[:, 0], p[:, 1], p[:, 5], p[:, 6]
    ok = (converged & np.all(np.isfinite(p), axis=1) & (np.hypot(cx, cy) <= MAX_SHIFT)
          & (np.abs(2 * amp) >= MIN_CONTRAST) & (np.abs(s) > 0.05) & (np.abs(s) < wins[pick][good]))
    rows = pick[good][ok]
    out[rows] = starts[rows] + np.stack([cx[ok], cy[ok]], axis=1)
    return out


def fit_corner(grey: np.ndarray, start: np.ndarray, along: np.ndarray, down: np.ndarray, win: int,
               curved: bool = True) -> np.ndarray | None:
    """The corner near ``start`` located by the model of the module docstring.

    ARGUMENTS
    grey        ``(h, w)`` grey image (uint8 or float)
    start       ``(2,)`` px, the corner's first location (e.g. ``cv2.cornerSubPix``'s)
    along, down ``(2,)`` px, the image vectors of one square along the board's rows and columns
                there (the two lines' directions)
    win         half-window, px: the ``(2 win + 1)^2`` pixels around the rounded start are fitted;
                the window must lie inside the image
    curved      fit the lines' curvature (in a photo) or hold them straight (in a rectified view)

    RETURNED VALUE
    float64 ``(2,)`` px, or None where the fit fails, finds no contrast, moves more than
    ``MAX_SHIFT`` px from ``start``, or the window leaves the image.
    """
    found = fit_windows(grey, np.asarray(start, np.float64)[None], np.asarray(along, np.float64)[None],
                        np.asarray(down, np.float64)[None], np.array([win]), curved)[0]
    return found if np.isfinite(found).all() else None


def axes(block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(step along a row, step down a column) of ``block`` (r, c, 2; NaN: none), px: the linear part
    of an affine map fitted from labels to pixels."""
    rows, cols = np.indices(block.shape[:2])
    ok = np.isfinite(block[..., 0])
    terms = np.stack([np.ones(ok.sum()), rows[ok], cols[ok]], axis=1).astype(np.float64)
    coef, *_ = np.linalg.lstsq(terms, block[ok], rcond=None)
    return coef[2], coef[1]


def local_axes(corners: np.ndarray) -> np.ndarray:
    """Per corner of a ``(rows, cols, 2)`` grid (NaN = missing), the image vectors (px) of one square
    along the board's columns and rows: float64 ``(rows, cols, 2, 2)``, ``[..., :, 0]`` along +x,
    ``[..., :, 1]`` along +y; central differences where both neighbours are known, one-sided where
    one is, NaN where none is."""
    axes = np.full(corners.shape[:2] + (2, 2), np.nan)
    for k, axis in enumerate((1, 0)):
        fwd = np.full(corners.shape, np.nan)
        bwd = np.full(corners.shape, np.nan)
        d = np.diff(corners, axis=axis)
        if axis == 1:
            fwd[:, :-1], bwd[:, 1:] = d, d
        else:
            fwd[:-1], bwd[1:] = d, d
        both = np.isfinite(fwd[..., 0]) & np.isfinite(bwd[..., 0])
        v = np.where(np.isfinite(fwd), fwd, bwd)
        v[both] = 0.5 * (fwd[both] + bwd[both])
        axes[..., :, k] = v
    return axes


def corner_axes(corners: np.ndarray) -> np.ndarray:
    """:func:`local_axes`, with the grid's own affine axes (:func:`axes`) for a corner that has no
    seen neighbour (a lone identified corner of a cut ChArUco board); NaN only where fewer than
    three corners are seen."""
    local = local_axes(corners)
    lone = np.isfinite(corners[..., 0]) & ~(np.isfinite(local[..., 0, 0]) & np.isfinite(local[..., 0, 1]))
    if lone.any() and np.isfinite(corners[..., 0]).sum() >= 3:
        along, down = axes(corners)
        filled = local[lone]
        filled[:, :, 0] = np.where(np.isfinite(filled[:, :, 0]), filled[:, :, 0], along)
        filled[:, :, 1] = np.where(np.isfinite(filled[:, :, 1]), filled[:, :, 1], down)
        local[lone] = filled
    return local


def fit_corners(grey: np.ndarray, corners: np.ndarray, win: int | np.ndarray, curved: bool) -> np.ndarray:
    """Every corner of a ``(rows, cols, 2)`` grid (NaN: not seen) located once more by
    :func:`.corner_model.fit_corner` in a half-window of ``win`` px (one for all, or an int
    ``(rows, cols)`` array), the lines' directions from its neighbours (:func:`corner_axes`).  Where
    the fit fails (no corner-like contrast, a crisp digital image with no blur to fit, a fit that
    wanders more than ``corner_model.MAX_SHIFT``) the corner keeps its location in ``corners``."""
    axes = corner_axes(corners)
    wins = np.broadcast_to(np.asarray(win), corners.shape[:2])
    out = corners.copy()
    ok = np.isfinite(corners[..., 0]) & np.isfinite(axes[..., 0, 0]) & np.isfinite(axes[..., 0, 1])
    fitted = fit_windows(grey, corners[ok], axes[ok][:, :, 0], axes[ok][:, :, 1], wins[ok], curved)
    out[ok] = np.where(np.isfinite(fitted), fitted, corners[ok])
    return out
