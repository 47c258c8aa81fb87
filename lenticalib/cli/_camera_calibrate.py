"""``lenticalib camera calibrate``: photos of a chessboard or ChArUco board -> an mrcal ``.cameramodel`` and a report.

The work, checks first, is :func:`lenticalib.calib.intrinsics.pipeline.calibrate_camera`; this
module parses the options, shows a progress bar per stage and prints the summary.
"""

from __future__ import annotations

import argparse


def add_calibrate_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("photos", nargs="+", metavar="PHOTOS", help="photos (.jpg, .jpeg, .png) or folders of them")
    parser.add_argument("-o", "--output", required=True, metavar="FILE", help="the camera model to write "
                        "(.cameramodel)")
    parser.add_argument("--board", metavar="COLSxROWS", help="inner corners of the board (default: from the "
                        "board.json next to the photos)")
    parser.add_argument("--charuco", metavar="COLSxROWS", help="a ChArUco board you already have: its squares "
                        "(as OpenCV's CharucoBoard counts them, e.g. 5x7), with --square, --marker and --dictionary")
    parser.add_argument("--square", type=float, metavar="MM", help="square size of the board in mm (with --board or "
                        "--charuco)")
    parser.add_argument("--marker", type=float, metavar="MM", help="side of the ChArUco markers in mm (with --charuco)")
    parser.add_argument("--dictionary", metavar="NAME", help="ArUco dictionary of the ChArUco board, OpenCV's name "
                        "(with --charuco; e.g. DICT_4X4_50, DICT_5X5_100, DICT_6X6_250)")
    parser.add_argument("--report", metavar="DIR", help="folder for the figures and summary.json")
    parser.add_argument("--lensmodel", metavar="NAME", help="force an mrcal lens model (default: chosen by the "
                        "data among LENSMODEL_OPENCV5, LENSMODEL_OPENCV8 and a splined model)")
    parser.add_argument("--jobs", type=int, default=2, metavar="N", help="photos processed in parallel (default 2)")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON instead of sentences")


FLAGS = {"photos": "PHOTOS", "board_corners": "--board COLSxROWS", "square_mm": "--square MM", "jobs": "--jobs",
         "lensmodel": "--lensmodel", "board_squares": "--charuco COLSxROWS", "marker_mm": "--marker MM",
         "dictionary": "--dictionary NAME"}  # the library's argument names, as this command's flags


def run_calibrate(args: argparse.Namespace) -> int:
    import json

    from ..calib.intrinsics.board import parse_charuco_squares, parse_squares
    from ..calib.intrinsics.pipeline import calibrate_camera
    from ..calib.intrinsics.report import summary_lines
    from .shared.flags import flag_names
    from .shared.progress import staged_bars

    corners = parse_squares(args.board, "--board") if args.board is not None else None
    squares = parse_charuco_squares(args.charuco, "--charuco") if args.charuco is not None else None
    with staged_bars() as stage, flag_names(FLAGS):
        run = calibrate_camera(args.photos, args.output, board_corners=corners, square_mm=args.square,
                               report_dir=args.report, lensmodel=args.lensmodel, jobs=args.jobs, stage=stage,
                               board_squares=squares, marker_mm=args.marker, dictionary=args.dictionary)
    if args.json:
        print(json.dumps(run.summary))
    else:
        print("\n".join(summary_lines(run.summary)))
    return 0
