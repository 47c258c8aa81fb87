"""The fit's uncertainty: jackknife plus floors, propagated into the profile's constants.

Units: the plane (a, b, c0) of :mod:`.model` in cycles per subpixel, per row and cycles; the
reported figures in views.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import model
from ..patterns.calibration_patterns import FINE_PERIODS

REGISTRATION_FLOOR_PIXELS = 0.01  # working pixels, per photo: the error seen against known shake (RMS 0.008)
UNREGISTERED_PIXELS = 0.2  # working pixels: shake assumed for a photo whose shift was not measured


def constants_with_uncertainty(fit: model.PlaneFit, cov: np.ndarray) -> tuple[dict, dict]:
    """Profile constants and their 1-sigma, propagating the (a, b, c0) covariance numerically."""
    base = model.profile_constants(fit)
    params = np.array([fit.a, fit.b, fit.c0])
    steps = np.sqrt(np.maximum(np.diag(cov), 1e-30)) * 1e-2 + np.array([1e-12, 1e-12, 1e-9])
    jac = np.zeros((3, 3))
    keys = ("period", "slant", "offset")
    for j in range(3):
        p = params.copy()
        p[j] += steps[j]
        shifted = model.profile_constants(dataclasses.replace(fit, a=p[0], b=p[1], c0=p[2]))
        for i, k in enumerate(keys):
            d = shifted[k] - base[k]
            if k == "offset":
                d = (d + base["period"] / 2) % base["period"] - base["period"] / 2
            jac[i, j] = d / steps[j]
    out = jac @ cov @ jac.T
    sigmas = {k: float(math.sqrt(max(out[i, i], 0.0))) for i, k in enumerate(keys)}
    sigmas["reference_view"] = 0.0
    return base, sigmas


def quality_and_covariance(fit, samples, weights, cov, ps, n_views, registration_var: float = 0.0) -> tuple[dict, np.ndarray]:
    """Quality numbers and the final covariance of (a, b, c0).

    The covariance gets the systematic floor of :func:`model.systematic_floor`: at least
    ``model.SYSTEMATIC_FLOOR_VIEWS``, and at least the *smooth* misfit of the plane -- a
    low-order surface fitted to the block residuals.  Block residuals also hold measurement
    noise, which the jackknife already counts and which averages out in the plane; taking their
    raw RMS as a systematic floor made noisy (far, blurry) panels report several times their true
    error.  ``registration_var`` (cycles^2) is the variance the group registration leaves in c0.

    The residuals, in views, all from ``fit.residual(samples)`` (measured minus fitted, wrapped)
    with the fit's robust ``weights``: ``pixel_residual_rms_views`` their weighted RMS over the
    samples (one camera pixel's noise, mostly); ``block_residual_map`` (14, 24) their weighted
    mean in 24 x 14 panel blocks, less the mean over the blocks (NaN where a block has too few
    samples); ``block_residual_rms_views`` and ``_worst_views`` the weighted RMS and the largest
    magnitude of that map: the misfit of the plane, the fit's headline residual.
    """
    r = fit.residual(samples)
    # misfit: weighted mean residual in panel blocks of ~1/24 x 1/14 of the panel
    bx = np.clip((samples.x / (3 * ps.width) * 24).astype(int), 0, 23)
    by = np.clip((samples.y / ps.height * 14).astype(int), 0, 13)
    block = by * 24 + bx
    wsum = np.bincount(block, weights=weights, minlength=24 * 14)
    rsum = np.bincount(block, weights=weights * r, minlength=24 * 14)
    ok = wsum > np.percentile(wsum[wsum > 0], 10) * 0.5 if np.any(wsum > 0) else wsum > 0
    block_mean = np.where(ok, rsum / np.maximum(wsum, 1e-12), np.nan)
    block_mean -= np.average(block_mean[ok], weights=wsum[ok])  # the mean is the centring, reported apart
    bm = block_mean[ok]
    block_rms = float(np.sqrt(np.average(bm ** 2, weights=wsum[ok])) * n_views)
    smooth_rms = smooth_misfit(bm, (np.arange(24 * 14) % 24)[ok], (np.arange(24 * 14) // 24)[ok], wsum[ok]) * n_views
    cov = cov + model.systematic_floor(n_views, ps.width, ps.height, max(model.SYSTEMATIC_FLOOR_VIEWS, smooth_rms))
    cov[1, 1] += (model.SLANT_RELATIVE_FLOOR * fit.b) ** 2
    cov[2, 2] += registration_var
    corners = np.array([[0, 0], [3 * ps.width, 0], [0, ps.height], [3 * ps.width, ps.height],
                        [1.5 * ps.width, 0.5 * ps.height]], dtype=float)
    # relative to the panel centre (what a viewer sees as banding) and the centre itself (centring)
    grads = np.stack([corners[:, 0] - fit.x0, corners[:, 1] - fit.y0, np.zeros(len(corners))], axis=1)
    sig = np.sqrt(np.einsum("ij,jk,ik->i", grads, cov, grads)) * n_views
    sig[-1] = math.sqrt(cov[2, 2]) * n_views
    return {
        "coherence": float(fit.coherence),
        "pixel_residual_rms_views": float(np.sqrt(np.average(r ** 2, weights=weights)) * n_views),
        "block_residual_rms_views": block_rms,
        "block_residual_smooth_rms_views": smooth_rms,
        "block_residual_worst_views": float(np.max(np.abs(bm)) * n_views),
        "registration_sigma_views": float(math.sqrt(registration_var) * n_views),
        "predicted_error_centre_views": float(sig[-1]),
        "predicted_error_worst_views": float(np.max(sig[:-1])),
        "samples": int(samples.x.size),
        "block_residual_map": block_mean.reshape(14, 24) * n_views,  # views, NaN where too few samples
    }, cov


def smooth_misfit(values: np.ndarray, bx: np.ndarray, by: np.ndarray, weights: np.ndarray) -> float:
    """RMS (same unit as ``values``) of a cubic surface fitted to block residuals on a 24 x 14 grid.

    With ~300 blocks and 10 terms, noise enters the fitted surface at about a sixth of its RMS,
    while a misfit that spans the panel (the kind the plane's constants could absorb) stays.
    """
    u = (bx + 0.5) / 24 - 0.5
    v = (by + 0.5) / 14 - 0.5
    terms = np.stack([u ** i * v ** j for i in range(4) for j in range(4 - i)], axis=1)
    sw = np.sqrt(weights)
    coef, *_ = np.linalg.lstsq(terms * sw[:, None], values * sw, rcond=None)
    surface = terms @ coef
    surface -= np.average(surface, weights=weights)
    return float(np.sqrt(np.average(surface ** 2, weights=weights)))


def registration_variance(groups, shifts, x_sm, y_sm, valid, fit, used) -> float:
    """Variance (cycles^2) that residual registration errors leave in the plane's c0.

    A fine sample at pixel p pairs the fine phase with X, Y from the coordinate groups; a
    residual shift d between the fine group and x2 (y1) -- every photo registered to the same
    reference, whose own error cancels -- moves it by
    ``(1/T - 1/Delta_r) dX/dp d`` (``b dY/dp d``) cycles.  A group's shift is the mean of its
    photos' shifts, each known to ``max(sigma, REGISTRATION_FLOOR_PIXELS)``: the Cramer-Rao bound
    counts only noise, while the frame-based registration was seen off by more (see the
    constant) on simulated phone-like sets with known shifts.  ``shifts``: photo name ->
    {"sigma", "measured", ...} in photo pixels.
    """
    gy, gx = np.gradient(x_sm)
    hy, hx = np.gradient(y_sm)
    sel = valid & np.isfinite(gx) & np.isfinite(hy)
    dxdp = float(np.median(np.hypot(gx[sel], gy[sel])))
    dydp = float(np.median(np.hypot(hx[sel], hy[sel])))
    period = -1.0 / fit.a

    def sigma(name):
        photos = groups[name].photos
        total = 0.0
        for photo in photos:
            entry = shifts.get(photo.name)
            s = entry["sigma"] * photo.scale if entry and entry["measured"] else UNREGISTERED_PIXELS
            total += max(s, REGISTRATION_FLOOR_PIXELS) ** 2
        return math.sqrt(total) / len(photos)

    variances = []
    for gi, t in enumerate(FINE_PERIODS):
        if gi not in used:
            continue
        sf = sigma(f"f{t:g}")
        ex = abs(1.0 / t - 1.0 / period) * dxdp * math.sqrt(sf ** 2 + sigma("x2") ** 2)
        ey = abs(fit.b) * dydp * math.sqrt(sf ** 2 + sigma("y1") ** 2)
        variances.append(ex ** 2 + ey ** 2)
    return float(np.mean(variances)) if variances else 0.0
