"""``calibrate_camera``: photos of a chessboard or ChArUco board -> an mrcal ``.cameramodel`` and a report, in one call.

Order of work: every check first (arguments, photos readable and of one size, board geometry,
output paths writable, mrcal importable, enough photos), then corner detection (``jobs``
threads), the count of photos with the board (too few ends here, before the solve), the mrcal
solve, the cross-validation, the model (written atomically) and the report folder (staged).

Errors name the argument at fault by its parameter name (``source="photos"``, ``"square_mm"``,
``"jobs"``, ``"lensmodel"``, ``"board_squares"``, ``"marker_mm"``, ``"dictionary"``; hints mention
``board_corners`` and ``square_mm``); a command-line front end maps them to its flags.

A photo needs only part of the board (:mod:`.corners`: a chessboard's visible block of corners
placed into the board's grid by :mod:`.partial`, a ChArUco board's identified corners); a photo
with too few corners is left out with its reason in the summary, like a photo without the board.
The corners of either board, after the first solve, are located again in views rectified with
its model (:mod:`.rectified`: no lens curvature in the refinement window) and solved again; the
ChArUco corners are always the second ones; chessboard corners the second ones when the model
fits them better (a lower inlier RMS) or when the first ones are pulled outward against them
(:func:`.rectified.bend_pull`: a barrel lens's bend, which the solve absorbs).  A board shown on
the panel is not located again (measured: its model moved off the truth).
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from pathlib import Path
from typing import Callable

from ...core.errors import ImageError, InputError
from ...core.files.imageio import header_size, write_image
from ...core.files.outputs import Inputs, check_output_file, check_output_folder, staged_folder
from ...core.profile import load_profile
from ...core.sizes import MIN_PANEL_SIDE, parse_size
from .board import MANIFEST_NAME as BOARD_MANIFEST

PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png")
MIN_VIEWS = 10  # photos with the board found, at least
MIN_INLIER_CORNERS = 8  # corners of a photo the solve must keep (fewer: the photo is left out and the rest solved again)
MAX_JOBS = 64
TOO_FEW_HINT = ("photograph the board at least 10 times (15-30 is better): tilt the camera 20-40 degrees "
                "in varied directions, and let the board reach every corner of the image")
NOT_FOUND_HINT = {"chessboard": "is sharp in the photos, at least 3 x 3 of its inner corners in each",
                  "charuco": "is sharp in the photos and its dictionary, squares and marker size are right"}
REPORT_WHAT = "calibration report"

StageFn = Callable[[str, int], Callable[..., None]]
"""``stage(name, steps)`` is called as each stage starts; it returns the function called once per step."""


@dataclasses.dataclass
class CameraCalibration:
    """What :func:`calibrate_camera` did: ``summary`` (the report's ``summary.json`` document,
    :func:`~.report.calibration_summary`), ``output`` (the ``.cameramodel`` written), ``report_dir``
    (the report folder written, or None), ``model`` (the mrcal cameramodel), ``calibration``
    (:class:`~.solve.Calibration`), ``quality`` (:func:`~.quality.quality`)."""

    summary: dict
    output: Path
    report_dir: Path | None
    model: object
    calibration: object
    quality: dict


def collect_photos(items) -> list[Path]:
    """The photo files named by ``items`` (files, or folders: their .jpg/.jpeg/.png files, sorted, no
    dotfiles; the board folder 'camera patterns' wrote, holding board.json and captures/, stands for
    its captures/, not for the board drawing beside them), in order, without repeats; InputError for
    anything missing or not a photo."""
    photos, seen = [], set()
    for item in items:
        path = Path(item)
        if path.is_dir() and (path / BOARD_MANIFEST).is_file() and (path / "captures").is_dir():
            path = path / "captures"
        if path.is_dir():
            found = sorted(p for p in path.iterdir()
                           if p.is_file() and not p.name.startswith(".") and p.suffix.lower() in PHOTO_SUFFIXES)
            if not found:
                raise InputError("folder holds no photos (.jpg, .jpeg, .png)", source=str(path),
                                 hint="give the folder the photos of the board are in")
        elif path.is_file():
            if path.suffix.lower() not in PHOTO_SUFFIXES:
                raise InputError("is not a photo (.jpg, .jpeg or .png)", source=str(path),
                                 hint="give photos or folders")
            found = [path]
        else:
            raise InputError("no such file or folder", source=str(path), hint="check the path of the photos")
        for p in found:
            key = p.resolve()
            if key not in seen:
                seen.add(key)
                photos.append(p)
    return photos


def photo_size(path) -> tuple[int, int]:
    """(width, height) of a photo as read with its EXIF orientation, from its header; ImageError when
    it is not a readable image or has more pixels than :data:`lenticalib.core.files.imageio.MAX_IMAGE_PIXELS`."""
    size = header_size(path, camera_orientation=True)
    if size is None:
        raise ImageError("not a readable photo (not an image format Pillow knows)", source=str(path),
                         hint="remove it or give another photo")
    return size


def photos_board(photos: list[Path], board_corners: tuple[int, int] | None = None,
                 square_mm: float | None = None, *, board_squares: tuple[int, int] | None = None,
                 marker_mm: float | None = None, dictionary: str | None = None):
    """(:class:`~.board.Board`, its board.json or None): a printed chessboard of ``board_corners``
    (inner corners, columns x rows) and ``square_mm``; a printed ChArUco board of ``board_squares``
    (squares, columns x rows, as OpenCV's CharucoBoard counts them), ``square_mm``, ``marker_mm``
    and ``dictionary``; or the ``board.json`` beside the photos or up to two folders above.
    InputError naming the argument otherwise."""
    from .board import Board, find_board_manifest, read_board

    if board_corners is not None and board_squares is not None:
        raise InputError("give either a chessboard's inner corners or a ChArUco board's squares, not both",
                         source="board_squares", hint="board_corners for a chessboard, board_squares for ChArUco")
    charuco_args = {"marker_mm": marker_mm, "dictionary": dictionary}
    if board_squares is None and any(v is not None for v in charuco_args.values()):
        name = next(k for k, v in charuco_args.items() if v is not None)
        raise InputError("applies to a ChArUco board only", source=name,
                         hint="give board_squares (the ChArUco board's squares) with it, or leave it out")
    given = board_corners if board_corners is not None else board_squares
    if (given is None) != (square_mm is None):
        raise InputError("needs both the board's size and square_mm",
                         source=("board_squares" if board_squares is not None else "board_corners")
                         if given is not None else "square_mm",
                         hint="e.g. 11x6 inner corners of 20 mm squares, or neither to use board.json")
    if given is not None:
        if not (math.isfinite(square_mm) and 0.1 <= square_mm <= 1000):
            raise InputError(f"{square_mm} mm squares is out of range", source="square_mm",
                             hint="give the square size in mm, 0.1..1000")
        if board_corners is not None:
            cols, rows = board_corners
            return Board(cols=cols, rows=rows, square_mm=float(square_mm), kind="print"), None
        if marker_mm is None:
            raise InputError("a ChArUco board needs its marker size", source="marker_mm",
                             hint="give the side of the black markers in mm (e.g. 12 for 20 mm squares)")
        if dictionary is None:
            raise InputError("a ChArUco board needs its ArUco dictionary", source="dictionary",
                             hint="give the OpenCV name it was made with, e.g. DICT_4X4_50 or DICT_5X5_100")
        cols, rows = board_squares
        return Board(cols=cols - 1, rows=rows - 1, square_mm=float(square_mm), kind="print", pattern="charuco",
                     dictionary=dictionary, marker_mm=float(marker_mm)), None
    manifest = find_board_manifest(photos)
    if manifest is None:
        raise InputError("no board geometry: no board.json beside the photos or up to two folders above",
                         source="photos", hint="pass board_corners and square_mm, or keep the photos in "
                         "DIR/captures of the folder 'lenticalib camera patterns' wrote")
    return read_board(manifest), manifest


def calibrate_camera(photos, output: str | os.PathLike, *, board_corners: tuple[int, int] | None = None,
                     square_mm: float | None = None, report_dir: str | os.PathLike | None = None,
                     lensmodel: str | None = None, jobs: int = 2, stage: StageFn | None = None,
                     board_squares: tuple[int, int] | None = None, marker_mm: float | None = None,
                     dictionary: str | None = None) -> CameraCalibration:
    """Calibrate one camera from photos of a chessboard or a ChArUco board; write the model (and the report).

    ARGUMENTS
    photos         photo files (.jpg, .jpeg, .png) or folders of them
    output         the ``.cameramodel`` to write (atomically)
    board_corners  (columns, rows) of inner corners of a printed board, with ``square_mm`` (its
                   square size in mm); both None: the ``board.json`` beside the photos
    board_squares  (columns, rows) of squares of a printed ChArUco board, with ``square_mm``,
                   ``marker_mm`` (marker side, mm) and ``dictionary`` (OpenCV name, e.g. DICT_4X4_50)
    report_dir     the report folder (figures and ``summary.json``, staged); None: no report
    lensmodel      force an mrcal lens model; None: chosen by the data
    jobs           photos searched for corners in parallel, 1..64
    stage          progress: ``stage(name, steps)`` as each stage starts returns the per-step
                   callback (:data:`StageFn`)

    RETURNED VALUE
    :class:`CameraCalibration`.  Every InputError comes before the corner search, except too few
    photos with the board found (after it, before the solve).
    """
    import numpy as np

    from . import solve as solve_module
    from ..camera.model_file import write_cameramodel
    from .report import REPORT_FILES, calibration_summary, write_report

    start = time.perf_counter()
    if not 1 <= jobs <= MAX_JOBS:
        raise InputError(f"{jobs} jobs is out of range", source="jobs", hint=f"use 1..{MAX_JOBS} (the number of cores)")
    if lensmodel is not None:
        solve_module.check_lensmodel(lensmodel)
    photos = collect_photos(photos)  # the photos and the board file first: the outputs may be neither
    board, manifest = photos_board(photos, board_corners, square_mm, board_squares=board_squares,
                                   marker_mm=marker_mm, dictionary=dictionary)
    inputs = (*photos, manifest)
    output = check_output_file(output, "camera model", example="camera.cameramodel", inputs=inputs)
    if output.suffix != ".cameramodel":  # mrcal's format: fit --camera would refuse any other name
        raise InputError(f"a camera model is written in mrcal's .cameramodel format, not as "
                         f"{output.suffix or 'a file without a suffix'}", source=str(output),
                         hint=f"name it {output.with_suffix('.cameramodel')}")
    if report_dir is not None:
        check_output_folder(report_dir, REPORT_WHAT, REPORT_FILES, inputs=inputs)
    if len(photos) < MIN_VIEWS:
        raise InputError(f"only {len(photos)} photos given; at least {MIN_VIEWS} views of the board are needed",
                         source="photos", hint=TOO_FEW_HINT)
    sizes = {p: photo_size(p) for p in photos}
    size = sizes[photos[0]]
    for p, s in sizes.items():
        if s != size:
            raise InputError(f"is {s[0]}x{s[1]} pixels, the first photo {size[0]}x{size[1]}", source=str(p),
                             hint="calibrate photos of one camera at one resolution and zoom")
    solve_module.import_mrcal()

    from .corners import detect_photos
    from .crossval import cross_validation, locator_difference, with_locator_term
    from .quality import quality

    def steps(name: str, total: int):
        return stage(name, total) if stage is not None else (lambda *message: None)

    found = detect_photos(photos, board, jobs=jobs, progress=steps("finding corners", len(photos)))
    used = [f for f in found if f.corners is not None]
    if len(used) < MIN_VIEWS:
        raise InputError(f"the board was found in {len(used)} of {len(photos)} photos; at least {MIN_VIEWS} are needed",
                         source="photos", hint=f"check the board ({board.describe()}) "
                         f"{NOT_FOUND_HINT[board.pattern]}, and {TOO_FEW_HINT}")
    corners = np.stack([f.corners for f in used])
    solving = solve_module.PROGRESS_STEPS
    cal = solve_module.calibrate(corners, board, size, lensmodel=lensmodel, progress=steps("solving", solving))
    kept = cal.solve.inlier.sum(axis=(1, 2))
    lost = kept < MIN_INLIER_CORNERS
    if lost.any() and len(used) - int(lost.sum()) >= MIN_VIEWS:
        # a photo whose corners the solve rejected (nearly) all of disagrees with the others (a
        # misread board): its pose would be unconstrained, so it is left out and the rest solved again
        for f, n in zip(used, kept):
            if n < MIN_INLIER_CORNERS:
                f.corners, f.reason = None, (f"its corners disagree with the other photos ({int(n)} of them fit): "
                                             "a misread or moving board")
        used = [f for f in used if f.corners is not None]
        corners = np.stack([f.corners for f in used])
        cal = solve_module.calibrate(corners, board, size, lensmodel=lensmodel, progress=steps("solving again", solving))
    # the corners located again without the lens's curvature (:mod:`.rectified`), solved again
    from .rectified import BEND_MIN_PX, BEND_T, bend_pull, refine_photos

    if board.kind == "panel":
        # a board shown through the lens sheet is left as first located: measured on the simulated
        # panel set, its rectified corners fit better yet moved the model (truth within 3 sigma on
        # 91 % of the image instead of 98 %)
        rectified = {"rms_first": round(cal.solve.rms, 5), "rms_rectified": None, "kept": False}
        unkept = None
    else:
        refined = refine_photos([f.path for f in used], corners, board, cal.cameramodel(),
                                progress=steps("refining corners in rectified views", len(used)))
        second = solve_module.calibrate(refined, board, size, lensmodel=lensmodel,
                                        progress=steps("solving with the refined corners", solving))
        # ChArUco corners: always kept (their first windows straddle markers).  Chessboard corners:
        # kept when the model fits them better, or when the first ones are pulled outward along
        # the radius against them (a barrel lens's bend, which the solve absorbs into the lens with
        # lower residuals: bench strong 3, 0.213 px with the first corners); not otherwise (a noisy,
        # sharpened phone photo's resampled view can make the second ones worse: measured on the
        # bench's phone sets, 0.12 -> 0.44-0.53 px)
        pull = bend_pull(corners, refined, cal.cameramodel())
        bent = pull["t"] > BEND_T and pull["pull_px"] > BEND_MIN_PX
        rectified = {"rms_first": round(cal.solve.rms, 5), "rms_rectified": round(second.solve.rms, 5),
                     "first_pull": pull,
                     "kept": bool(board.pattern == "charuco" or second.solve.rms <= cal.solve.rms or bent)}
        # when a chessboard's first corners are kept, the rectified solve measures their locator's
        # error (their fit takes the lines' bend for a parabola over the window); the rectified
        # corners, fitted where the lines are straight, are not measured by the first ones (which
        # would count the first locator's error against them: on the bench's sets that grew the
        # scale to 1.8-2.8 with the truth at a median 0.3-0.8 sigma), nor are ChArUco corners
        unkept = None if board.pattern == "charuco" or rectified["kept"] else second
        if rectified["kept"]:
            corners, cal = refined, second
            for f, c in zip(used, corners):
                f.corners = c
    model = cal.cameramodel()
    step = steps("cross-validating", 1)
    check = cross_validation(corners, board, size, cal.lensmodel)
    if unkept is not None and not check.get("skipped"):
        check = with_locator_term(check, locator_difference(model, unkept.cameramodel(), corners))
    step()
    qual = quality(model, cal.solve, [f.path for f in used], cross_validation=check)
    summary = calibration_summary(cal, qual, board, found, photos, output=output,
                                  report=None if report_dir is None else str(report_dir),
                                  manifest=manifest, seconds=time.perf_counter() - start, rectified=rectified)
    write_cameramodel(model, output, note=summary["note"])
    if report_dir is not None:
        with staged_folder(report_dir, REPORT_WHAT, REPORT_FILES, inputs=inputs) as stage_dir:
            write_report(stage_dir, cal, qual, summary)
    return CameraCalibration(summary, output, None if report_dir is None else Path(report_dir), model, cal, qual)


def board_panel(profile: str | os.PathLike | None = None, panel: str | tuple[int, int] | None = None,
                pixel_pitch_mm: float | None = None) -> tuple[int, int, float, float | None]:
    """The panel a board is drawn for: ``(width, height)`` in pixels, the pixel pitch in mm and the
    lens pitch in pixels (None without a profile), for :func:`write_board_folder`.

    Give the panel once: ``profile`` (a profile's path: its size, lens period, and its physical
    block's pixel pitch unless ``pixel_pitch_mm`` is given), or ``panel`` (``"WxH"`` or a pair, at
    least :data:`lenticalib.core.sizes.MIN_PANEL_SIDE` pixels a side) with ``pixel_pitch_mm``.
    InputError (ProfileError for the profile) naming the argument otherwise.
    """
    if (profile is None) == (panel is None):
        raise InputError("give the panel once: `profile` P, or `panel` WxH with `pixel_pitch_mm` MM",
                         source="profile" if profile else "panel",
                         hint="e.g. `panel` 3840x2160 and `pixel_pitch_mm` 0.1796")
    pitch, lens_px = pixel_pitch_mm, None
    if profile is not None:
        loaded = load_profile(profile, "`profile`")
        width, height = loaded.width, loaded.height
        lens_px = loaded.period / 3.0
        if pitch is None:
            pitch = (loaded.physical or {}).get("pixel_pitch_mm")
        if pitch is None:
            raise InputError("the profile does not give the panel's pixel pitch", source=str(profile),
                             hint="pass `pixel_pitch_mm` MM (from the panel's data sheet)")
    else:
        width, height = parse_size(panel, "panel", MIN_PANEL_SIDE)
        if pitch is None:
            raise InputError("the panel's pixel pitch is needed for the board's square size", source="panel",
                             hint="pass `pixel_pitch_mm` MM (from the panel's data sheet)")
    return width, height, pitch, lens_px


def write_board_folder(output: str | os.PathLike, width: int, height: int, pixel_pitch_mm: float, *,
                       squares: tuple[int, int] | None = None, lens_pitch_mm: float | None = None,
                       lens_pitch_px: float | None = None, print_square_mm: float = 20.0, paper: str = "A4",
                       pattern: str = "chessboard", dictionary: str | None = None, inputs: Inputs):
    """Write the calibration board (``pattern`` "chessboard" or "charuco", then with markers of
    ``dictionary``, default the smallest 4x4 dictionary that holds them) of a ``width`` x ``height``
    panel of ``pixel_pitch_mm`` into the folder ``output`` (staged, whole or not at all):
    ``board.png`` (the panel raster), ``board.json``, and ``print/`` (a sheet of ``print_square_mm``
    squares on ``paper``, PDF and PNG, with its own ``board.json``).  ``squares``: inner corners (columns, rows) of the panel board
    (default: 9 squares down the short side); the lens pitch (``lens_pitch_mm`` from a data sheet,
    or ``lens_pitch_px`` panel pixels from a profile) widens the squares' soft edges to span at
    least two lenses.  ``inputs``: the files the caller read (a profile), never written over.  Returns
    (panel board, printed board); InputError naming the argument first.
    """
    from .board import (MANIFEST_NAME, PANEL_IMAGE, PRINT_FOLDER, PRINT_PDF, PRINT_PNG, panel_board, print_board,
                        write_manifest)
    from .draw import panel_raster, write_print_sheet

    if not (isinstance(pixel_pitch_mm, (int, float)) and math.isfinite(pixel_pitch_mm)
            and 0.005 <= pixel_pitch_mm <= 5.0):
        raise InputError(f"pixel pitch {pixel_pitch_mm!r} mm is out of range", source="pixel_pitch_mm",
                         hint="give the panel's pixel pitch in mm, 0.005..5 (e.g. 0.1796)")
    if lens_pitch_mm is not None:
        if not (math.isfinite(lens_pitch_mm) and 0.005 <= lens_pitch_mm <= 50.0):
            raise InputError(f"lens pitch {lens_pitch_mm!r} mm is out of range", source="lens_pitch_mm",
                             hint="give the sheet's horizontal lens pitch in mm, 0.005..50")
        lens_pitch_px = lens_pitch_mm / pixel_pitch_mm
    board = panel_board(width, height, float(pixel_pitch_mm), squares, lens_pitch_px=lens_pitch_px,
                        pattern=pattern, dictionary=dictionary)
    sheet = print_board(print_square_mm, paper, pattern=pattern, dictionary=dictionary)
    contents = (PANEL_IMAGE, MANIFEST_NAME, PRINT_FOLDER,
                *(f"{PRINT_FOLDER}/{name}" for name in (PRINT_PDF, PRINT_PNG, MANIFEST_NAME)))
    check_output_folder(output, "camera board folder", contents, inputs=inputs)
    with staged_folder(output, "camera board folder", contents, inputs=inputs) as stage:
        write_image(stage / PANEL_IMAGE, panel_raster(board))
        write_manifest(board, stage)
        (stage / PRINT_FOLDER).mkdir()
        write_print_sheet(sheet, stage / PRINT_FOLDER)
        write_manifest(sheet, stage / PRINT_FOLDER)
    return board, sheet
