"""The seen-coordinate smoothing of the fit (``phase.smooth_coordinate``): its robust polynomial
(normal equations, least-squares fallback) against a known map with unwrapping outliers."""

import numpy as np

from lenticalib.calib.patterns import phase


def _known_map(h=300, w=400):
    """A smooth degree-3 coordinate map (subpixels) with perspective-like curvature, its weights."""
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float64)
    u, v = (cols - w / 2) / w, (rows - h / 2) / w
    truth = 2000.0 + 5400.0 * u + 310.0 * v + 80.0 * u * u - 45.0 * u * v + 12.0 * u ** 3
    weight = np.ones((h, w))
    weight[:20] = 0.0  # the bezel: not measured
    return truth, weight


def test_smoothing_recovers_the_map():
    truth, weight = _known_map()
    measured = truth + np.random.default_rng(4).normal(0.0, 0.05, truth.shape)
    smooth = phase.smooth_coordinate(measured, weight, sigma=4.0)
    inside = weight > 0
    assert np.isnan(smooth[~inside]).all()
    assert np.abs(smooth - truth)[inside].max() < 0.05


def test_the_polynomial_ignores_unwrapping_outliers():
    rng = np.random.default_rng(2)
    u, v = rng.uniform(-0.5, 0.5, 20000), rng.uniform(-0.3, 0.3, 20000)
    terms = phase._poly_terms(u, v, 4)
    coef = rng.normal(size=terms.shape[1]) * 100.0
    target = terms @ coef + rng.normal(0.0, 0.02, u.size)
    wrong = rng.random(u.size) < 0.05  # 5 % of the points on the wrong fringe (a period off)
    target[wrong] += rng.choice([-16.0, 16.0], wrong.sum())
    fitted = phase._robust_lstsq(terms, target, np.ones(u.size))
    assert np.abs(terms @ (fitted - coef)).max() < 0.01
    plain, *_ = np.linalg.lstsq(terms, target, rcond=None)  # what the reweighting is for
    assert np.abs(terms @ (plain - coef)).max() > 0.1


def test_the_robust_solve_matches_least_squares_and_survives_a_singular_design():
    rng = np.random.default_rng(1)
    u, v = rng.uniform(-0.5, 0.5, 5000), rng.uniform(-0.3, 0.3, 5000)
    terms = phase._poly_terms(u, v, 4)
    coef = rng.normal(size=terms.shape[1])
    target = terms @ coef + rng.normal(0.0, 1e-3, u.size)
    weights = rng.uniform(0.5, 1.0, u.size)
    # no outliers: each round is the weighted least-squares solution of the SVD solver
    sw = np.sqrt(weights)
    expected, *_ = np.linalg.lstsq(terms * sw[:, None], target * sw, rcond=None)
    assert np.allclose(phase._robust_lstsq(terms, target, weights, rounds=1), expected, rtol=0, atol=1e-9)
    # a repeated column: no unique solution; the fallback still fits the data
    doubled = np.column_stack([terms, terms[:, 1]])
    solved = phase._robust_lstsq(doubled, target, weights)
    assert np.sqrt(np.mean((doubled @ solved - target) ** 2)) < 2e-3
