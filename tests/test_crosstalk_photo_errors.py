"""Errors that differ from band photo to band photo, not from pixel to pixel (issue 51).

A camera whose exposure drifts between photos adds to each band photo's ratios a floor of its
own (the drift times black's light over white's).  Every part of the panel shares it, so a spread
over strips of rows does not see it; the jackknife over the photos does (``cone.photo_jackknife``:
bench case 23 under a phone's conditions had far views 3.5 sigma off without it).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from lenticalib.calib.crosstalk import cone

N, K = 32, 10


def _cone(t):
    t = np.mod(t + N / 2, N) - N / 2
    return 0.0005 + 0.45 * np.exp(-0.5 * (t / 0.75) ** 2)


def _normalised_row(fit, ratios, rows, cols, shifts):
    grid, values, counts = cone.profile_for(fit, ratios, rows, cols, shifts)
    row = cone.values_at_integers(grid, values, counts, N)
    return row / row.sum()


def test_a_floor_of_each_photo_is_in_the_jackknife_over_the_photos_not_in_the_spread_over_strips():
    rng = np.random.default_rng(21)
    rows, cols = np.mgrid[0:160, 0:320]
    rows, cols = rows.ravel(), cols.ravel()
    delta = 0.07 * cols + 0.004 * rows - 9.0  # 22 views across the region
    shifts = np.arange(K) * N / K
    floors = rng.normal(0.0, 0.002, K)  # exposure drift of +-4 % times a black of 5 % of white
    ratios = _cone(delta[:, None] + shifts[None, :]) + floors[None, :] + rng.normal(0, 0.01, (rows.size, K))
    fit = cone.fit_cone(ratios, rows, cols, shifts, N, (160, 320))
    row = _normalised_row(fit, ratios, rows, cols, shifts)
    truth = _cone(np.arange(N))
    truth = truth / truth.sum()
    error = np.abs(row - truth)
    strips = [_normalised_row(fit, ratios[rows // 10 == s], rows[rows // 10 == s], cols[rows // 10 == s], shifts)
              for s in range(16)]
    strip_sigma = np.std(np.array(strips), axis=0, ddof=1) / math.sqrt(16)
    photo_sigma = cone.jackknife_sigma(cone.photo_jackknife(fit, ratios, rows, cols, shifts))
    assert np.max(error / strip_sigma) > 4.0  # the strips share every photo's floor
    assert np.max(error / np.maximum(strip_sigma, photo_sigma)) < 3.0
    # without floors the jackknife is the noise, about what the strips show
    clean = _cone(delta[:, None] + shifts[None, :]) + rng.normal(0, 0.01, (rows.size, K))
    fit = cone.fit_cone(clean, rows, cols, shifts, N, (160, 320))
    jk = cone.jackknife_sigma(cone.photo_jackknife(fit, clean, rows, cols, shifts))
    strips = [_normalised_row(fit, clean[rows // 10 == s], rows[rows // 10 == s], cols[rows // 10 == s], shifts)
              for s in range(16)]
    spread = np.std(np.array(strips), axis=0, ddof=1) / math.sqrt(16)
    assert 0.3 < np.median(jk / spread) < 3.0


def test_the_figures_carry_the_jackknife_over_the_photos_as_the_row_does():
    from lenticalib.calib.crosstalk.result import figures_with_sigma

    rng = np.random.default_rng(4)
    row = _cone(np.arange(N))
    row = row / row.sum()
    blocks = row[None, :] * (1 + rng.normal(0, 1e-4, (16, N)))
    left_out = row[None, :] * (1 + rng.normal(0, 0.01, (K, N)))
    left_out /= left_out.sum(axis=1, keepdims=True)
    quiet = figures_with_sigma(row, {"blocks": blocks}, None)
    photos = figures_with_sigma(row, {"blocks": blocks, "photos-left-out": left_out}, None)
    own = [r[0] for r in left_out]
    expected = math.sqrt((K - 1) / K * np.sum((np.array(own) - np.mean(own)) ** 2))
    assert quiet["own_view_share"]["sigma"] < 0.2 * expected
    assert abs(photos["own_view_share"]["sigma"] - expected) < 1e-9


def test_the_figures_carry_each_views_scatter_independently():
    """A scatter of 0.001 on every view (``samples["far-scatter"]``) adds, to the non-adjacent
    crosstalk (the far views' sum over the own view), about sqrt(number of far views) x 0.001 /
    own in quadrature, and to the own-view share 0.001."""
    from lenticalib.calib.crosstalk.result import figures_with_sigma

    row = _cone(np.arange(N))
    row = row / row.sum()
    blocks = np.tile(row, (16, 1))
    quiet = figures_with_sigma(row, {"blocks": blocks}, None)
    scattered = figures_with_sigma(row, {"blocks": blocks, "far-scatter": np.full(N, 0.001)}, None)
    assert quiet["non_adjacent_crosstalk"]["sigma"] < 1e-9
    far = N - 3
    own = row[0]
    assert scattered["non_adjacent_crosstalk"]["sigma"] == pytest.approx(math.sqrt(far) * 0.001 / own, rel=0.05)
    assert scattered["own_view_share"]["sigma"] == pytest.approx(0.001, rel=1e-6)
