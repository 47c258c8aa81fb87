"""The angular profile of one view, from the band sweeps (``docs/crosstalk.md``).

Frames and units: working pixels ``(row, col)``; view offsets ``t`` in views (zone widths).

Each band photo ``k``, divided by white (both black- and glare-corrected), gives at working
pixel ``p`` the share of white's light the camera receives from a one-view band centred
``delta(p) + c_k`` views from it: ``r_k(p) = a_k h(delta(p) + c_k)``.  ``h`` is the view's
angular profile (the view cone), ``c_k`` the pattern's shift, ``a_k`` the photo's exposure
relative to white (close to 1) and ``delta(p)`` a smooth function of the pixel (the sweep,
through the camera's perspective and the profile's residual errors).  Nothing about the camera
geometry is assumed: ``delta`` is a polynomial in the pixel coordinates, found with ``h`` and
``a_k`` from the photos themselves (:func:`fit_cone`):

1. start: the first Fourier harmonic of the ``K`` samples at each pixel gives ``delta`` (the
   harmonics near ``K`` alias into it, but they oscillate quickly across the panel and the
   polynomial averages them out);
2. repeat: ``h`` on a fine grid of offsets from all samples (bin means), ``a_k`` from each
   photo's ratio to it, ``delta``'s coefficients by Gauss-Newton on ``r_k - a_k h``; the origin of
   ``t`` is kept at ``h``'s centre (its first harmonic's phase) and at last moved to the middle
   of ``h``'s core (:func:`core_centre`), which is where an eye sits at the centre of a view's
   zone.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

BINS_PER_VIEW = 16
DEGREE = 6
MAX_SAMPLES = 40_000
ROUNDS = 6
FAR_FROM = 3  # views: the far views (|m| >= FAR_FROM) whose scatter about a smooth floor is judged (far_scatter)


@dataclasses.dataclass
class ConeFit:
    """``coefficients``: delta's polynomial (terms of :func:`_terms`); ``scale``: (x0, y0, s) of the
    normalised coordinates; ``gains``: (K,) a_k; ``grid``, ``profile``: h on the bin centres
    (views, share of white); ``rms``: residual of ``r_k - a_k h`` (share of white)."""

    views: int
    coefficients: np.ndarray
    scale: tuple[float, float, float]
    degree: int
    gains: np.ndarray
    grid: np.ndarray
    profile: np.ndarray
    rms: float

    def delta(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """delta (views, unwrapped) at working pixels."""
        return _terms(rows, cols, self.scale, self.degree) @ self.coefficients


def _terms(rows, cols, scale, degree=DEGREE):
    x0, y0, s = scale
    u = (np.asarray(cols, np.float64) - x0) / s
    v = (np.asarray(rows, np.float64) - y0) / s
    pu, pv = [np.ones_like(u)], [np.ones_like(v)]
    for _ in range(degree):
        pu.append(pu[-1] * u)
        pv.append(pv[-1] * v)
    return np.stack([pu[i] * pv[j] for i in range(degree + 1) for j in range(degree + 1 - i)], axis=-1)


def binned_profile(t: np.ndarray, values: np.ndarray, views: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bin means of ``values`` over offsets ``t`` (views, any), periodic with ``views``.

    RETURNED VALUE
    (grid (B,) bin centres in [-N/2, N/2), means (B,), counts (B,)); empty bins are filled by
    periodic linear interpolation.
    """
    bins = views * BINS_PER_VIEW
    index = np.floor(np.mod(np.asarray(t) + views / 2.0, views) * BINS_PER_VIEW).astype(np.int64) % bins
    counts = np.bincount(index, minlength=bins).astype(np.float64)
    sums = np.bincount(index, weights=values, minlength=bins)
    grid = (np.arange(bins) + 0.5) / BINS_PER_VIEW - views / 2.0
    means = np.divide(sums, counts, out=np.zeros(bins), where=counts > 0)
    filled = counts > 0
    if not filled.all() and filled.sum() >= 2:
        means[~filled] = np.interp(grid[~filled], grid[filled], means[filled], period=views)
    return grid, means, counts


