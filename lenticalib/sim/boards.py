"""Photographing calibration chessboards with a known camera: the ground truth of ``lenticalib camera``.

Two kinds of board (:mod:`lenticalib.calib.intrinsics.board`):

print   a flat printed board at a chosen pose in front of the camera.  Every sensor pixel
        integrates ``n x n`` stratified rays (:attr:`.camera.Camera.subsamples`); each ray is cast
        exactly (the camera's undistortion on a grid every ``GRID_STEP`` pixels, bilinear in
        between, as the panel renderer does) onto the board plane; the board's ink edges are soft
        (a linear ramp ``EDGE_SOFTNESS`` squares wide), the light falls off slightly across the
        board; then the camera's photometric chain :func:`.render.develop` and JPEG.
panel   the board raster shown on the virtual panel and photographed through its lens sheet by
        the panel renderer (:func:`.render.photograph_jpeg`), the camera moved around the panel.

Frames and units.  Camera frame: OpenCV's (x right, y down, z forward), mm.  Board frame: origin
at inner corner (0, 0), x along a row of corners, y down a column, z into the board, mm.  A
board pose is ``R_cam_board`` (3 x 3) and ``t_cam_board`` (3,) mm: ``p_cam = R p_board + t``.
For the panel kind the board lies in the panel's pixel plane (world z = +g, :mod:`.optics`): the
lens sheet shows every pixel-plane point along the straight line from the camera through it
(across the lenses sampled at the lens centres), so what the camera sees is exactly a rigid board
in the pixel plane; its poses are recorded in that frame, the camera standing ``D + g`` from it.

Poses (:func:`board_poses`): a fixed seed spreads the boards over the image -- anchored in turn
at the four image corners, the four edges and the centre -- tilted by ``tilt`` degrees about a
random axis and rolled, at a distance that makes them ``fill`` of the image width, each checked to
lie wholly inside the frame with a margin.  mrcal needs exactly this: tilted views and corners
observed near the image corners.  With ``cut`` a share of the boards instead reaches out of the
frame at an image corner or edge, as a user filling the image corners photographs them.
Lens kinds (:data:`LENSES`): everyday lenses, mild and strong barrel distortion, a wide angle.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit, prange

from ..core.errors import InputError
from .camera import Camera

GRID_STEP = 4  # pixels between exactly undistorted grid points (as in .render)
EDGE_SOFTNESS = 0.02  # half-width of the ink edge ramp, in squares
PAPER_BORDER = 0.6  # white paper around the outer squares, in squares
REFLECTANCE = {"black": 0.05, "white": 0.85, "background": 0.22}


@dataclasses.dataclass(frozen=True)
class BoardPose:
    """Pose of the board in the camera frame: ``p_cam = rotation @ p_board + translation`` (mm)."""

    rotation: np.ndarray  # R_cam_board, (3, 3)
    translation: np.ndarray  # t_cam_board, (3,), mm

    def rt(self) -> np.ndarray:
        """mrcal's ``rt_cam_board``: (6,) = Rodrigues vector (rad), translation (mm)."""
        import cv2

        r, _ = cv2.Rodrigues(np.asarray(self.rotation, np.float64))
        return np.concatenate([r.ravel(), np.asarray(self.translation, np.float64)])

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """Board-frame points ``(..., 3)`` mm -> camera frame ``(..., 3)`` mm."""
        return np.asarray(points, np.float64) @ self.rotation.T + self.translation


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


def _front_rotation(direction: np.ndarray) -> np.ndarray:
    """R_cam_board of a board facing the camera square-on along ``direction`` (its z axis), x as
    close to the camera's x as possible."""
    z = direction / np.linalg.norm(direction)
    x = np.array([1.0, 0.0, 0.0]) - z * z[0]
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    import cv2

    r, _ = cv2.Rodrigues(np.asarray(axis, np.float64) * angle)
    return r


def board_outline(board) -> np.ndarray:
    """Board-frame points (n, 3) mm around the squares, half a square outside: the area that must be
    in the photo for the detector (the squares and a quiet zone)."""
    s = board.square_mm
    x0, y0, x1, y1 = -1.5 * s, -1.5 * s, (board.cols + 0.5) * s, (board.rows + 0.5) * s
    t = np.linspace(0.0, 1.0, 9)
    xs, ys = x0 + (x1 - x0) * t, y0 + (y1 - y0) * t
    edges = [np.stack([xs, np.full_like(t, y0)], 1), np.stack([xs, np.full_like(t, y1)], 1),
             np.stack([np.full_like(t, x0), ys], 1), np.stack([np.full_like(t, x1), ys], 1)]
    pts = np.concatenate(edges)
    return np.concatenate([pts, np.zeros((len(pts), 1))], 1)


