"""Photographing calibration chessboards with a known camera: the ground truth of ``lenticalib camera``.

Two kinds of board (:mod:`lenticalib.calib.intrinsics.board`):

print   a flat printed board at a chosen pose in front of the camera.  Every sensor pixel
        integrates ``n x n`` stratified rays (:attr:`.camera.Camera.subsamples`); each ray is cast
        exactly (the camera's undistortion on a grid every ``GRID_STEP`` pixels, bilinear in
        between, as the panel renderer does) onto the board plane; the board's ink edges are soft
        (a linear ramp ``EDGE_SOFTNESS`` squares wide), the light falls off slightly across the
        board; then the camera's photometric chain :func:`.photo.develop` and JPEG.
panel   the board raster shown on the virtual panel and photographed through its lens sheet by
        the panel renderer (:func:`.photo.photograph_jpeg`), the camera moved around the panel.

Frames and units.  Camera frame: OpenCV's (x right, y down, z forward), mm.  Board frame: origin
at inner corner (0, 0), x along a row of corners, y down a column, z into the board, mm.  A
board pose is ``R_cam_board`` (3 x 3) and ``t_cam_board`` (3,) mm: ``p_cam = R p_board + t``.
For the panel kind the board lies in the panel's pixel plane (world z = +g, :mod:`.optics`): the
lens sheet shows every pixel-plane point along the straight line from the camera through it
(across the lenses sampled at the lens centres), so what the camera sees is exactly a rigid board
in the pixel plane; its poses are recorded in that frame, the camera standing ``D + g`` from it.

Poses: :mod:`.board_poses`.

ChArUco boards (printed): the ArUco markers of :meth:`~lenticalib.calib.intrinsics.board.Board.marker_bits`
are drawn in the white squares with the same soft ink edges.
Lens kinds (:data:`LENSES`): everyday lenses, mild and strong barrel distortion, a wide angle.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..core.errors import InputError
from .board_poses import BoardPose
from .camera import Camera

GRID_STEP = 4  # pixels between exactly undistorted grid points (as in .render)
EDGE_SOFTNESS = 0.02  # half-width of the ink edge ramp, in squares
PAPER_BORDER = 0.6  # white paper around the outer squares, in squares
REFLECTANCE = {"black": 0.05, "white": 0.85, "background": 0.22}


LENSES = {
    # name: (horizontal field of view, degrees), k1, k2, k3 ranges drawn uniformly
    "standard": ((50.0, 70.0), (-0.25, 0.05), (-0.02, 0.08), (-0.01, 0.01)),
    "mild": ((45.0, 60.0), (-0.08, -0.02), (0.0, 0.03), (0.0, 0.0)),
    "strong": ((60.0, 70.0), (-0.34, -0.28), (0.08, 0.12), (0.0, 0.005)),
    "wide": ((85.0, 95.0), (-0.30, -0.24), (0.06, 0.09), (0.0, 0.004)),
}
"""Lens kinds of :func:`calibration_camera`: "standard" spans everyday lenses; "mild" and
"strong" barrel distortion at a normal field of view, "wide" a wide-angle lens."""


def calibration_camera(seed: int, resolution: tuple[int, int] = (1600, 1200), conditions: str = "standard",
                       subsamples: int = 2, lens: str = "standard") -> Camera:
    """A plausible camera to calibrate, fully determined by ``seed``: a lens of kind ``lens``
    (:data:`LENSES`; "standard": 50-70 degrees) with real radial and tangential distortion, sensor
    noise, defocus, sharpening and JPEG.

    ``conditions``: "standard", or "hard" (a phone: S-shaped tone curve, +-4 % exposure drift
    between photos, high-ISO noise).  No lateral chromatic aberration (it would make the grey
    image's focal length differ from the green one's) and no per-photo shake (a moved camera is
    just another pose).  Pose: at the world origin looking along +z (world = camera frame).
    """
    if conditions not in ("standard", "hard"):
        raise InputError(f"unknown conditions {conditions!r}", source="conditions", hint="use standard or hard")
    if lens not in LENSES:
        raise InputError(f"unknown lens {lens!r}", source="lens", hint="use " + ", ".join(LENSES))
    rng = np.random.default_rng([int(seed), 0xB0A2D])
    w, h = resolution
    fov, k1r, k2r, k3r = LENSES[lens]
    hfov = math.radians(rng.uniform(*fov))
    fx = 0.5 * w / math.tan(0.5 * hfov)
    k1, k2, k3 = rng.uniform(*k1r), rng.uniform(*k2r), rng.uniform(*k3r)
    p1, p2 = rng.uniform(-0.002, 0.002, size=2)
    hard = conditions == "hard"
    return Camera(width=int(w), height=int(h), fx=fx, fy=fx * rng.uniform(0.998, 1.002),
                  cx=(w - 1) / 2 + rng.uniform(-0.02, 0.02) * w, cy=(h - 1) / 2 + rng.uniform(-0.02, 0.02) * h,
                  distortion=(float(k1), float(k2), float(p1), float(p2), float(k3)), position=(0.0, 0.0, -1.0),
                  subsamples=int(subsamples), exposure=1.0, vignetting=(0.15, 0.05),
                  defocus_sigma=float(rng.uniform(0.4, 0.9)),
                  full_well=float(rng.uniform(800, 2500) if hard else rng.uniform(4000, 12000)),
                  read_noise=float(rng.uniform(3, 10) if hard else rng.uniform(1.5, 4)),
                  tone_gamma=float(rng.uniform(0.95, 1.05)), sharpen=float(rng.uniform(0.0, 0.4)),
                  jpeg_quality=int(rng.integers(85, 96)), tone_contrast=float(rng.uniform(0.1, 0.8) if hard else 0.0),
                  exposure_jitter=0.04 if hard else 0.0)


@njit(cache=True, inline="always")
def _ramp(x, soft):
    """Soft step: 0 below -soft, 1 above +soft, linear between (r(x) + r(-x) = 1)."""
    return min(max(0.5 + 0.5 * x / soft, 0.0), 1.0)


@njit(cache=True, inline="always")
def _blackness(u, v, cols, rows, soft):
    """Share of black ink at square coordinates (u, v) (square (ku, kv) covers [ku, ku+1) x [kv, kv+1),
    black when (ku + kv) is even and it is one of the (cols + 1) x (rows + 1) squares)."""
    ku0 = math.floor(u + 0.5) - 1
    kv0 = math.floor(v + 0.5) - 1
    total = 0.0
    for ku in range(ku0, ku0 + 2):
        if ku < 0 or ku > cols:
            continue
        bu = _ramp(u - ku, soft) * _ramp(ku + 1 - u, soft)
        for kv in range(kv0, kv0 + 2):
            if kv < 0 or kv > rows or (ku + kv) % 2 != 0:
                continue
            total += bu * _ramp(v - kv, soft) * _ramp(kv + 1 - v, soft)
    return total


@njit(cache=True, inline="always")
def _marker_blackness(u, v, ids, bits, share, soft):
    """Share of black ink of the ArUco markers at square coordinates (u, v): the marker of the white
    square holding the point (``ids`` (rows + 1, cols + 1), -1 for none), ``share`` of a square wide
    and centred, its cells ``bits`` (markers, n, n) with edges ramped over ``soft`` squares."""
    ku = math.floor(u)
    kv = math.floor(v)
    if ku < 0 or kv < 0 or kv >= ids.shape[0] or ku >= ids.shape[1]:
        return 0.0
    k = ids[kv, ku]
    if k < 0:
        return 0.0
    n = bits.shape[1]
    cell = share / n
    x = (u - ku - 0.5 * (1.0 - share)) / cell  # in cells from the marker's top-left corner
    y = (v - kv - 0.5 * (1.0 - share)) / cell
    c0 = math.floor(x + 0.5) - 1
    r0 = math.floor(y + 0.5) - 1
    total = 0.0
    for c in range(c0, c0 + 2):
        if c < 0 or c >= n:
            continue
        bu = _ramp((x - c) * cell, soft) * _ramp((c + 1 - x) * cell, soft)
        for r in range(r0, r0 + 2):
            if r < 0 or r >= n or bits[k, r, c] == 0:
                continue
            total += bu * _ramp((y - r) * cell, soft) * _ramp((r + 1 - y) * cell, soft)
    return total


@njit(parallel=True, cache=True, error_model="numpy")
def _print_kernel(gx, gy, step, n, rot, t, square, cols, rows, border, soft, refl, grad, ids, bits, share, out):
    """Reflectance seen by every sensor pixel (mean of n x n rays) into ``out`` (h, w) float32.

    ``refl`` = (black, white, background); ``grad`` = (gx, gy) relative light change per mm along
    the board's x and y about its centre; ``ids``, ``bits``, ``share``: the ChArUco markers
    (:func:`_marker_blackness`; ids all -1 for a chessboard).
    """
    h, w = out.shape
    nx, ny, nz = rot[0, 2], rot[1, 2], rot[2, 2]
    d0 = nx * t[0] + ny * t[1] + nz * t[2]
    x_lo, y_lo = -(1.0 + border) * square, -(1.0 + border) * square
    x_hi, y_hi = (cols + border) * square, (rows + border) * square
    cxb, cyb = 0.5 * (cols - 1) * square, 0.5 * (rows - 1) * square
    for i in prange(h):
        for j in range(w):
            acc = 0.0
            for b in range(n):
                fy = (i + (b + 0.5) / n) / step
                i0 = min(int(fy), gx.shape[0] - 2)
                ay = fy - i0
                for a in range(n):
                    fx = (j + (a + 0.5) / n) / step
                    j0 = min(int(fx), gx.shape[1] - 2)
                    ax = fx - j0
                    xn = ((1 - ay) * ((1 - ax) * gx[i0, j0] + ax * gx[i0, j0 + 1])
                          + ay * ((1 - ax) * gx[i0 + 1, j0] + ax * gx[i0 + 1, j0 + 1]))
                    yn = ((1 - ay) * ((1 - ax) * gy[i0, j0] + ax * gy[i0, j0 + 1])
                          + ay * ((1 - ax) * gy[i0 + 1, j0] + ax * gy[i0 + 1, j0 + 1]))
                    den = nx * xn + ny * yn + nz
                    lam = d0 / den if den > 1e-12 else -1.0
                    if lam <= 0.0:
                        acc += refl[2]
                        continue
                    px, py, pz = lam * xn - t[0], lam * yn - t[1], lam - t[2]
                    bx = rot[0, 0] * px + rot[1, 0] * py + rot[2, 0] * pz
                    by = rot[0, 1] * px + rot[1, 1] * py + rot[2, 1] * pz
                    if bx < x_lo or bx > x_hi or by < y_lo or by > y_hi:
                        acc += refl[2]
                        continue
                    light = 1.0 + grad[0] * (bx - cxb) + grad[1] * (by - cyb)
                    u, v = bx / square + 1.0, by / square + 1.0
                    black = _blackness(u, v, cols, rows, soft) + _marker_blackness(u, v, ids, bits, share, soft)
                    acc += (refl[1] - (refl[1] - refl[0]) * min(black, 1.0)) * light
            out[i, j] = acc / (n * n)


def _markers(board) -> tuple[np.ndarray, np.ndarray, float]:
    """(ids int64 (rows + 1, cols + 1), bits uint8 (markers, n, n), marker share of a square) for the
    print kernel: a ChArUco board's markers, or none (ids -1) for a chessboard."""
    if getattr(board, "charuco", False):
        return (np.ascontiguousarray(board.marker_ids()), np.ascontiguousarray(board.marker_bits().astype(np.uint8)),
                float(board.marker_mm) / float(board.square_mm))
    return np.full((board.rows + 1, board.cols + 1), -1, np.int64), np.zeros((1, 1, 1), np.uint8), 0.5