def profile_at(grid: np.ndarray, profile: np.ndarray, t: np.ndarray, views: int) -> np.ndarray:
    """h at offsets ``t`` (periodic linear interpolation of the table)."""
    return np.interp(np.mod(np.asarray(t) + views / 2.0, views) - views / 2.0, grid, profile, period=views)


def centre_of(grid: np.ndarray, profile: np.ndarray, views: int) -> float:
    """The profile's centre (views): the phase of its first harmonic (robust, the fit's start)."""
    z = np.sum(profile * np.exp(2j * math.pi * grid / views))
    return float(np.angle(z) * views / (2 * math.pi))


def core_centre(grid: np.ndarray, profile: np.ndarray, views: int) -> float:
    """The centre of the profile's core (views): the centroid of its part above half its height.

    The zone centre is where a view's subpixels send their light, the middle of the cone's core.
    The first harmonic's phase (:func:`centre_of`) is pulled by asymmetric tails (a blur growing
    with the angle, a lens' aperture, a long tail: bench case 22 had it 0.013 view off the core,
    and the neighbours 0.003 off at 3 sigma); the core is not.  Height is above the profile's
    floor (its 5th percentile); the core is the run of bins above half height (3-bin running
    mean) around the highest point within ``N/4`` of the harmonic centre.  A profile with no such
    run of at least 3 bins (flat, all noise) keeps the harmonic centre.
    """
    start = centre_of(grid, profile, views)
    d = np.mod(grid - start + views / 2.0, views) - views / 2.0
    order = np.argsort(d)
    d, h = d[order], profile[order]
    smooth = np.convolve(np.pad(h, 1, mode="wrap"), np.ones(3) / 3.0, mode="valid")
    window = np.abs(d) <= views / 4.0
    if not window.any():
        return start
    peak = int(np.flatnonzero(window)[np.argmax(smooth[window])])
    floor = float(np.percentile(h, 5))
    level = floor + 0.5 * (smooth[peak] - floor)
    if not smooth[peak] > floor:
        return start
    lo = hi = peak
    while lo > 0 and smooth[lo - 1] > level:
        lo -= 1
    while hi < h.size - 1 and smooth[hi + 1] > level:
        hi += 1
    weight = np.clip(h[lo:hi + 1] - level, 0.0, None)
    if hi - lo < 2 or not weight.sum() > 0:
        return start
    return start + float(np.sum(weight * d[lo:hi + 1]) / weight.sum())


def column_angle(mask: np.ndarray) -> float:
    """The panel's columns in the photo (radians from the working image's vertical, + towards +x
    going down), from the sides of the smallest rectangle around the panel mask (bool (h, w))."""
    import cv2

    points = np.argwhere(mask)[:, ::-1].astype(np.float32)  # (x, y)
    corners = cv2.boxPoints(cv2.minAreaRect(points))
    sides = np.diff(np.vstack([corners, corners[:1]]), axis=0)
    dx, dy = sides[int(np.argmax(np.abs(sides[:, 1]) - np.abs(sides[:, 0])))]
    if dy < 0:
        dx, dy = -dx, -dy
    return float(math.atan2(dx, dy))


