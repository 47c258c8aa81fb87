"""A corner located by fitting a blurred-corner model (:mod:`lenticalib.calib.intrinsics.corner_model`).

Synthetic corners with known positions: two lines through ``c`` (straight, or bent by a curvature
``k`` px^-1 as a lens bends them over a window), rendered 8 x 8 supersampled, blurred, with 2 grey
levels of noise, rounded to uint8; fixed seeds.
"""

import numpy as np
import pytest

from lenticalib.calib.intrinsics.corner_model import fit_corner

SIZE = 61
WIN = 14


def _corner(c, a1, a2, bend, rng, blur=1.2, noise=2.0, ss=8, light=(0.0, 0.0)):
    """uint8 ``(SIZE, SIZE)``: dark and light quadrants between lines at angles a1, a2 through c,
    lit by ``1 + light . (p - centre)`` (uneven light, per px)."""
    import cv2

    u = (np.arange(SIZE * ss) + 0.5) / ss - 0.5
    xx, yy = np.meshgrid(u, u)
    dx, dy = xx - c[0], yy - c[1]
    sides = []
    for a in (a1, a2):
        along = np.cos(a) * dx + np.sin(a) * dy
        sides.append(np.sign(np.cos(a) * dy - np.sin(a) * dx + bend * along * along))
    img = (sides[0] * sides[1]).reshape(SIZE, ss, SIZE, ss).mean(axis=(1, 3))
    yy, xx = np.mgrid[0:SIZE, 0:SIZE] - SIZE // 2
    lit = 1.0 + light[0] * xx + light[1] * yy
    img = 255 * lit * (0.5 + 0.35 * cv2.GaussianBlur(img, (0, 0), blur)) + rng.normal(0, noise, (SIZE, SIZE))
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def _errors(bend, seed, n=30, light=(0.0, 0.0)):
    """Errors (px) of the curved fit, the straight fit and cv2.cornerSubPix: dict of (n, 2)."""
    import cv2

    rng = np.random.default_rng(seed)
    out = {"curved": [], "straight": [], "subpix": []}
    for _ in range(n):
        c = np.array([30.0, 30.0]) + rng.uniform(-0.5, 0.5, 2)
        a1 = rng.uniform(0, np.pi / 2)
        a2 = a1 + np.pi / 2 + rng.uniform(-0.4, 0.4)  # a tilted board's lines are not square
        img = _corner(c, a1, a2, bend, rng, light=light)
        start = np.round(c) + rng.uniform(-0.3, 0.3, 2)
        along, down = 40 * np.array([np.cos(a1), np.sin(a1)]), 40 * np.array([np.cos(a2), np.sin(a2)])
        for name, curved in (("curved", True), ("straight", False)):
            found = fit_corner(img, start, along, down, WIN, curved=curved)
            out[name].append(found - c if found is not None else [np.nan, np.nan])
        sp = cv2.cornerSubPix(img, start.reshape(1, 1, 2).astype(np.float32), (WIN, WIN), (-1, -1),
                              (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-5))
        out["subpix"].append(sp.reshape(2) - c)
    return {k: np.array(v, dtype=np.float64) for k, v in out.items()}


def _rms(e):
    return float(np.sqrt(np.mean(e * e)))


def test_straight_corners_are_located_without_bias_and_with_less_noise_than_cornersubpix():
    e = _errors(0.0, seed=7)
    assert np.isfinite(e["curved"]).all() and np.isfinite(e["straight"]).all()
    for name in ("curved", "straight"):
        assert np.all(np.abs(e[name].mean(axis=0)) < 0.004), name
    assert _rms(e["straight"]) < 0.008
    assert _rms(e["curved"]) < 0.011
    # every pixel of the window counts, not the gradients on the edges alone
    assert _rms(e["curved"]) < 0.75 * _rms(e["subpix"])


@pytest.mark.parametrize("bend", [0.001, 0.002])
def test_bent_lines_do_not_pull_the_curved_fit(bend):
    """A bend of 0.001-0.002 px^-1 moves the lines 0.2-0.4 px at the window's edge; it pulls
    cornerSubPix and the straight fit by a tenth of a pixel and more, the curved fit by the blur's
    own shift of a curved edge (about bend x blur^2)."""
    e = _errors(bend, seed=8)
    assert np.isfinite(e["curved"]).all()
    pull = np.linalg.norm(e["curved"].mean(axis=0))
    assert pull < 0.012
    assert _rms(e["curved"]) < 0.015
    assert np.linalg.norm(e["subpix"].mean(axis=0)) > 5 * pull


def test_uneven_light_across_the_window_does_not_pull_the_corner():
    """Light falling off by 0.5 % per px (vignetting, a lamp to one side): the dark and the light
    squares on one side of the corner are brighter than their opposites, which pulls a fit that
    assumes even light toward them (measured on the simulator's wide-angle set: 0.33 px at the
    image corner with the model's light held even, 0.02 px with it fitted)."""
    e = _errors(0.0, seed=9, light=(0.005, -0.003))
    for name in ("curved", "straight"):
        assert np.isfinite(e[name]).all(), name
        assert np.linalg.norm(e[name].mean(axis=0)) < 0.004, name
        assert _rms(e[name]) < 0.012, name


def test_a_window_without_a_corner_is_not_fitted():
    rng = np.random.default_rng(3)
    flat = np.clip(np.round(128 + rng.normal(0, 2.0, (SIZE, SIZE))), 0, 255).astype(np.uint8)
    assert fit_corner(flat, np.array([30.0, 30.0]), np.array([40.0, 0.0]), np.array([0.0, 40.0]), WIN) is None
    edge = np.zeros((SIZE, SIZE), np.uint8)
    edge[:, 30:] = 200  # one straight edge: no corner on it
    found = fit_corner(edge, np.array([30.0, 30.0]), np.array([40.0, 0.0]), np.array([0.0, 40.0]), WIN)
    assert found is None


def test_a_window_leaving_the_image_is_refused():
    rng = np.random.default_rng(4)
    img = _corner(np.array([30.2, 29.7]), 0.3, 1.9, 0.0, rng)
    assert fit_corner(img, np.array([5.0, 30.0]), np.array([40.0, 0.0]), np.array([0.0, 40.0]), WIN) is None