def print_board_radiance(camera: Camera, board, pose: BoardPose, rng: np.random.Generator) -> np.ndarray:
    """Light reaching each sensor pixel from a printed board at ``pose``: float32 ``(h, w, 3)``, the
    three channels equal (grey paper and ink), in the units :func:`.photo.develop` takes.

    The light falls off across the board by up to +-8 % in a random direction drawn from ``rng``.
    """
    from .panel_light import undistortion_grid

    gx, gy = undistortion_grid(camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy,
                                tuple(float(v) for v in camera.distortion), GRID_STEP)
    angle = rng.uniform(0.0, 2.0 * math.pi)
    slope = rng.uniform(0.0, 0.16) / max(board.size_mm)
    out = np.empty((camera.height, camera.width), np.float32)
    # the grid holds pixel coordinates (J step - 0.5, I step - 0.5): index = (pixel + 0.5) / step
    _print_kernel(gx, gy, float(GRID_STEP), int(camera.subsamples), np.ascontiguousarray(pose.rotation, np.float64),
                  np.ascontiguousarray(pose.translation, np.float64), float(board.square_mm), int(board.cols),
                  int(board.rows), PAPER_BORDER, EDGE_SOFTNESS,
                  np.array([REFLECTANCE["black"], REFLECTANCE["white"], REFLECTANCE["background"]]),
                  np.array([slope * math.cos(angle), slope * math.sin(angle)]), *_markers(board), out)
    return np.repeat(out[:, :, None], 3, axis=2)