def average_along_columns(image: np.ndarray, inside: np.ndarray, sigma: float, angle: float = 0.0) -> np.ndarray:
    """``image`` (h, w) averaged along the panel's columns with a Gaussian of ``sigma`` working
    pixels, over the pixels where ``inside`` (bool (h, w)) only; ``angle`` from :func:`column_angle`.

    Why: a one-view band lights whole subpixels, about ``Delta_r / N`` of a subpixel per lens, and
    which one lights depends on where the subpixel grid falls under each lens.  That phase beats
    between the lens pitch and the subpixel pitch (a moire tens of lenses long, which a close
    camera resolves), so one photo's ratio at one pixel is the band seen at one phase, 0 or full,
    while ``h`` is its average over all phases, which is what an eye sees over a region.  Along a
    panel column the sweep ``delta`` stays put (``b`` depends on the column only) while the phase
    runs through the moire, so averaging there makes the ratios the model's without blurring the
    sweep."""
    import cv2

    radius = int(math.ceil(3 * sigma))
    size = 2 * radius + 1
    kernel = np.zeros((size, size), np.float32)
    for s in np.arange(-3 * sigma, 3 * sigma + 0.25, 0.25):
        x, y = radius + s * math.sin(angle), radius + s * math.cos(angle)
        x0, y0 = int(math.floor(x)), int(math.floor(y))
        fx, fy = x - x0, y - y0
        w = math.exp(-0.5 * (s / sigma) ** 2)
        for xi, yi, wi in ((x0, y0, (1 - fx) * (1 - fy)), (x0 + 1, y0, fx * (1 - fy)),
                           (x0, y0 + 1, (1 - fx) * fy), (x0 + 1, y0 + 1, fx * fy)):
            if 0 <= xi < size and 0 <= yi < size:
                kernel[yi, xi] += w * wi
    weight = inside.astype(np.float32)
    summed = cv2.filter2D(np.where(inside, image, 0.0).astype(np.float32), -1, kernel, borderType=cv2.BORDER_CONSTANT)
    norm = cv2.filter2D(weight, -1, kernel, borderType=cv2.BORDER_CONSTANT)
    return summed / np.maximum(norm, 1e-6)


