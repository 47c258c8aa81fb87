"""A synthetic camera-calibration set: photos of a chessboard or ChArUco board by a known camera, and the truth.

Layout written into ``DIR`` (the folder ``lenticalib camera simulate DIR`` makes):

    DIR/captures/board-NN.jpg   the camera's JPEGs, NN = 01, 02, ...
    DIR/board.json              the board (:mod:`lenticalib.calib.intrinsics.board`); a panel set
    DIR/board.png               also holds the raster the panel showed
    DIR/truth.cameramodel       the true intrinsics as an mrcal model: LENSMODEL_OPENCV5 (the
                                simulated camera is OpenCV's k1 k2 p1 p2 k3 model)
    DIR/simulation.json         seed, kind, conditions, ``cut`` (share of photos with the board
                                partly outside the frame: ChArUco sets), the camera (every field), for a panel set
                                the panel optics, and for every photo the true board pose
                                ``rt_cam_board`` (mrcal rt: Rodrigues rad, translation mm), for a
                                panel set also the camera's world pose; and the render time

Board poses are in the camera frame; a panel board's frame lies in the panel's pixel plane (see
:mod:`.boards`), so ``rt_cam_board`` of a panel set is the pose of that plane, the camera
standing ``D + g`` from it.  ``calibrate`` against ``truth.cameramodel`` and these poses
(:func:`lenticalib.calib.intrinsics.quality.compare_to_truth`) to check a calibration.
"""

from __future__ import annotations

import datetime as _dt
import os
import time
from pathlib import Path
from typing import Callable

import numpy as np

from .. import __version__
from ..calib.intrinsics.board import PANEL_IMAGE, panel_board, print_board, write_manifest
from ..calib.intrinsics.draw import panel_raster
from ..calib.camera.model_file import write_cameramodel
from ..calib.intrinsics.solve import import_mrcal
from ..core.files.atomic import write_bytes_atomic
from ..core.files.documents import FORMATS, read_document, write_document
from ..core.errors import InputError
from ..core.files.imageio import write_image
from .board_poses import BoardPose, board_poses
from .boards import calibration_camera, camera_for_pose, photograph_print_board

CAPTURE_FOLDER = "captures"
SIMULATION_NAME = "simulation.json"
TRUTH_NAME = "truth.cameramodel"
DOCUMENT = FORMATS["lenticalib.camera-simulation"]
PANEL_SIZE = (3840, 2160)
CHARUCO_CUT = 0.35  # share of a ChArUco set's photos with the board partly outside the frame
CONTENTS = (CAPTURE_FOLDER, SIMULATION_NAME, TRUTH_NAME, "board.json", "board.png")


def photo_name(k: int) -> str:
    """File name of photo ``k`` (0-based): ``board-01.jpg`` ..."""
    return f"board-{k + 1:02d}.jpg"


def panel_scene(seed: int, resolution: tuple[int, int], conditions: str = "standard", subsamples: int = 2,
                panel=None):
    """The virtual panel (a random panel drawn from ``seed``: 3840 x 2160, or ``panel`` = a board's
    ``{"width", "height", "pixel_pitch_mm"}``) with the calibration camera of
    :func:`.boards.calibration_camera` (its geometry and noise) in place of the scene's camera
    geometry; the panel's colour mixing and exposure are kept."""
    from .scene import random_scene

    size = PANEL_SIZE if panel is None else (int(panel["width"]), int(panel["height"]))
    ranges = {} if panel is None else {"panel_width": float(panel["pixel_pitch_mm"]) * size[0]}
    scene = random_scene(int(seed), width=size[0], height=size[1], resolution=resolution,
                         subsamples=subsamples, conditions=conditions, **ranges)
    cal = calibration_camera(seed, resolution, conditions, subsamples)
    keep = ("width", "height", "fx", "fy", "cx", "cy", "distortion", "defocus_sigma", "full_well", "read_noise",
            "tone_gamma", "tone_contrast", "sharpen", "jpeg_quality", "exposure_jitter")
    return scene.replace_camera(**{k: getattr(cal, k) for k in keep}, chromatic=(0.0, 0.0), shake=0.0)


def truth_cameramodel(camera):
    """The camera's intrinsics as an ``mrcal.cameramodel`` (LENSMODEL_OPENCV5, identity pose)."""
    mrcal = import_mrcal()
    intrinsics = np.array([camera.fx, camera.fy, camera.cx, camera.cy, *camera.distortion], np.float64)
    return mrcal.cameramodel(intrinsics=("LENSMODEL_OPENCV5", intrinsics), imagersize=(camera.width, camera.height))


