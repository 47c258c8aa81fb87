"""The global model of a calibration: the view-coordinate plane and the subpixel order.

Convention (``docs/optics.md``): the calibration camera sits at ``w* = N/2``.  For a
fine pattern of period ``T`` whose lens alias is the first one (``T/Delta_r`` in (1/1.5, 2)),
a camera pixel seeing panel point (X, Y) measures the phase

    Phi / 2 pi = X / T + psi(X, Y)   (mod 1),    psi = (w*(X, Y) - N/2) / N,

and ``psi`` is a plane: ``psi = a X + b Y + c`` with ``a = -1/Delta_r``, ``b = 3 C_r / Delta_r``,
``c = Q0 / Delta_r`` (X in subpixels, Y in rows, continuous; Q0 the seen lens centre phase).
This module finds that plane from per-pixel samples (FFT search, then robust Gauss-Newton
on wrapped residuals), estimates honest 1-sigma uncertainties (spatial block jackknife plus
the disagreement between fine groups), and converts the plane into a profile.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...core.errors import CalibrationError


@dataclasses.dataclass
class PlaneSamples:
    """Per-pixel samples of psi: panel X (subpixels), Y (rows), psi (cycles), weight, group id."""

    x: np.ndarray
    y: np.ndarray
    psi: np.ndarray
    weight: np.ndarray
    group: np.ndarray


@dataclasses.dataclass
class PlaneFit:
    """psi = a (X - x0) + b (Y - y0) + c0, with reference point (x0, y0) (panel centre)."""

    a: float
    b: float
    c0: float
    x0: float
    y0: float
    coherence: float

    def psi(self, x, y):
        return self.a * (np.asarray(x) - self.x0) + self.b * (np.asarray(y) - self.y0) + self.c0

    def residual(self, samples: PlaneSamples) -> np.ndarray:
        return wrap(samples.psi - self.psi(samples.x, samples.y))


def wrap(cycles):
    """Wrap cycles into [-0.5, 0.5)."""
    return (np.asarray(cycles) + 0.5) % 1.0 - 0.5


def fft_search(samples: PlaneSamples, width: int, height: int, period_range: tuple[float, float],
               slant_limit: float = 0.6) -> tuple[float, float]:
    """Coarse (a, b) from the peak of the 2-D spectrum of exp(2 pi i psi) gridded on the panel.

    Grid cells are 3 subpixels x 2 rows; the search covers Delta_r in ``period_range`` and
    |C_r| <= ``slant_limit``.
    """
    cx, cy = 3.0, 2.0
    nx, ny = int(math.ceil(3 * width / cx)), int(math.ceil(height / cy))
    ix = np.clip((samples.x / cx).astype(np.int64), 0, nx - 1)
    iy = np.clip((samples.y / cy).astype(np.int64), 0, ny - 1)
    value = samples.weight * np.exp(2j * math.pi * samples.psi)
    grid = np.zeros(ny * nx, dtype=np.complex128)
    np.add.at(grid, iy * nx + ix, value)
    spectrum = np.abs(np.fft.fft2(grid.reshape(ny, nx)))
    fx = np.fft.fftfreq(nx, d=cx)  # cycles per subpixel
    fy = np.fft.fftfreq(ny, d=cy)  # cycles per row
    a_ok = (fx <= -1.0 / period_range[1]) & (fx >= -1.0 / period_range[0])
    b_ok = np.abs(fy) <= 3 * slant_limit / period_range[0]
    masked = np.where(b_ok[:, None] & a_ok[None, :], spectrum, -1.0)
    iy0, ix0 = np.unravel_index(int(np.argmax(masked)), masked.shape)

    def refine(s_m, s_0, s_p):
        den = s_m - 2 * s_0 + s_p
        return 0.0 if den == 0 else 0.5 * (s_m - s_p) / den

    dx = refine(spectrum[iy0, ix0 - 1], spectrum[iy0, ix0], spectrum[iy0, (ix0 + 1) % nx])
    dy = refine(spectrum[iy0 - 1, ix0], spectrum[iy0, ix0], spectrum[(iy0 + 1) % ny, ix0])
    return float(fx[ix0] + dx / (nx * cx)), float(fy[iy0] + dy / (ny * cy))


def _normal_equations(x, y, r, weights, block=None, nblocks=1):
    """Weighted sums for the 3-parameter linear step: A (nblocks, 3, 3), g (nblocks, 3)."""
    cols = (x, y, np.ones_like(x))
    if block is None:
        wc = [weights * c for c in cols]
        a1 = np.array([[np.dot(wc[i], cols[j]) for j in range(3)] for i in range(3)])
        return a1[None], np.array([np.dot(wc[i], r) for i in range(3)])[None]
    a = np.empty((nblocks, 3, 3))
    g = np.empty((nblocks, 3))
    for i in range(3):
        g[:, i] = np.bincount(block, weights=weights * cols[i] * r, minlength=nblocks)
        for j in range(i, 3):
            a[:, i, j] = a[:, j, i] = np.bincount(block, weights=weights * cols[i] * cols[j], minlength=nblocks)
    return a, g


def _robust_weights(r, w0):
    probe = np.abs(r[:: max(1, r.size // 200_000)])
    scale = 1.4826 * float(np.median(probe)) + 1e-6
    cut = max(4.685 * scale, 0.02)
    return w0 * np.where(np.abs(r) < cut, (1 - (r / cut) ** 2) ** 2, 0.0)


def fit_plane(samples: PlaneSamples, a: float, b: float, x0: float, y0: float,
              iterations: int = 12, keep: np.ndarray | None = None) -> tuple[PlaneFit, np.ndarray]:
    """Robust Gauss-Newton for (a, b, c0) from a start (a, b); returns the fit and final weights.

    Residuals are wrapped into [-0.5, 0.5) cycles; weights are the sample weights times a
    Tukey biweight on the residual (scale from the median absolute residual), so pixels on
    the wrong lens or in glare do not pull the plane.
    """
    sel = slice(None) if keep is None else keep
    x = samples.x[sel] - x0
    y = samples.y[sel] - y0
    psi = samples.psi[sel]
    w0 = samples.weight[sel]
    c0 = float(np.angle(np.sum(w0 * np.exp(2j * math.pi * (psi - a * x - b * y)))) / (2 * math.pi))
    weights = w0
    for _ in range(iterations):
        r = wrap(psi - (a * x + b * y + c0))
        weights = _robust_weights(r, w0)
        mat, grad = _normal_equations(x, y, r, weights)
        step = np.linalg.solve(mat[0], grad[0])
        a, b, c0 = a + step[0], b + step[1], c0 + step[2]
        if np.all(np.abs(step * [3000.0, 1000.0, 1.0]) < 1e-7):
            break
    coherence = float(np.abs(np.sum(w0 * np.exp(2j * math.pi * wrap(psi - (a * x + b * y + c0)))))
                      / max(np.sum(w0), 1e-12))
    return PlaneFit(float(a), float(b), float(wrap(c0)), x0, y0, coherence), weights


def block_jackknife(samples: PlaneSamples, fit: PlaneFit, weights: np.ndarray, width: int, height: int,
                    blocks: tuple[int, int] = (8, 6)) -> np.ndarray:
    """Covariance (3x3) of (a, b, c0) from a delete-one-block jackknife over panel blocks.

    Blocks of the panel (not of the photo) capture spatially correlated errors (moire,
    glare, JPEG blocks) that a per-pixel error model would miss.  Each replicate is one
    Gauss-Newton step from the full solution with that block's normal equations removed
    (the linearised jackknife; the robust ``weights`` of the full fit are kept).
    """
    nb = blocks[0] * blocks[1]
    bx = np.clip((samples.x / (3 * width) * blocks[0]).astype(int), 0, blocks[0] - 1)
    by = np.clip((samples.y / height * blocks[1]).astype(int), 0, blocks[1] - 1)
    block = by * blocks[0] + bx
    x, y = samples.x - fit.x0, samples.y - fit.y0
    r = fit.residual(samples)
    mat, grad = _normal_equations(x, y, r, weights, block, nb)
    total_a, total_g = mat.sum(axis=0), grad.sum(axis=0)
    counts = np.bincount(block, weights=(weights > 0).astype(float), minlength=nb)
    estimates = []
    for k in range(nb):
        if counts[k] < 200:
            continue
        estimates.append(np.linalg.solve(total_a - mat[k], total_g - grad[k]))
    est = np.asarray(estimates)
    m = len(est)
    if m < 3:
        raise CalibrationError("too little of the panel was measured to estimate uncertainties",
                               hint="photograph the whole panel, filling most of the frame")
    centred = est - est.mean(axis=0)
    return (m - 1) / m * centred.T @ centred


SYSTEMATIC_FLOOR_VIEWS = 0.012


def systematic_floor(views: int, width: int, height: int, floor: float = SYSTEMATIC_FLOOR_VIEWS) -> np.ndarray:
    """Covariance (3x3) of the method's systematic limit: ``floor`` views (1 sigma) each for the
    centring and for a linear trend reaching the panel's left/right and top/bottom edges.

    Measured on simulated capture sets (tools/bench_fit.py), the errors that neither the
    jackknife nor the fine-group comparison can see -- sub-0.02-row scale errors of the
    smoothed coordinate maps -- amount to about 0.01 view at the panel edges.
    """
    sa = floor / views / (1.5 * width)
    sb = floor / views / (0.5 * height)
    sc = floor / views
    return np.diag([sa * sa, sb * sb, sc * sc])


# The measured panel coordinates can be shrunk slightly toward the panel centre, which makes the
# fitted |C_r| too large: the one-sided fringe averaging at the bezel did this by ~5e-5 (fixed in
# fit.py by fitting only pixels whose averaging window lies on the panel); brightness fall-off
# across the panel and the camera's colour fringing still leave up to ~3e-5 (relative) on some
# simulated sets (under 0.06 view at the panel edges).  That residue is part of the reported
# slant uncertainty rather than corrected.
SLANT_RELATIVE_FLOOR = 4e-5


@dataclasses.dataclass
class OrderDecision:
    """Subpixel order from the red-only and blue-only photos.

    ``offset_r``/``offset_b``: measured phase offsets (cycles) of the red and blue light
    against the fitted model; ``expected_bgr``: the difference (b - r) a BGR panel gives
    (RGB gives 0); ``amplitude_r``/``_b``: fringe contrast relative to the green fine groups.
    """

    order: str
    offset_r: float
    offset_b: float
    expected_bgr: float
    margin: float
    amplitude_r: float
    amplitude_b: float


def decide_order(offset_r: float, offset_b: float, period: float, amplitude_r: float,
                 amplitude_b: float) -> OrderDecision:
    """RGB if blue minus red is near 0, BGR if near +4/period cycles (slots 0 and 2 swapped)."""
    expected = 4.0 / period
    d = float(wrap(offset_b - offset_r))
    dist_rgb, dist_bgr = abs(d), abs(float(wrap(d - expected)))
    order = "RGB" if dist_rgb <= dist_bgr else "BGR"
    margin = abs(dist_rgb - dist_bgr) / expected
    return OrderDecision(order, offset_r, offset_b, expected, margin, amplitude_r, amplitude_b)


def profile_constants(fit: PlaneFit) -> dict[str, float]:
    """(Delta_r, C_r, s_ref) with i_ref = 0 for a fitted plane; see the module docstring.

    The profile's ``w(x_s, y)`` is evaluated at the subpixel's left edge and row index,
    the measured ``w*`` at its centre (x_s + 0.5, y + 0.5): ``w(x_s, y) = w*(x_s + .5, y + .5)``.
    With i_ref = N/2: s_ref = Delta_r * psi(0.5, 0.5) ... reduced into [0, Delta_r).
    """
    period = -1.0 / fit.a
    slant = fit.b * period / 3.0
    psi_half = float(fit.psi(0.5, 0.5))
    offset = (period * psi_half) % period
    return {"period": period, "slant": slant, "offset": offset}
