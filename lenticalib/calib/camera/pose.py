"""Where the calibration camera was, in millimetres, from the panel's own pixel grid.

The fit measures, for every camera pixel, the panel point it sees (raster coordinates from the
phase patterns).  Seen through the lens sheet, a pixel-plane point ``P`` shows at the lens-plane
point ``L = F + (P - F) / m``, ``m = 1 + g / D``, ``F`` the camera's foot point (docs/physical.md):
the rays from the camera to the points it sees are exactly the rays to a flat target lying in
the *pixel plane*, behind the lens surface by the gap ``g``.  So the camera pose comes from a
perspective-n-point solve against the pixel grid in that plane (``p`` mm per pixel), and the
camera's distance to the lens surface, which the routing formula needs, is the distance to the
pixel plane minus ``g``.  Without that subtraction every distance is ``g`` too far (the lens-sheet
magnification ``m`` read as distance); lateral positions need no correction (the magnification
is about the foot point).

Uncertainty, both ways honest: the spread of delete-one-block (4 x 4 panel blocks) jackknife
solves -- the correspondences are smoothed maps, so point-wise noise would understate it --
with a floor of 1e-4 of the distance (distance only) for the maps' own smooth distortion, plus
the spread over intrinsics drawn from the camera calibration's own covariance
(:meth:`.camera_file.CameraModel.intrinsics_draws`), which dominates the distance (a 0.1 %
focal length error is a 0.1 % distance error).

Frames and units: world mm, origin at the panel centre on the lens surface, x right, y down,
z into the screen; panel points are given in panel pixels relative to the panel centre
(``X / 3 - W / 2``, ``Y - H / 2`` for raster coordinates X in subpixels, Y in rows).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ...core.errors import CalibrationError
from .model_file import CameraModel

INTRINSICS_DRAWS = 40
JACKKNIFE_BLOCKS = 4  # per side
# A floor under the distance's jackknife, relative to the distance, for what no resampling of one
# set sees: the seen-point maps are smoothed and sampled once per lens, which leaves a smooth
# scale distortion of the measured grid (on the simulator, with an exactly known camera, errors up
# to 8e-5 of the distance; the lateral position shows no such floor beyond its jackknife).
SYSTEMATIC_FRACTION = 1e-4


@dataclasses.dataclass
class PanelPose:
    """The camera centre relative to the panel.

    eye_mm              (3,) [x, y, D]: lateral position (mm from the panel centre, x right,
                        y down) and distance D to the lens surface (mm); D is to the pixel plane
                        when ``gap_mm`` is None
    sigma_mm            (3,) their 1-sigma (jackknife and intrinsics, added in quadrature)
    pixel_plane_distance_mm   D + g, what the panel's pixel grid measures directly
    gap_mm              the gap subtracted (None: not known, not subtracted)
    rotation            (3, 3) world -> camera rotation
    rms_px              reprojection RMS of the correspondences, photo pixels
    points              correspondences used
    intrinsics_sigma    whether sigma_mm includes the camera's intrinsics uncertainty
    jackknife_sigma_mm  (3,) the jackknife's part of sigma_mm alone (no floor, no intrinsics)
    drawn_distances     (draws,) pixel-plane distances solved with each intrinsics draw (the same
                        draws for every set fitted with one camera model), or None
    """

    eye_mm: np.ndarray
    sigma_mm: np.ndarray
    pixel_plane_distance_mm: float
    gap_mm: float | None
    rotation: np.ndarray
    rms_px: float
    points: int
    intrinsics_sigma: bool
    jackknife_sigma_mm: np.ndarray
    drawn_distances: np.ndarray | None = None

    def with_gap(self, gap_mm: float) -> "PanelPose":
        """The same pose with the distance referred to the lens surface: D = (D + g) - g."""
        eye = self.eye_mm.copy()
        eye[2] = self.pixel_plane_distance_mm - gap_mm
        return dataclasses.replace(self, eye_mm=eye, gap_mm=float(gap_mm))

    def to_dict(self) -> dict[str, Any]:
        rot = self.rotation
        axis = rot.T @ np.array([0.0, 0.0, 1.0])  # optical axis in the world frame
        return {
            "eye_mm": [float(v) for v in self.eye_mm],
            "eye_sigma_mm": [float(v) for v in self.sigma_mm],
            "distance_mm": float(self.eye_mm[2]),
            "distance_refers_to": "lens surface" if self.gap_mm is not None else "pixel plane (gap unknown)",
            "pixel_plane_distance_mm": float(self.pixel_plane_distance_mm),
            "gap_subtracted_mm": self.gap_mm,
            "optical_axis_angle_deg": float(math.degrees(math.acos(min(1.0, abs(axis[2]))))),
            "roll_deg": float(math.degrees(math.atan2(rot[1, 0], rot[0, 0]))),
            "reprojection_rms_px": float(self.rms_px),
            "points": int(self.points),
            "sigma_includes_intrinsics": bool(self.intrinsics_sigma),
        }


def camera_pose(pixels: np.ndarray, panel_px: np.ndarray, model: CameraModel, pixel_pitch_mm: float,
                gap_mm: float | None = None, draws: int = INTRINSICS_DRAWS, seed: int = 0) -> PanelPose:
    """The camera's pose from correspondences (see the module docstring).

    ARGUMENTS
    pixels          (n, 2) photo pixels (OpenCV convention)
    panel_px        (n, 2) the panel points they see, panel pixels from the panel centre
    model           the calibrated camera
    pixel_pitch_mm  p
    gap_mm          g, when known (a data sheet, or two capture sets); else distances refer to
                    the pixel plane
    draws           intrinsics draws for the uncertainty (0: jackknife only)
    """
    pixels = np.asarray(pixels, np.float64).reshape(-1, 2)
    panel_px = np.asarray(panel_px, np.float64).reshape(-1, 2)
    if len(pixels) < 50 or len(pixels) != len(panel_px):
        raise CalibrationError(f"{len(pixels)} correspondences are too few for a camera pose",
                               hint="photograph the whole panel, in focus")
    obj = np.column_stack([panel_px * pixel_pitch_mm, np.zeros(len(panel_px))])
    norm = model.normalized(pixels)
    rot, centre = _solve(obj, norm)
    focal = float(np.mean(model.intrinsics[:2]))
    rms = float(np.sqrt(np.mean(np.sum((_project(obj, rot, centre) - norm) ** 2, axis=1)))) * focal

    # jackknife over panel blocks
    span = panel_px.max(0) - panel_px.min(0) + 1e-9
    cell = np.floor((panel_px - panel_px.min(0)) / span * JACKKNIFE_BLOCKS).clip(0, JACKKNIFE_BLOCKS - 1)
    block = (cell[:, 1] * JACKKNIFE_BLOCKS + cell[:, 0]).astype(int)
    centres = []
    for b in np.unique(block):
        keep = block != b
        centres.append(_solve(obj[keep], norm[keep], rot, centre)[1])
    centres = np.array(centres)
    k = len(centres)
    var = (k - 1) / k * np.sum((centres - centres.mean(0)) ** 2, axis=0) if k > 1 else np.zeros(3)
    jackknife = np.sqrt(var)
    var[2] += (SYSTEMATIC_FRACTION * -centre[2]) ** 2
    drawn_distances = None
    sampled = model.intrinsics_draws(draws, seed) if draws > 0 else None
    if sampled is not None:
        step = max(1, len(obj) // 3000)
        drawn = np.array([_solve(obj[::step], model.normalized(pixels[::step], d), rot, centre)[1] for d in sampled])
        var = var + np.var(drawn, axis=0, ddof=1)
        drawn_distances = -drawn[:, 2]
    eye = np.array([centre[0], centre[1], -centre[2]])
    pose = PanelPose(eye, np.sqrt(var), float(-centre[2]), None, rot, rms, len(obj), sampled is not None,
                     jackknife, drawn_distances)
    return pose.with_gap(gap_mm) if gap_mm is not None else pose


def _solve(obj: np.ndarray, norm: np.ndarray, rot0: np.ndarray | None = None,
           centre0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(world -> camera rotation (3, 3), camera centre (3,) world mm) from a planar PnP on
    normalised coordinates; refined with Levenberg-Marquardt from the given start."""
    import cv2

    eye3 = np.eye(3)
    img = norm.reshape(-1, 1, 2)
    if rot0 is None:
        ok, rvec, tvec = cv2.solvePnP(obj, img, eye3, None, flags=cv2.SOLVEPNP_IPPE)
        if not ok:
            raise CalibrationError("no camera pose fits the panel correspondences",
                                   hint="check that the camera model belongs to the camera that took the photos")
    else:
        rvec = cv2.Rodrigues(rot0)[0]
        tvec = (-rot0 @ centre0).reshape(3, 1)
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, eye3, None, rvec.copy(), tvec.copy(),
                                      (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14))
    rot = cv2.Rodrigues(rvec)[0]
    centre = -rot.T @ tvec.reshape(3)
    if centre[2] >= 0:
        raise CalibrationError("the camera pose puts the camera behind the panel",
                               hint="check that the camera model belongs to the camera that took the photos")
    return rot, centre


def _project(obj: np.ndarray, rot: np.ndarray, centre: np.ndarray) -> np.ndarray:
    cam = (obj - centre) @ rot.T
    return cam[:, :2] / cam[:, 2:3]
