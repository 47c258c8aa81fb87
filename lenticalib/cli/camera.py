"""``lenticalib camera``: calibrate the camera (its intrinsics, with mrcal) from photos of a board.

    lenticalib camera patterns -o DIR (--profile P | --panel WxH --pixel-pitch MM) [--board charuco]
        DIR/board.png (the board as a panel raster), DIR/board.json, DIR/print/board-print.pdf
        and .png (a board to print, with its own DIR/print/board.json); a chessboard, or a
        ChArUco board (markers identify every corner, so the board may run off the photo)
    lenticalib camera calibrate PHOTOS... -o camera.cameramodel [--report DIR]
        corners, mrcal solve, camera model, report; the board comes from the board.json next
        to the photos (DIR/captures/*.jpg -> DIR/board.json), --board/--square (a chessboard) or
        --charuco/--square/--marker/--dictionary (a ChArUco board)
    lenticalib camera simulate DIR [--board charuco]
        a synthetic set: DIR/captures/board-NN.jpg photographed by a known camera, with
        DIR/truth.cameramodel and the true board poses in DIR/simulation.json

Every user error ends as one line before the long work (detection, solve, rendering) starts.
See ``docs/camera.md``.
"""

from __future__ import annotations

import argparse


PATTERNS = ("chessboard", "charuco")  # lenticalib.calib.intrinsics.board.PATTERNS (not imported: --help stays instant)



def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="camera_command", metavar="SUBCOMMAND")
    sub.required = True
    text = "write the calibration board: a panel raster to show, and a sheet to print"
    p = sub.add_parser("patterns", help=text, description=text)
    p.add_argument("--board", choices=PATTERNS, default="chessboard", dest="pattern",
                   help="'chessboard' (default): a photo may show part of it (a block of at least 3 x 3 inner "
                        "corners); 'charuco': ArUco markers in the white squares identify every corner, so any "
                        "part of the board with a few markers counts")
    p.add_argument("--dictionary", metavar="NAME", help="ArUco dictionary of a ChArUco board (default: the smallest "
                   "4x4 one that holds its markers, e.g. DICT_4X4_100)")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for board.png, board.json and print/")
    p.add_argument("--profile", metavar="P", help="the panel's profile (size; pixel pitch from its physical block)")
    p.add_argument("--panel", metavar="WxH", help="panel raster size in pixels (instead of --profile)")
    p.add_argument("--pixel-pitch", type=float, metavar="MM", help="panel pixel pitch in mm (data sheet)")
    p.add_argument("--lens-pitch", type=float, metavar="MM", help="the lens sheet's horizontal lens pitch in mm (data "
                   "sheet), when no --profile gives it: the squares' soft edges then span at least two lenses")
    p.add_argument("--squares", metavar="COLSxROWS", help="inner corners of the panel board (default: 9 squares "
                   "down the short side, square squares; one count odd, one even)")
    p.add_argument("--print-square", type=float, default=20.0, metavar="MM",
                   help="square size of the printable board in mm (default 20)")
    p.add_argument("--paper", choices=("A4", "letter"), default="A4", help="paper of the printable board (landscape)")
    p.set_defaults(run=run_patterns)

    text = "calibrate the camera from photos of the board (mrcal): a .cameramodel and a report"
    c = sub.add_parser("calibrate", help=text, description=text)
    add_calibrate_arguments(c)
    c.set_defaults(run=run_calibrate)

    text = "photograph a board with a known virtual camera (a synthetic calibration set with its truth)"
    s = sub.add_parser("simulate", help=text, description=text)
    s.add_argument("directory", metavar="DIR", help="folder to write (new, or one this command wrote before)")
    s.add_argument("--seed", type=int, metavar="N", help="seed of the camera, panel, poses and noise "
                   "(default: a fresh one, recorded in simulation.json)")
    s.add_argument("--photos", type=int, default=24, metavar="K", help="number of photos (default 24)")
    s.add_argument("--kind", choices=("panel", "print"), default="panel",
                   help="'panel': the board shown on a virtual panel, through its lens sheet; 'print': a printed "
                        "board (default panel)")
    s.add_argument("--resolution", default="1600x1200", metavar="WxH", help="camera resolution (default 1600x1200)")
    s.add_argument("--conditions", choices=("standard", "hard"), default="standard",
                   help="'hard': a phone's S-curve, exposure drift and high-ISO noise")
    s.add_argument("--subsamples", type=int, default=2, metavar="N", help="rays per pixel side, 1..8 (default 2)")
    s.add_argument("--board", choices=PATTERNS, default="chessboard", dest="pattern",
                   help="the board photographed: 'chessboard' (default), or 'charuco' (then about a third of the "
                        "photos show the board partly outside the frame)")
    s.add_argument("--json", action="store_true", help="print a JSON summary instead of sentences")
    s.set_defaults(run=run_simulate)


FLAGS = {"pixel_pitch_mm": "--pixel-pitch", "lens_pitch_mm": "--lens-pitch", "resolution": "--resolution",
         "photos": "--photos", "subsamples": "--subsamples", "seed": "--seed", "kind": "--kind",
         "conditions": "--conditions", "squares": "--squares", "paper": "--paper",
         "square_mm": "--print-square", "dictionary": "--dictionary",
         "pattern": "--board", "profile": "--profile", "panel": "--panel"}  # the library's argument names