def _least_squares(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x (T,) minimising ``|a x - b|`` for a tall ``a`` (n, T) with few columns: the normal
    equations of ``a`` with its columns scaled to unit length, solved as a T x T system (LAPACK's
    tall least squares runs a hundred times slower when its threads compete for a few busy cores).
    For delta's polynomial terms over a panel the scaled Gram matrix's condition number is a few
    thousand: about twelve digits are kept."""
    norm = np.sqrt(np.einsum("ij,ij->j", a, a))
    norm[norm == 0] = 1.0
    scaled = a / norm
    x, *_ = np.linalg.lstsq(scaled.T @ scaled, scaled.T @ b, rcond=None)
    return x / norm


def _initial_delta(ratios: np.ndarray, shifts: np.ndarray, views: int) -> np.ndarray:
    """Per-sample first-harmonic estimate of delta (views, wrapped to [-N/2, N/2))."""
    phasors = np.exp(-2j * math.pi * shifts / views)
    z = ratios @ phasors  # (n,)
    return np.angle(z) * views / (2 * math.pi)


def _coherence(z, u, values, views):
    """``|mean(z exp(-2 pi i g u / N))|`` for each ``g`` of ``values`` (float (G,), evenly spaced).

    ``exp(-2 pi i g u / N)`` splits into a coarse and a fine factor (``g = g_0 + m a + b``), so
    ``G`` coherences cost ``~2 sqrt(G)`` complex exponentials per sample and one matrix product."""
    values = np.asarray(values, np.float64)
    step = values[1] - values[0] if values.size > 1 else 1.0
    m = max(1, int(math.ceil(math.sqrt(values.size))))
    coarse = values[0] + step * m * np.arange(-(-values.size // m))
    fine = step * np.arange(m)
    a = np.exp(np.outer(coarse, -2j * math.pi * u / views)) * z[None, :]
    b = np.exp(np.outer(fine, -2j * math.pi * u / views))
    return np.abs(a @ b.T).ravel()[:values.size] / z.size


def _unwrap_to_plane(rows, cols, wrapped, views, scale, terms):
    """Fit delta's polynomial (``terms``: :func:`_terms` of the samples) to wrapped samples: a plane
    first (2D FFT-free grid search of the sweep's gradient), then unwrapping against it and the
    full polynomial."""
    x0, y0, s = scale
    u = (cols - x0) / s
    v = (rows - y0) / s
    # coarse search for the gradient (views per normalised unit) maximising coherence: along x,
    # then along y at the best x gradient (the first of equal scores wins)
    z = np.exp(2j * math.pi * wrapped / views)
    gxs = np.linspace(-400, 400, 801)
    scores = _coherence(z, u, gxs, views)
    gx, gy, best = float(gxs[int(np.argmax(scores))]), 0.0, float(scores.max())
    gys = np.linspace(-100, 100, 201)
    scores = _coherence(z * np.exp(-2j * math.pi * gx * u / views), v, gys, views)
    if scores.max() > best:
        gy = float(gys[int(np.argmax(scores))])
    # refine the gradient finely: a 21 x 21 grid around it, separable in x and y
    for span in (1.0, 0.1):
        steps = np.linspace(-span, span, 21)
        z0 = z * np.exp(-2j * math.pi * (gx * u + gy * v) / views)
        ex = np.exp(np.outer(steps, -2j * math.pi * u / views)) * z0[None, :]
        ey = np.exp(np.outer(steps, -2j * math.pi * v / views))
        a, b = np.unravel_index(int(np.argmax(np.abs(ex @ ey.T))), (steps.size, steps.size))
        gx, gy = gx + steps[a], gy + steps[b]
    plane = gx * u + gy * v
    offset = np.angle(np.mean(z * np.exp(-2j * math.pi * plane / views))) * views / (2 * math.pi)
    plane = plane + offset
    unwrapped = plane + (np.mod(wrapped - plane + views / 2.0, views) - views / 2.0)
    weights = np.ones_like(unwrapped)
    for _ in range(4):  # robust: the aliasing makes some samples far off
        coef = _least_squares(terms * weights[:, None], unwrapped * weights)
        resid = unwrapped - terms @ coef
        scale_r = 1.4826 * np.median(np.abs(resid)) + 1e-6
        weights = 1.0 / np.maximum(1.0, np.abs(resid) / (2.5 * scale_r))
        unwrapped = terms @ coef + (np.mod(unwrapped - terms @ coef + views / 2.0, views) - views / 2.0)
    return coef


def _gains(r: np.ndarray, model: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """float (K,): each photo's exposure ``a_k``, the least-squares scale of the model ``model``
    (n, K) onto the ratios ``r`` (n, K), normalised to a median of 1 (a band seen only in the
    cone's tails, whose scale can be anything, does not move the others').  A band whose scale is not positive
    (the pixels do not show it: a region narrower than the band spacing, where the band lies in
    the cone's dark tail, exactly 0 on noiseless photos) cannot tell its exposure and keeps
    ``previous``: the centre region of a noiseless set at 500 mm showed four bands at 0, a gain of
    0 made the profile NaN and the measurement ended in a traceback.  Bands seen only faintly keep
    their own scale: held at the whole panel's exposure instead (below 0.1 % of the median band's
    energy), hard case 1's own-view share moved from 0.0039 to 0.0066 off."""
    energy = np.sum(model ** 2, axis=0)
    scale = np.sum(r * model, axis=0) / np.maximum(energy, 1e-30)
    gains = np.where(scale > 0, scale, previous)
    return gains / np.median(gains)


def fit_cone(ratios: np.ndarray, rows: np.ndarray, cols: np.ndarray, shifts: np.ndarray, views: int,
             shape: tuple[int, int], seed: int = 0, degree: int = DEGREE, start: "ConeFit | None" = None) -> ConeFit:
    """Fit delta(p), the gains and the profile h to band ratios.

    ARGUMENTS
    ratios       float (n, K): r_k at n working pixels (share of white)
    rows, cols   int (n,): the pixels
    shifts       float (K,): c_k, views
    views        N
    shape        (h, w) of the working image (for the coordinate normalisation)
    degree       of delta's polynomial (the whole panel: DEGREE; one region: less)
    start        a fit to start from (its delta and gains), instead of the harmonic start and search
    """
    rng = np.random.default_rng(seed)
    n, k = ratios.shape
    pick = rng.choice(n, size=min(MAX_SAMPLES, n), replace=False)
    r, rr, cc = ratios[pick], rows[pick].astype(np.float64), cols[pick].astype(np.float64)
    scale = (float(cc.mean()), float(rr.mean()), max(shape) / 2.0)
    terms = _terms(rr, cc, scale, degree)
    if start is None:
        coef = _unwrap_to_plane(rr, cc, _initial_delta(r, shifts, views), views, scale, terms)
        gains = np.ones(k)
    else:
        coef = _least_squares(terms, start.delta(rr, cc))
        gains = start.gains.copy()
    grid = profile = None
    rms = math.nan
    for _ in range(ROUNDS):
        delta = terms @ coef
        t = delta[:, None] + shifts[None, :]
        grid, profile, _ = binned_profile(t.ravel(), (r / gains[None, :]).ravel(), views)
        centre = centre_of(grid, profile, views)
        coef[0] -= centre  # keep t's origin at the profile's centre
        delta = terms @ coef
        t = delta[:, None] + shifts[None, :]
        grid, profile, _ = binned_profile(t.ravel(), (r / gains[None, :]).ravel(), views)
        model = profile_at(grid, profile, t, views)
        gains = _gains(r, model, gains)
        # Gauss-Newton step on delta's coefficients: the Jacobian's row for sample (p, k) is
        # w_pk terms_p (w = a_k h'), so its normal equations are those of one row per pixel,
        # sqrt(sum_k w_pk^2) terms_p against sum_k w_pk r_pk / sqrt(sum_k w_pk^2): the same step
        # from a system K times smaller
        slope = (profile_at(grid, profile, t + 0.05, views) - profile_at(grid, profile, t - 0.05, views)) / 0.1
        resid = r - gains[None, :] * model
        w = gains[None, :] * slope
        norm = np.sqrt(np.sum(w ** 2, axis=1))
        rhs = np.divide(np.sum(w * resid, axis=1), norm, out=np.zeros_like(norm), where=norm > 0)
        step = _least_squares(terms * norm[:, None], rhs)
        coef = coef + step
        rms = float(np.sqrt(np.mean(resid ** 2)))
    delta = terms @ coef
    t = delta[:, None] + shifts[None, :]
    grid, profile, _ = binned_profile(t.ravel(), (r / gains[None, :]).ravel(), views)
    coef[0] -= core_centre(grid, profile, views)  # t's origin at the zone centre (the core's middle)
    t = (terms @ coef)[:, None] + shifts[None, :]
    grid, profile, _ = binned_profile(t.ravel(), (r / gains[None, :]).ravel(), views)
    return ConeFit(views, coef, scale, degree, gains, grid, profile, rms)


def profile_for(fit: ConeFit, ratios: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                shifts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """h (bin means on fit.grid) from the samples of some pixels (a region), with the fit's delta and gains."""
    t = fit.delta(rows, cols)[:, None] + shifts[None, :]
    return binned_profile(t.ravel(), (ratios / fit.gains[None, :]).ravel(), fit.views)


def values_at_integers(grid: np.ndarray, profile: np.ndarray, counts: np.ndarray, views: int,
                       half_width: float = 0.25) -> np.ndarray:
    """h at integer offsets m = 0, 1, ..., N-1 (m and m - N the same): a weighted local quadratic
    fit of the bin means within ``half_width`` views of each integer (narrow: over +-0.5 view a
    quadratic would flatten a sharp view's peak by about 1 %)."""
    out = np.empty(views)
    for m in range(views):
        centre = m if m < views / 2 else m - views
        d = np.mod(grid - centre + views / 2.0, views) - views / 2.0
        near = np.abs(d) <= half_width
        w = counts[near]
        if w.sum() <= 0 or near.sum() < 3:
            out[m] = profile_at(grid, profile, np.array([centre]), views)[0]
            continue
        a = np.stack([np.ones(near.sum()), d[near], d[near] ** 2], axis=1)
        coef, *_ = np.linalg.lstsq(a * np.sqrt(w)[:, None], profile[near] * np.sqrt(w), rcond=None)
        out[m] = coef[0]
    return out


def jackknife_sigma(values: np.ndarray) -> np.ndarray:
    """The jackknife's 1-sigma ``sqrt((K - 1) / K sum_k (v_k - mean)^2)`` of leave-one-out values
    ``values`` (K, ...) along their first axis; zeros where fewer than 2."""
    values = np.asarray(values, np.float64)
    if values.shape[0] < 2:
        return np.zeros(values.shape[1:])
    count = values.shape[0]
    return np.sqrt((count - 1) / count * np.sum((values - values.mean(axis=0)) ** 2, axis=0))


def photo_jackknife(fit: ConeFit, ratios: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                    shifts: np.ndarray) -> np.ndarray:
    """float (K', N): the row (h at the integers, normalised to sum 1) with each band photo ``k``
    left out in turn (K' of the K: a left-out row with no light is dropped); its spread
    (:func:`jackknife_sigma`) is the row's 1-sigma over the photos.  What differs from photo to photo and not from pixel to pixel shows here and not in
    a spread over parts of the panel: an exposure that drifted by ``e_k`` adds ``e_k`` times black's
    light over white's to each of the photo's ratios, a floor of its own (bench case 23 under a
    phone's conditions: far views up to 3.5 sigma off with the spread over strips of rows alone).
    ``ratios`` (n, K), ``rows``/``cols`` (n,) working pixels, ``shifts`` (K,) views; ``fit`` gives
    delta and the photos' exposures."""
    t = fit.delta(rows, cols)[:, None] + np.asarray(shifts, np.float64)[None, :]
    scaled = ratios / fit.gains[None, :]
    count = t.shape[1]
    left_out = []
    for k in range(count):
        keep = np.arange(count) != k
        grid, profile, counts = binned_profile(t[:, keep].ravel(), scaled[:, keep].ravel(), fit.views)
        row = values_at_integers(grid, profile, counts, fit.views)
        if row.sum() > 0:
            left_out.append(row / row.sum())
    return np.array(left_out).reshape(len(left_out), fit.views)


def local_offsets(fit: ConeFit, ratios: np.ndarray, rows: np.ndarray, cols: np.ndarray, shifts: np.ndarray,
                  tile: int = 16) -> np.ndarray:
    """How far the sweep model is off, tile by tile: for each ``tile`` x ``tile`` block of working
    pixels, the shift of delta (views, searched over +-0.5 in 1/32 steps) that best fits its
    samples.  Their spread is the model's local error, which smears the measured cone."""
    key = (rows // tile) * 100_000 + cols // tile
    order = np.argsort(key, kind="stable")
    key, r, rr, cc = key[order], ratios[order], rows[order], cols[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    ends = np.r_[starts[1:], key.size]
    candidates = np.arange(-16, 17) / 32.0
    out = []
    for a, b in zip(starts, ends):
        if b - a < tile * tile // 2:
            continue
        t = fit.delta(rr[a:b], cc[a:b])[:, None] + shifts[None, :]
        best, best_err = 0.0, math.inf
        for c in candidates:
            model = profile_at(fit.grid, fit.profile, t + c, fit.views) * fit.gains[None, :]
            err = float(np.sum((r[a:b] - model) ** 2))
            if err < best_err:
                best, best_err = c, err
        out.append(best)
    return np.array(out)


def far_scatter(row: np.ndarray) -> float:
    """The scatter of the row's views about a smooth cone, read on its far views (offsets
    ``|m| >= FAR_FROM``): a 1-sigma of every view (share of white's light).

    ``row`` (N,): h at the integer offsets (m and m - N the same).  The far views' light comes from
    the lens' blur tails, scatter and glare, all smooth in the offset; what the sampling of each
    offset (which photos and pixels reached it, their floors) leaves there is common to every
    strip of rows and every band photo, so neither spread shows it (bench hard cases 13-23: view
    23 read -0.0012 for 0.0011, 2.5-3.2 times its sigma, from linear photos and JPEGs alike), and
    it is the same at every offset, the own view's too.  Each far view's second difference
    ``h(m) - (h(m - 1) + h(m + 1)) / 2`` is that scatter times sqrt(3/2) where the cone is smooth;
    their robust spread (1.4826 times the median absolute value: the steep flank of a long-tailed
    cone next to the core does not count) over sqrt(3/2) is the 1-sigma."""
    row = np.asarray(row, np.float64)
    n = row.size
    signed = np.where(np.arange(n) < n / 2, np.arange(n), np.arange(n) - n)
    far = np.abs(signed) >= FAR_FROM
    second = row - 0.5 * (np.roll(row, 1) + np.roll(row, -1))
    if np.count_nonzero(far) < 8 or not np.all(np.isfinite(second[far])):
        return 0.0
    return float(1.4826 * np.median(np.abs(second[far])) / math.sqrt(1.5))
