"""Poses of a calibration board in front of a known camera (the simulator's photo plan).

Frames and units.  Camera frame: OpenCV's (x right, y down, z forward), mm.  Board frame: origin
at inner corner (0, 0), x along a row of corners, y down a column, z into the board, mm.  A
board pose is ``R_cam_board`` (3 x 3) and ``t_cam_board`` (3,) mm: ``p_cam = R p_board + t``.

Poses (:func:`board_poses`): a fixed seed spreads the boards over the image -- anchored in turn
at the four image corners, the four edges and the centre -- tilted by ``tilt`` degrees about a
random axis and rolled, at a distance that makes them ``fill`` of the image width, each checked to
lie wholly inside the frame with a margin.  mrcal needs exactly this: tilted views and corners
observed near the image corners.  With ``cut`` > 0 (ChArUco boards) that share of the poses is
instead a closer board pushed past an image corner or edge, so that only part of its corners
(``CUT_INSIDE``) is in the photo: the extreme corners and edges of the image get observations, as
a user who follows "let the board reach every corner of the image" takes them.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..core.errors import InputError
from .camera import Camera

CUT_INSIDE = (0.3, 0.8)  # share of the corners of a cut board that lie inside the photo


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


def _place(camera: Camera, board, target: np.ndarray, f: float, theta: float, alpha: float, psi: float) -> BoardPose:
    """The board pose whose centre is seen at pixel ``target``, ``f`` of the image wide, tilted by
    ``theta`` about the in-board axis at angle ``alpha`` and rolled by ``psi`` (radians)."""
    bw = board.size_mm[0]
    centre = np.array([(board.cols - 1) * board.square_mm / 2, (board.rows - 1) * board.square_mm / 2, 0.0])
    xn, yn = camera.normalized(target[:1], target[1:])
    ray = np.array([xn[0], yn[0], 1.0])
    distance = camera.fx * bw / (f * camera.width)
    rot = (_front_rotation(ray) @ _axis_rotation([0, 0, 1], psi)
           @ _axis_rotation([math.cos(alpha), math.sin(alpha), 0.0], theta))
    return BoardPose(rot, distance * ray / np.linalg.norm(ray) - rot @ centre)


def inside_share(camera: Camera, board, pose: BoardPose, margin: float = 3.0) -> float:
    """Share of the board's inner corners that ``camera`` sees inside its frame (:func:`inside_mask`)."""
    return float(inside_mask(camera, board, pose, margin).mean())


def inside_mask(camera: Camera, board, pose: BoardPose, margin: float = 3.0) -> np.ndarray:
    """bool ``(rows * cols,)``: which of the board's inner corners ``camera`` sees inside its frame,
    ``margin`` pixels from the edges (in front of the camera, and within the field its pixels cover:
    the distortion polynomial folds back far outside the frame, so a projection alone is not enough)."""
    p = pose.to_camera(board.object_points().reshape(-1, 3))
    w, h = camera.width, camera.height
    cx, cy = camera.normalized(np.array([0.0, w - 1.0, 0.0, w - 1.0, 0.0, w - 1.0, (w - 1) / 2, (w - 1) / 2]),
                               np.array([0.0, 0.0, h - 1.0, h - 1.0, (h - 1) / 2, (h - 1) / 2, 0.0, h - 1.0]))
    front = p[:, 2] > 1e-6
    xn = np.where(front, p[:, 0] / np.where(front, p[:, 2], 1.0), np.inf)
    yn = np.where(front, p[:, 1] / np.where(front, p[:, 2], 1.0), np.inf)
    within = (xn >= cx.min()) & (xn <= cx.max()) & (yn >= cy.min()) & (yn <= cy.max())
    q = project_camera(camera, np.where(front[:, None], p, 1.0))
    return (within & (q[:, 0] >= margin) & (q[:, 1] >= margin) & (q[:, 0] <= w - 1 - margin)
            & (q[:, 1] <= h - 1 - margin))


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
    cut       share of the poses (0..1) that put the board partly outside the frame, past an image
              corner or edge (for ChArUco boards, whose partial views are usable), with
              ``CUT_INSIDE`` of its corners inside; 0 (default): every board wholly inside

    RETURNED VALUE
    list of :class:`BoardPose`; anchors cycle through the four image corners, the four edges
    and the centre (shuffled per cycle).  A cut pose is anchored at a corner or an edge.
    """
    rng = np.random.default_rng([int(seed), 0x9053])
    w, h = camera.width, camera.height
    bw, bh = board.size_mm
    outline = board_outline(board)
    anchors = [(ax, ay) for ax in (-1, 1) for ay in (-1, 1)] + [(0, -1), (0, 1), (-1, 0), (1, 0), (0, 0)]
    order: list[tuple[int, int]] = []
    while len(order) < count:
        order += [anchors[i] for i in rng.permutation(len(anchors))]
    cut_rng = np.random.default_rng([int(seed), 0xC07])
    poses = []
    for ax, ay in order[:count]:
        f = rng.uniform(*fill)
        theta = math.radians(rng.uniform(*tilt))
        alpha = rng.uniform(0.0, 2.0 * math.pi)
        psi = math.radians(rng.uniform(-roll, roll))
        edge = margin * w * (1.0 + rng.uniform(0.0, 1.5))  # free pixels kept at the image edge
        if cut > 0 and cut_rng.random() < cut:
            poses.append(_cut_pose(camera, board, (ax, ay), f, theta, alpha, psi, cut_rng))
            continue
        lo_ok, hi_ok = np.array([edge, edge]), np.array([w - 1 - edge, h - 1 - edge])
        half = 0.5 * f * np.array([1.0, (bh / bw) * (w / h)])
        target = (0.5 + np.array([ax, ay]) * np.maximum(0.5 - half, 0.0)) * (w, h) - 0.5  # moved inside below
        for _ in range(100):
            pose = _place(camera, board, target, f, theta, alpha, psi)
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
        poses.append(pose)
    return poses


def _cut_pose(camera: Camera, board, anchor, f, theta, alpha, psi, rng) -> BoardPose:
    """A board past the image corner or edge ``anchor`` (the centre anchor becomes a random corner),
    ``1.2-1.6 f`` of the image wide, with a share of its corners in :data:`CUT_INSIDE` inside."""
    w, h = camera.width, camera.height
    if anchor == (0, 0):
        anchor = (int(rng.choice([-1, 1])), int(rng.choice([-1, 1])))
    a = np.array(anchor, np.float64)
    f = f * rng.uniform(1.2, 1.6)
    centre_px = np.array([w, h]) / 2 - 0.5
    lo, hi = CUT_INSIDE
    want = rng.uniform(lo + 0.1, hi - 0.1)
    t_in, t_out = 0.0, 0.75  # fractions of the way from the image centre to the edge point, and beyond
    pose = None
    for _ in range(40):
        t = 0.5 * (t_in + t_out)
        target = centre_px + t * a * centre_px
        pose = _place(camera, board, target, f, theta, alpha, psi)
        share = inside_share(camera, board, pose)
        if lo <= share <= hi and abs(share - want) < 0.05:
            return pose
        if share > want:
            t_in = t  # push further out
            if t_out - t_in < 1e-3:
                t_out += 0.5
        else:
            t_out = t
    if pose is not None and lo <= inside_share(camera, board, pose) <= hi:
        return pose
    raise InputError("cannot place a board partly outside the camera frame", source="board_poses",
                     hint="use a smaller board or a wider lens")