def photograph_print_board(camera: Camera, board, pose: BoardPose, rng: np.random.Generator) -> bytes:
    """The camera's JPEG of a printed ``board`` at ``pose`` (noise, exposure drift from ``rng``)."""
    from .photo import develop, encode_jpeg

    shot, _ = camera.for_photo(rng)
    shot = shot.replace(exposure=shot.exposure * 0.8 / REFLECTANCE["white"])
    photo = develop(print_board_radiance(camera, board, pose, rng), shot, rng)
    return encode_jpeg(photo, camera.jpeg_quality or 95, camera.jpeg_chroma)


def panel_board_origin(optics, board) -> np.ndarray:
    """World position (mm) of inner corner (0, 0) of a panel board: in the pixel plane, z = +g."""
    p = optics.pixel_pitch
    return np.array([board.origin_px[0] * p - optics.width * p / 2, board.origin_px[1] * p - optics.height * p / 2,
                     optics.gap])


def camera_for_pose(camera: Camera, optics, board, pose: BoardPose) -> Camera:
    """``camera`` moved (position, aim, roll) so that the panel board is at ``pose`` in its frame.

    The board frame is the world frame shifted to :func:`panel_board_origin`, so
    ``R_world_cam = R_cam_board^T`` and the camera centre is ``origin - R_cam_board^T t``.
    """
    r_wc = np.asarray(pose.rotation).T
    centre = panel_board_origin(optics, board) - r_wc @ pose.translation
    z_c = r_wc[:, 2]
    if not (centre[2] < 0 and z_c[2] > 1e-6):
        raise InputError("the pose puts the camera behind the panel", source="camera_for_pose")
    aim = centre - z_c * centre[2] / z_c[2]
    base = camera.replace(position=tuple(float(c) for c in centre), aim=(float(aim[0]), float(aim[1])), roll=0.0)
    rb = base.rotation
    roll = math.degrees(math.atan2(float(r_wc[:, 0] @ rb[:, 1]), float(r_wc[:, 0] @ rb[:, 0])))
    moved = base.replace(roll=roll)
    if not np.allclose(moved.rotation, r_wc, atol=1e-9):
        raise AssertionError("camera pose conversion failed")  # a bug, not a user error
    return moved