def project_camera(camera: Camera, points_cam: np.ndarray) -> np.ndarray:
    """Camera-frame points ``(n, 3)`` mm -> pixel coordinates ``(n, 2)`` with the camera's intrinsics."""
    import cv2

    pts = np.ascontiguousarray(np.asarray(points_cam, np.float64).reshape(-1, 3))
    out, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), camera.camera_matrix, camera.dist_coeffs)
    return out.reshape(-1, 2)


def board_poses(camera: Camera, board, count: int, seed: int, *, tilt: tuple[float, float] = (15.0, 40.0),
                fill: tuple[float, float] = (0.3, 0.55), roll: float = 20.0, margin: float = 0.02,
                cut: float = 0.0) -> list[BoardPose]:
    """``count`` board poses spread over the image of ``camera``, fully determined by ``seed``.

    ARGUMENTS
    camera    the camera's intrinsics (its own pose is ignored: poses are in the camera frame)
    board     a :class:`~lenticalib.calib.intrinsics.board.Board`
    tilt      (min, max) angle in degrees between the board normal and the line of sight
    fill      (min, max) share of the image width the squares span
    roll      bound of the board's rotation about its normal, degrees (keep < 90: see .corners)
    margin    share of the image width kept free at every edge
    cut       share of the poses (rounded) whose board reaches out of the frame at its anchor's
              edges: 15-35 % of its span along each of those edges lies outside, as a user
              filling the image corners produces (drawn from a separate stream: the other poses
              are those of ``cut=0``)

    RETURNED VALUE
    list of :class:`BoardPose`; anchors cycle through the four image corners, the four edges
    and the centre (shuffled per cycle).
    """
    if not 0.0 <= cut <= 1.0:
        raise InputError(f"cut share {cut} is out of range", source="cut", hint="use 0..1")
    cut_rng = np.random.default_rng([int(seed), 0xC07])
    n_cut = int(round(cut * count))
    cut_at = set(cut_rng.permutation(count)[:n_cut].tolist())
    rng = np.random.default_rng([int(seed), 0x9053])
    w, h = camera.width, camera.height
    bw, bh = board.size_mm
    centre = np.array([(board.cols - 1) * board.square_mm / 2, (board.rows - 1) * board.square_mm / 2, 0.0])
    outline = board_outline(board)
    anchors = [(ax, ay) for ax in (-1, 1) for ay in (-1, 1)] + [(0, -1), (0, 1), (-1, 0), (1, 0), (0, 0)]
    order: list[tuple[int, int]] = []
    while len(order) < count:
        order += [anchors[i] for i in rng.permutation(len(anchors))]
    poses = []
    for k, (ax, ay) in enumerate(order[:count]):
        f = rng.uniform(*fill)
        theta = math.radians(rng.uniform(*tilt))
        alpha = rng.uniform(0.0, 2.0 * math.pi)
        psi = math.radians(rng.uniform(-roll, roll))
        edge = margin * w * (1.0 + rng.uniform(0.0, 1.5))  # free pixels kept at the image edge
        lo_ok, hi_ok = np.array([edge, edge]), np.array([w - 1 - edge, h - 1 - edge])
        half = 0.5 * f * np.array([1.0, (bh / bw) * (w / h)])
        target = (0.5 + np.array([ax, ay]) * np.maximum(0.5 - half, 0.0)) * (w, h) - 0.5  # moved inside below
        for _ in range(100):
            xn, yn = camera.normalized(target[:1], target[1:])
            ray = np.array([xn[0], yn[0], 1.0])
            distance = camera.fx * bw / (f * w)
            rot = (_front_rotation(ray) @ _axis_rotation([0, 0, 1], psi)
                   @ _axis_rotation([math.cos(alpha), math.sin(alpha), 0.0], theta))
            pose = BoardPose(rot, distance * ray / np.linalg.norm(ray) - rot @ centre)
            q = project_camera(camera, pose.to_camera(outline))
            span, room = q.max(0) - q.min(0), hi_ok - lo_ok
            if np.any(pose.to_camera(outline)[:, 2] <= 0) or np.any(span > room):
                f *= 0.97 * min(1.0, float(np.min(room / np.maximum(span, 1e-9))))
                target = 0.9 * target + 0.1 * (np.array([w, h]) / 2 - 0.5)
                continue
            shift = np.maximum(lo_ok - q.min(0), 0.0) - np.maximum(q.max(0) - hi_ok, 0.0)
            if not np.any(shift):
                break
            target = target + 0.7 * shift + np.sign(shift)
        else:
            raise InputError("cannot place the board inside the camera frame", source="board_poses",
                             hint="use a smaller board or a wider lens")
        poses.append(_cut_pose(camera, board, cut_rng, tilt, fill, roll, centre, outline) if k in cut_at else pose)
    return poses