def run_patterns(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..calib.intrinsics.board import MANIFEST_NAME, PANEL_IMAGE, PRINT_FOLDER, PRINT_PDF, PRINT_PNG, parse_squares
    from ..calib.intrinsics.pipeline import board_panel, write_board_folder
    from .shared.flags import flag_names

    with flag_names(FLAGS):
        width, height, pitch, lens_px = board_panel(args.profile, args.panel, args.pixel_pitch)
    squares = parse_squares(args.squares, "--squares") if args.squares else None
    if args.dictionary is not None and args.pattern != "charuco":
        from ..core.errors import InputError

        raise InputError("applies to a ChArUco board only", source="--dictionary", hint="add --board charuco")
    with flag_names(FLAGS):
        board, sheet = write_board_folder(args.output, width, height, pitch, squares=squares,
                                          lens_pitch_mm=args.lens_pitch, lens_pitch_px=lens_px,
                                          print_square_mm=args.print_square, paper=args.paper,
                                          pattern=args.pattern, dictionary=args.dictionary, inputs=[args.profile])
    out = Path(args.output)
    markers = (f", {board.dictionary} markers of {board.marker_px} px = {board.marker_mm:.4f} mm"
               if board.charuco else "")
    print(f"wrote {out / PANEL_IMAGE} ({width}x{height}: {board.cols}x{board.rows} inner corners, squares of "
          f"{board.square_px} px = {board.square_mm:.4f} mm{markers}, edges {board.edge_px} px) and "
          f"{out / MANIFEST_NAME}")
    markers = f", {sheet.dictionary} markers of {sheet.marker_mm:g} mm" if sheet.charuco else ""
    print(f"wrote {out / PRINT_FOLDER / PRINT_PDF} and {PRINT_PNG} ({sheet.cols}x{sheet.rows} inner corners, "
          f"{sheet.square_mm:g} mm squares{markers} on {args.paper}; print at 100 % and check the 100 mm bar)")
    reach = "the board reaching the image corners and edges (it may run off them)"
    print(f"next: 'lenticalib show {out / PANEL_IMAGE}', photograph the panel 15-30 times from varied, tilted "
          f"views with {reach}, save the photos in {out / 'captures'}/, then "
          f"'lenticalib camera calibrate {out / 'captures'} -o camera.cameramodel --report camera-report'")
    return 0


def run_simulate(args: argparse.Namespace) -> int:
    import json

    from ..sim.board_set import CAPTURE_FOLDER, TRUTH_NAME
    from ..sim.simulate_folder import simulate_camera_set
    from .shared.flags import flag_names
    from .shared.progress import progress_bar

    from ..core.sizes import MIN_CAMERA_SIDE, parse_size

    resolution = parse_size(args.resolution, "--resolution", MIN_CAMERA_SIDE, example="1600x1200")
    with progress_bar(args.photos, "photographing") as bar, flag_names(FLAGS):
        done = simulate_camera_set(args.directory, kind=args.kind, seed=args.seed, photos=args.photos,
                                   resolution=resolution, conditions=args.conditions, subsamples=args.subsamples,
                                   progress=bar.update, pattern=args.pattern)
    doc, seed, seconds = done.summary, done.seed, done.seconds
    if args.json:
        print(json.dumps({"directory": str(args.directory), "kind": args.kind, "seed": seed, "photos": args.photos,
                          "resolution": list(resolution), "seconds": seconds,
                          "seconds_per_photo": doc["seconds_per_photo"], "truth": f"{args.directory}/{TRUTH_NAME}"}))
        return 0
    cam = doc["camera"]
    what = "ChArUco board (some partly outside the frame)" if args.pattern == "charuco" else "board"
    print(f"wrote {args.photos} photos of a {args.kind} {what} to {args.directory}/{CAPTURE_FOLDER} "
          f"({resolution[0]}x{resolution[1]}, seed {seed}, {doc['seconds_per_photo']:.2f} s per photo)")
    print(f"truth: {args.directory}/{TRUTH_NAME} (fx {cam['fx']:.2f}, fy {cam['fy']:.2f}, cx {cam['cx']:.2f}, "
          f"cy {cam['cy']:.2f} px; k1 k2 p1 p2 k3 {', '.join(f'{v:.5f}' for v in cam['distortion'])}); the board "
          "poses are in simulation.json")
    print(f"next: lenticalib camera calibrate {args.directory}/{CAPTURE_FOLDER} -o {args.directory}/camera.cameramodel "
          f"--report {args.directory}/report")
    return 0


# ------------------------------------------------------------------ camera calibrate
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


CALIBRATE_FLAGS = {"photos": "PHOTOS", "board_corners": "--board COLSxROWS", "square_mm": "--square MM", "jobs": "--jobs",
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
    with staged_bars() as stage, flag_names(CALIBRATE_FLAGS):
        run = calibrate_camera(args.photos, args.output, board_corners=corners, square_mm=args.square,
                               report_dir=args.report, lensmodel=args.lensmodel, jobs=args.jobs, stage=stage,
                               board_squares=squares, marker_mm=args.marker, dictionary=args.dictionary)
    if args.json:
        print(json.dumps(run.summary))
    else:
        print("\n".join(summary_lines(run.summary)))
    return 0