def simulate_board_set(directory: str | os.PathLike, *, kind: str = "panel", seed: int = 0, photos: int = 24,
                       resolution: tuple[int, int] = (1600, 1200), conditions: str = "standard",
                       subsamples: int = 2, progress: Callable[[], None] | None = None, scene=None,
                       board=None, pattern: str = "chessboard", lens: str = "standard",
                       cut: float | None = None) -> dict:
    """Photograph a board ``photos`` times into ``directory`` (an existing, empty or fresh folder).

    ARGUMENTS
    kind         "panel" (the board on the virtual panel, through its lens sheet) or "print"
    seed         seed of the camera, the panel, the poses and the noise
    photos       number of photos
    resolution   camera (width, height) in pixels
    conditions   "standard" or "hard" (:func:`.boards.calibration_camera`)
    lens         a print set's lens kind (:data:`.boards.LENSES`)
    subsamples   rays per sensor pixel side
    progress     called after every photo
    scene        a panel set's :class:`.scene.Scene` to use instead of the one drawn from ``seed``
                 (its panel, and its camera's intrinsics and photometry: the camera that will
                 photograph the calibration patterns too); ``resolution``, ``conditions`` and
                 ``subsamples`` are then the scene's
    board        a panel set's board (:func:`lenticalib.calib.intrinsics.board.panel_board`, e.g. from
                 the user's ``camera patterns`` folder) instead of the default one, whose soft edges
                 span two of the scene's lens pitches; without ``scene`` the panel drawn from
                 ``seed`` then has the board's panel size and pixel pitch; for a print set, a
                 printed board (:func:`lenticalib.calib.intrinsics.board.print_board`)
    pattern      the default board's pattern, "chessboard" or "charuco" (ignored with ``board``)
    cut          share of the photos whose board runs off the frame (:func:`.board_poses.board_poses`);
                 None: ``CHARUCO_CUT`` for a ChArUco board, 0 for a chessboard (a cut chessboard
                 photo is used for the block of its corners in view)

    RETURNED VALUE
    the ``simulation.json`` document (also written).
    """
    if kind not in ("panel", "print"):
        raise InputError(f"unknown board kind {kind!r}", source="kind", hint="use panel or print")
    if kind == "panel" and lens != "standard":
        raise InputError(f"lens {lens!r} applies to print sets only", source="lens",
                         hint="a panel set's camera comes from its scene")
    folder = Path(directory)
    captures = folder / CAPTURE_FOLDER
    captures.mkdir(exist_ok=True)
    records, seconds = [], []
    if kind == "panel":
        if scene is None:
            scene = panel_scene(seed, resolution, conditions, subsamples, None if board is None else board.panel)
        camera, optics = scene.camera, scene.optics
        resolution = (camera.width, camera.height)
        # the edges matched to the sheet, as 'camera patterns --profile' does (a profile's period / 3)
        if board is None:
            board = panel_board(optics.width, optics.height, optics.pixel_pitch,
                                lens_pitch_px=optics.lens_pitch / optics.pixel_pitch, pattern=pattern)
        raster = panel_raster(board)
        write_image(folder / PANEL_IMAGE, raster)
    else:
        camera, optics = calibration_camera(seed, resolution, conditions, subsamples, lens), None
        if board is None:
            board = print_board(pattern=pattern)
        elif board.kind != "print":
            raise InputError("a print set needs a printed board", source="board",
                             hint="make one with print_board()")
    if cut is None:
        cut = CHARUCO_CUT if board.charuco else 0.0
    poses: list[BoardPose] = board_poses(camera, board, photos, seed, cut=cut)
    for k, pose in enumerate(poses):
        rng = np.random.default_rng([int(seed), k, 0x5107])
        start = time.perf_counter()
        record = {"file": f"{CAPTURE_FOLDER}/{photo_name(k)}", "rt_cam_board": pose.rt().round(12).tolist()}
        if kind == "panel":
            from .photo import photograph_jpeg

            moved = camera_for_pose(camera, optics, board, pose)
            shot, _ = moved.for_photo(rng)
            data = photograph_jpeg(raster, scene.replace_camera(position=moved.position, aim=moved.aim,
                                                                roll=moved.roll, exposure=shot.exposure), rng)
            record["camera_world"] = {"position": list(moved.position), "aim": list(moved.aim), "roll": moved.roll}
        else:
            data = photograph_print_board(camera, board, pose, rng)
        seconds.append(time.perf_counter() - start)
        write_bytes_atomic(captures / photo_name(k), data)
        records.append(record)
        if progress:
            progress()
    write_manifest(board, folder)
    truth = truth_cameramodel(camera)
    write_cameramodel(truth, folder / TRUTH_NAME, note=f"lenticalib camera simulate: the true intrinsics "
                                                     f"(seed {seed}, {kind} board)")

    document = {**DOCUMENT.envelope(), "kind": kind, "seed": int(seed), "conditions": conditions,
                "lens": lens if kind == "print" else "panel scene",
                "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
                "lenticalib_version": __version__, "resolution": list(resolution), "board": board.to_dict(),
                "camera": camera.to_dict(), "optics": None if optics is None else optics.to_dict(),
                "pose_frame": ("camera frame <- board frame (origin inner corner (0,0)"
                               + (", in the panel's pixel plane z = +g)" if kind == "panel" else ")")),
                "cut": float(cut), "photos": records, "seconds_per_photo": round(float(np.mean(seconds)), 3),
                "truth": TRUTH_NAME}
    write_document(folder / SIMULATION_NAME, DOCUMENT, document)
    return document


def read_truth_poses(directory: str | os.PathLike) -> dict[str, np.ndarray]:
    """``{photo file name: rt_cam_board (6,)}`` from a simulation's ``simulation.json``."""
    data = read_document(Path(directory) / SIMULATION_NAME, DOCUMENT, "simulate the set first")
    return {Path(p["file"]).name: np.asarray(p["rt_cam_board"], np.float64) for p in data["photos"]}
