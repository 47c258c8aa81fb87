"""The calibration camera, estimated from the panel itself (a flat target of known pixel grid).

The fit needs no camera model: every camera pixel's seen panel point is measured directly.
This module turns those correspondences into a camera estimate for the report and the
provenance: focal length, radial distortion, and the camera's pose relative to the panel,
or only the pose when the user gives a camera model (``--camera``).

Frames and units: panel plane points in *panel pixels* (X / 3, Y; origin top-left, x right,
y down, z into the screen); camera pixels of the photo as taken (not the working image).
The seen coordinates are magnified by (1 + g/D) about the camera's foot point (the lens sheet
acts as a magnifier), so distances carry that ~0.3 % bias.
"""

from __future__ import annotations

import ast
import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np

from ..errors import InputError


@dataclasses.dataclass
class CameraModel:
    """Pinhole + OpenCV distortion: ``matrix`` (3, 3) in pixels, ``distortion`` (k1 k2 p1 p2 [k3 ...])."""

    matrix: np.ndarray
    distortion: np.ndarray
    image_size: tuple[int, int] | None = None
    source: str | None = None


def load_camera_model(path: str | os.PathLike) -> CameraModel:
    """Read an mrcal ``.cameramodel`` (OPENCV or PINHOLE lens models) or an OpenCV YAML/JSON file.

    The .cameramodel text is parsed as a literal (never executed) when mrcal is not installed.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("camera model not found", source=str(path), hint="give an existing .cameramodel or .yaml")
    text = path.read_text(errors="replace")
    try:
        if path.suffix == ".cameramodel":
            return _from_mrcal(path, text)
        if path.suffix in (".yaml", ".yml", ".xml"):
            return _from_opencv_storage(path)
        data = json.loads(text)
        return CameraModel(np.asarray(data["camera_matrix"], float).reshape(3, 3),
                           np.asarray(data.get("distortion", [0, 0, 0, 0]), float).ravel(),
                           tuple(data["image_size"]) if "image_size" in data else None, str(path))
    except InputError:
        raise
    except Exception as exc:  # any parse failure of a user file is a user error
        raise InputError(f"cannot read the camera model ({exc})", source=str(path),
                         hint="give an mrcal .cameramodel with an OPENCV lens model, or OpenCV YAML/JSON with "
                              "camera_matrix and distortion") from None


def _from_mrcal(path: Path, text: str) -> CameraModel:
    try:
        import mrcal  # noqa: F401

        model = mrcal.cameramodel(str(path))
        lensmodel, intrinsics = model.intrinsics()
        size = tuple(int(v) for v in model.imagersize())
    except ImportError:
        lines = [line.split("#", 1)[0] for line in text.splitlines()]
        data = ast.literal_eval("\n".join(lines))
        lensmodel, intrinsics = data["lensmodel"], np.asarray(data["intrinsics"], float)
        size = tuple(int(v) for v in data["imagersize"])
    intrinsics = np.asarray(intrinsics, float)
    if not (lensmodel.startswith("LENSMODEL_OPENCV") or lensmodel == "LENSMODEL_PINHOLE"):
        raise InputError(f"lens model {lensmodel} is not supported", source=str(path),
                         hint="use a LENSMODEL_OPENCV4/5/8 or LENSMODEL_PINHOLE model")
    fx, fy, cx, cy = intrinsics[:4]
    matrix = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    return CameraModel(matrix, intrinsics[4:] if intrinsics.size > 4 else np.zeros(4), size, str(path))


def _from_opencv_storage(path: Path) -> CameraModel:
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        matrix = fs.getNode("camera_matrix").mat()
        dist = fs.getNode("distortion_coefficients").mat()
        if dist is None:
            dist = fs.getNode("distortion").mat()
    finally:
        fs.release()
    if matrix is None:
        raise InputError("has no camera_matrix", source=str(path), hint="write it with cv2.FileStorage")
    return CameraModel(np.asarray(matrix, float), np.zeros(4) if dist is None else np.asarray(dist, float).ravel(),
                       None, str(path))


def estimate_camera(pixels: np.ndarray, panel_points: np.ndarray, image_size: tuple[int, int],
                    model: CameraModel | None = None) -> dict:
    """Camera from correspondences: pixels (n, 2) of the photo <-> panel points (n, 2) in panel pixels.

    Without ``model``: focal length (square pixels, principal point at the centre), k1, k2
    and the pose; with it: the pose only.  Returns a JSON-able dict with the reprojection
    RMS (photo pixels) and the camera centre in panel pixels relative to the panel centre
    (x right, y down, z toward the viewer is negative).
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
        rvec, tvec = rvecs[0], tvecs[0]
        source = "estimated from the panel"
    else:
        matrix, dist = model.matrix, model.distortion
        ok, rvec, tvec = cv2.solvePnP(obj, img, matrix, dist, flags=cv2.SOLVEPNP_ITERATIVE)
        proj, _ = cv2.projectPoints(obj, rvec, tvec, matrix, dist)
        rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1))))
        source = model.source or "given"
    rot, _ = cv2.Rodrigues(rvec)
    centre = (-rot.T @ np.asarray(tvec).reshape(3)).tolist()  # camera centre in the panel frame
    return {"source": source, "reprojection_rms_px": float(rms),
            "focal_px": float(matrix[0, 0]), "principal_point_px": [float(matrix[0, 2]), float(matrix[1, 2])],
            "distortion": [float(v) for v in np.asarray(dist).ravel()[:5]],
            "centre_panel_px": centre, "roll_deg": float(math.degrees(math.atan2(rot[1, 0], rot[0, 0]))),
            "points": int(len(obj)),
            "note": None if model is not None else
            "without a camera model the focal length, and with it the distance, of a near-frontal view "
            "is poorly determined; pass --camera for a metric pose"}
