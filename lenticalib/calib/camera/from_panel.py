"""The calibration camera, estimated from the panel itself (a flat target of known pixel grid).

The fit needs no camera model: every camera pixel's seen panel point is measured directly.
This module turns those correspondences into a camera estimate for the report and the
provenance: focal length, radial distortion, and the camera's pose relative to the panel,
or only the pose when the user gives a camera model (``--camera``).

Frames and units: panel plane points in *panel pixels* (X / 3, Y; origin top-left, x right,
y down, z into the screen); camera pixels of the photo as taken (not the working image).
The seen points lie in the pixel plane, behind the lens surface by the gap g, so a distance from
them is to the pixel plane; with a camera model the pose (:mod:`.pose`) says so and, given the
gap, refers it to the lens surface.
"""

from __future__ import annotations

import math

import numpy as np

from .model_file import CameraModel, load_camera_model
from .pose import PanelPose, camera_pose

__all__ = ["CameraModel", "describe_pose", "estimate_camera", "load_camera_model"]


def estimate_camera(pixels: np.ndarray, panel_points: np.ndarray, image_size: tuple[int, int],
                    model: CameraModel | None = None, pixel_pitch_mm: float | None = None) -> dict:
    """Camera from correspondences: pixels (n, 2) of the photo <-> panel points (n, 2) in panel pixels.

    Without ``model``: focal length (square pixels, principal point at the centre), k1, k2
    and the pose; with it: the pose only (:func:`describe_pose`), in mm with its uncertainty
    when ``pixel_pitch_mm`` is given.  Returns a dict with the reprojection RMS (photo pixels) and
    the camera centre in panel pixels relative to the panel centre (x right, y down, z toward
    the viewer is negative).
    """
    import cv2

    obj = np.column_stack([panel_points, np.zeros(len(panel_points))]).astype(np.float32)
    img = pixels.astype(np.float32)
    w, h = image_size
    if model is None:
        guess = np.array([[1.2 * w, 0, w / 2], [0, 1.2 * w, h / 2], [0, 0, 1.0]])
        flags = (cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_PRINCIPAL_POINT | cv2.CALIB_FIX_ASPECT_RATIO
                 | cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3)
        rms, matrix, dist, rvecs, tvecs = cv2.calibrateCamera([obj], [img], (w, h), guess, np.zeros(5),
                                                              flags=flags)
        rot, _ = cv2.Rodrigues(rvecs[0])
        centre = (-rot.T @ np.asarray(tvecs[0]).reshape(3)).tolist()  # camera centre in the panel frame
        return {"source": "estimated from the panel", "reprojection_rms_px": float(rms),
                "focal_px": float(matrix[0, 0]), "principal_point_px": [float(matrix[0, 2]), float(matrix[1, 2])],
                "distortion": [float(v) for v in np.asarray(dist).ravel()[:5]],
                "centre_panel_px": centre, "roll_deg": float(math.degrees(math.atan2(rot[1, 0], rot[0, 0]))),
                "points": int(len(obj)),
                "note": "without a camera model the focal length, and with it the distance, of a near-frontal view "
                        "is poorly determined; give a camera model ('lenticalib fit --camera M', M from 'lenticalib camera calibrate') for a metric pose"}
    pose = camera_pose(pixels, panel_points, model, pixel_pitch_mm or 1.0)
    return describe_pose(pose, model, pixel_pitch_mm)


def describe_pose(pose: PanelPose, model: CameraModel, pixel_pitch_mm: float | None) -> dict:
    """The JSON-able camera record of a pose found with a given camera model: the centre in panel
    pixels (as without a model) and, with ``pixel_pitch_mm``, the pose in mm (``"pose"``)."""
    eye = pose.eye_mm
    scale = pixel_pitch_mm or 1.0
    out = {"source": model.source or "given", "lensmodel": model.lensmodel,
           "reprojection_rms_px": pose.rms_px, "focal_px": float(model.intrinsics[0]),
           "principal_point_px": [float(model.intrinsics[2]), float(model.intrinsics[3])],
           "centre_panel_px": [float(eye[0]) / scale, float(eye[1]) / scale, -float(pose.pixel_plane_distance_mm) / scale],
           "roll_deg": pose.to_dict()["roll_deg"], "points": pose.points, "note": None}
    if pixel_pitch_mm:
        out["pose"] = pose.to_dict()
    return out