def _cut_pose(camera: Camera, board, rng, tilt, fill, roll, centre, outline) -> BoardPose:
    """A pose whose board reaches out of the frame at an image corner or edge (see :func:`board_poses`)."""
    w, h = camera.width, camera.height
    bw = board.size_mm[0]
    anchors = [(ax, ay) for ax in (-1, 1) for ay in (-1, 1)] + [(0, -1), (0, 1), (-1, 0), (1, 0)]
    ax, ay = anchors[int(rng.integers(len(anchors)))]
    f = rng.uniform(*fill)
    theta = math.radians(rng.uniform(*tilt))
    alpha = rng.uniform(0.0, 2.0 * math.pi)
    psi = math.radians(rng.uniform(-roll, roll))
    out = rng.uniform(0.15, 0.35, size=2)  # share of the board's image span beyond the edge
    target = np.array([w, h]) / 2 - 0.5
    pose = None
    for _ in range(60):
        xn, yn = camera.normalized(target[:1], target[1:])
        ray = np.array([xn[0], yn[0], 1.0])
        rot = (_front_rotation(ray) @ _axis_rotation([0, 0, 1], psi)
               @ _axis_rotation([math.cos(alpha), math.sin(alpha), 0.0], theta))
        pose = BoardPose(rot, camera.fx * bw / (f * w) * ray / np.linalg.norm(ray) - rot @ centre)
        q = project_camera(camera, pose.to_camera(outline))
        lo, hi = q.min(0), q.max(0)
        span = hi - lo
        # wanted: lo = -out * span at a -1 anchor, hi = size - 1 + out * span at a +1 anchor, centred at 0
        want = np.array([w - 1.0, h - 1.0]) / 2 - (lo + hi) / 2
        for axis, a in enumerate((ax, ay)):
            size = (w, h)[axis] - 1.0
            if a < 0:
                want[axis] = -out[axis] * span[axis] - lo[axis]
            elif a > 0:
                want[axis] = size + out[axis] * span[axis] - hi[axis]
        if np.all(np.abs(want) < 1.0):
            break
        target = np.clip(target + 0.8 * want, [0.0, 0.0], [w - 1.0, h - 1.0])
    return pose


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


@njit(parallel=True, cache=True, error_model="numpy")
def _print_kernel(gx, gy, step, n, rot, t, square, cols, rows, border, soft, refl, grad, out):
    """Reflectance seen by every sensor pixel (mean of n x n rays) into ``out`` (h, w) float32.

    ``refl`` = (black, white, background); ``grad`` = (gx, gy) relative light change per mm along
    the board's x and y about its centre.
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
                    acc += (refl[1] - (refl[1] - refl[0]) * _blackness(bx / square + 1.0, by / square + 1.0,
                                                                      cols, rows, soft)) * light
            out[i, j] = acc / (n * n)


def print_board_radiance(camera: Camera, board, pose: BoardPose, rng: np.random.Generator) -> np.ndarray:
    """Light reaching each sensor pixel from a printed board at ``pose``: float32 ``(h, w, 3)``, the
    three channels equal (grey paper and ink), in the units :func:`.render.develop` takes.

    The light falls off across the board by up to +-8 % in a random direction drawn from ``rng``.
    """
    from .render import _undistortion_grid

    gx, gy = _undistortion_grid(camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy,
                                tuple(float(v) for v in camera.distortion), GRID_STEP)
    angle = rng.uniform(0.0, 2.0 * math.pi)
    slope = rng.uniform(0.0, 0.16) / max(board.size_mm)
    out = np.empty((camera.height, camera.width), np.float32)
    # the grid holds pixel coordinates (J step - 0.5, I step - 0.5): index = (pixel + 0.5) / step
    _print_kernel(gx, gy, float(GRID_STEP), int(camera.subsamples), np.ascontiguousarray(pose.rotation, np.float64),
                  np.ascontiguousarray(pose.translation, np.float64), float(board.square_mm), int(board.cols),
                  int(board.rows), PAPER_BORDER, EDGE_SOFTNESS,
                  np.array([REFLECTANCE["black"], REFLECTANCE["white"], REFLECTANCE["background"]]),
                  np.array([slope * math.cos(angle), slope * math.sin(angle)]), out)
    return np.repeat(out[:, :, None], 3, axis=2)


def photograph_print_board(camera: Camera, board, pose: BoardPose, rng: np.random.Generator) -> bytes:
    """The camera's JPEG of a printed ``board`` at ``pose`` (noise, exposure drift from ``rng``)."""
    from .render import develop, encode_jpeg

    shot, _ = camera.for_photo(rng)
    shot = shot.replace(exposure=shot.exposure * 0.8 / REFLECTANCE["white"])
    photo = develop(print_board_radiance(camera, board, pose, rng), shot, rng)
    return encode_jpeg(photo, camera.jpeg_quality or 95)


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
