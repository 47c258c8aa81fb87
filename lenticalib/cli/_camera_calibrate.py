"""``lenticalib camera calibrate``: photos of a chessboard -> an mrcal ``.cameramodel`` and a report.

Order of work: every check first (options, photos readable and of one size, board geometry,
output paths writable, mrcal importable, enough photos), then corner detection (``--jobs``
processes, a progress bar), the count of photos with the board (too few ends here, before the
solve), the mrcal solve, the model (written atomically) and the report folder (staged).
"""

from __future__ import annotations

import argparse

PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png")
MIN_VIEWS = 10  # photos with the board found, at least
TOO_FEW_HINT = ("photograph the board at least 10 times (15-30 is better): tilt the camera 20-40 degrees "
                "in varied directions, and let the board reach every corner of the image")


def add_calibrate_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("photos", nargs="+", metavar="PHOTOS", help="photos (.jpg, .jpeg, .png) or folders of them")
    parser.add_argument("-o", "--output", required=True, metavar="FILE", help="the camera model to write "
                        "(.cameramodel)")
    parser.add_argument("--board", metavar="COLSxROWS", help="inner corners of the board (default: from the "
                        "board.json next to the photos)")
    parser.add_argument("--square", type=float, metavar="MM", help="square size of the board in mm (with --board)")
    parser.add_argument("--report", metavar="DIR", help="folder for the figures and summary.json")
    parser.add_argument("--lensmodel", metavar="NAME", help="force an mrcal lens model (default: chosen by the "
                        "data between LENSMODEL_OPENCV8 and a splined model)")
    parser.add_argument("--jobs", type=int, default=2, metavar="N", help="photos processed in parallel (default 2)")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON instead of sentences")


def collect_photos(items: list[str]) -> list:
    """The photo files named by ``items`` (files, or folders: their .jpg/.jpeg/.png files, sorted, no
    dotfiles), in order, without repeats; InputError for anything missing or not a photo."""
    from pathlib import Path

    from ..core.errors import InputError

    photos, seen = [], set()
    for item in items:
        path = Path(item)
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
    it is not a readable image or has more pixels than :data:`lenticalib.core.imageio.MAX_IMAGE_PIXELS`."""
    from ..core.errors import ImageError
    from ..core.imageio import header_size

    size = header_size(path, camera_orientation=True)
    if size is None:
        raise ImageError("not a readable photo (not an image format Pillow knows)", source=str(path),
                         hint="remove it or give another photo")
    return size


def _board(args: argparse.Namespace, photos: list):
    import math

    from ..calib.intrinsics.board import Board, find_board_manifest, parse_squares, read_board
    from ..core.errors import InputError

    if (args.board is None) != (args.square is None):
        raise InputError("needs both --board COLSxROWS and --square MM", source="--board" if args.board else "--square",
                         hint="e.g. --board 11x6 --square 20, or leave both out to use board.json")
    if args.board is not None:
        cols, rows = parse_squares(args.board, "--board")
        if not (math.isfinite(args.square) and 0.1 <= args.square <= 1000):
            raise InputError(f"{args.square} mm squares is out of range", source="--square",
                             hint="give the square size in mm, 0.1..1000")
        return Board(cols=cols, rows=rows, square_mm=float(args.square), kind="print"), None
    manifest = find_board_manifest(photos)
    if manifest is None:
        raise InputError("no board geometry: no board.json beside the photos or up to two folders above",
                         source="PHOTOS", hint="pass --board COLSxROWS --square MM, or keep the photos in "
                         "DIR/captures of the folder 'lenticalib camera patterns' wrote")
    return read_board(manifest), manifest


def run_calibrate(args: argparse.Namespace) -> int:
    import json
    import time

    from ..calib.intrinsics.report import REPORT_FILES, calibration_summary, summary_lines, write_report
    from ..calib.intrinsics.solve import check_lensmodel, import_mrcal
    from ..core.errors import InputError
    from ..core.outputs import check_output_file, check_output_folder, staged_folder
    from ._progress import progress_bar

    start = time.perf_counter()
    if not 1 <= args.jobs <= 64:
        raise InputError(f"{args.jobs} jobs is out of range", source="--jobs", hint="use 1..64 (the number of cores)")
    if args.lensmodel is not None:
        check_lensmodel(args.lensmodel)
    output = check_output_file(args.output, "camera model", example="camera.cameramodel")
    if args.report is not None:
        check_output_folder(args.report, "calibration report", REPORT_FILES)
    photos = collect_photos(args.photos)
    board, manifest = _board(args, photos)
    if len(photos) < MIN_VIEWS:
        raise InputError(f"only {len(photos)} photos given; at least {MIN_VIEWS} views of the board are needed",
                         source="PHOTOS", hint=TOO_FEW_HINT)
    sizes = {p: photo_size(p) for p in photos}
    size = sizes[photos[0]]
    for p, s in sizes.items():
        if s != size:
            raise InputError(f"is {s[0]}x{s[1]} pixels, the first photo {size[0]}x{size[1]}", source=str(p),
                             hint="calibrate photos of one camera at one resolution and zoom")
    import_mrcal()

    import numpy as np

    from ..calib.intrinsics.corners import detect_photos
    from ..calib.intrinsics.quality import quality
    from ..calib.intrinsics.solve import calibrate, write_cameramodel

    with progress_bar(len(photos), "finding corners") as bar:
        found = detect_photos(photos, board, jobs=args.jobs, progress=bar.update)
    used = [f for f in found if f.corners is not None]
    if len(used) < MIN_VIEWS:
        raise InputError(f"the board was found in {len(used)} of {len(photos)} photos; at least {MIN_VIEWS} are needed",
                         source="PHOTOS", hint=f"check the board ({board.describe()}) is wholly in the photos and "
                         f"sharp, and {TOO_FEW_HINT}")
    corners = np.stack([f.corners for f in used])
    with progress_bar(3, "solving") as bar:
        cal = calibrate(corners, board, size, lensmodel=args.lensmodel, progress=lambda m: bar.update(m))
    model = cal.cameramodel()
    from ..calib.intrinsics.crossval import cross_validation

    with progress_bar(1, "cross-validating") as bar:
        check = cross_validation(corners, board, size, cal.lensmodel)
        bar.update()
    qual = quality(model, cal.solve, [f.path for f in used], cross_validation=check)
    summary = calibration_summary(cal, qual, board, found, photos, output=output, report=args.report,
                                  manifest=manifest, seconds=time.perf_counter() - start)
    write_cameramodel(model, output, note=summary["note"])
    if args.report is not None:
        with staged_folder(args.report, "calibration report", REPORT_FILES) as stage:
            write_report(stage, cal, qual, summary)
    if args.json:
        print(json.dumps(summary))
    else:
        print("\n".join(summary_lines(summary)))
    return 0
