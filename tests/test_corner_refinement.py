"""Corners refined where the board's lines are straight (:mod:`lenticalib.calib.intrinsics.straightened`).

A noiseless chessboard through a strongly distorting lens, rendered exactly (each pixel's ray
through the lens onto the board), so any error left is the locator's own.
"""

import numpy as np
import pytest

from lenticalib.calib.intrinsics import corners as corner_module

SIZE = (1200, 800)
K = np.array([[700.0, 0.0, 599.5], [0.0, 700.0, 399.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.32, 0.11, 0.0, 0.0, -0.015])  # OpenCV k1 k2 p1 p2 k3: strong barrel
COLS, ROWS, SQUARE = 11, 6, 0.16  # inner corners; square side in normalised (z = 1) units


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
    centre = K[:2, 2]
    d = truth - centre
    r = np.linalg.norm(d, axis=-1)
    far = np.isfinite(found[..., 0]) & (r > 0.35 * np.hypot(*SIZE) / 2)
    e = found - truth
    return float(np.mean(np.sum(e[far] * d[far], -1) / r[far])), float(np.sqrt(np.mean(e[far] ** 2)))


@pytest.fixture(scope="module")
def rendered():
    return _render()


def test_corners_on_bent_lines_are_located_without_the_bend_pulling_them(rendered, monkeypatch):
    grey, truth = rendered
    monkeypatch.setattr(corner_module, "RECTIFY", False)
    plain = corner_module.find_corners(grey, COLS, ROWS)
    monkeypatch.setattr(corner_module, "RECTIFY", True)
    rectified = corner_module.find_corners(grey, COLS, ROWS)
    assert plain is not None and rectified is not None
    bias_plain, rms_plain = _radial_bias(plain, truth)
    bias, rms = _radial_bias(rectified, truth)
    assert abs(bias_plain) > 0.01  # the bend pulls plain cornerSubPix (what this guards against)
    print(f"radial bias {bias_plain:+.4f} -> {bias:+.4f} px, rms {rms_plain:.4f} -> {rms:.4f} px")
    assert abs(bias) < 0.25 * abs(bias_plain) and rms < 0.5 * rms_plain, (bias_plain, bias, rms_plain, rms)
