"""``lenticalib capture``: show each calibration pattern on the panel and photograph it.

Checked before anything is shown: the pattern folder and its manifest, the captures folder
(writable, no foreign files), the display and monitor (its mode must be the panel's size),
and the camera (it must open).  Then every pattern is shown, photographed and checked at
once; a failing photo is retaken; an interrupted run resumes.  The set is then ready for
``lenticalib fit DIR``.
"""

from __future__ import annotations

import argparse

from ..core.terminal_text import safe_line


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("directory", metavar="DIR", help="pattern folder written by 'lenticalib patterns'")
    parser.add_argument("--camera", required=True, metavar="KIND",
                        help="gphoto2[:PORT] (USB-tethered camera), opencv:INDEX (webcam), manual[:FOLDER] "
                             "(you press the shutter; FOLDER is watched for each new photo), sim[:SEED] "
                             "(the virtual panel is the camera; for crosstalk patterns, the virtual panel their "
                             "profile was fitted on)")
    parser.add_argument("--display", metavar="SPEC",
                        help="monitor: index, @X,Y or part of its name (default: the one whose mode is the "
                             "panel's size; for --camera sim: offscreen, or 'none' for no graphics)")
    parser.add_argument("--settle", type=float, metavar="S",
                        help="seconds between showing a pattern and triggering (default 0.5; sim 0)")
    parser.add_argument("--retakes", type=int, default=2, help="retakes of a failing photo before stopping (default 2)")
    parser.add_argument("--restart", action="store_true", help="take every photo again (the old ones go to rejected/)")
    parser.add_argument("--timeout", type=float, default=600.0, metavar="S",
                        help="manual camera with a folder: how long to wait for each photo (default 600)")
    parser.add_argument("--resolution", metavar="WxH",
                        help="sim camera resolution (default the same as 'lenticalib simulate': 4000x3000)")
    parser.add_argument("--conditions", choices=("standard", "hard"), default="standard",
                        help="sim camera behaviour (hard: phone-like tone curve, exposure drift, shake, noise)")
    parser.add_argument("--subsamples", type=int, metavar="K",
                        help="sim camera: rays per sensor pixel side, K x K per pixel, 1..16 (default 3; 1 is about "
                             "five times faster and only aliases more)")
    parser.add_argument("--layout", metavar="NAME|FILE",
                        help="sim panel's subpixel layout: RGB, BGR, lkg-columns, lkg-checker, lkg-rows4 or a JSON "
                             "layout file (default: the seed's RGB or BGR stripe)")
    parser.set_defaults(run=run, flags={"camera": "--camera", "display": "--display", "layout": "--layout"})  # library names -> flags


def run(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    from ..calib.acquire import capture_set, wait_for_key
    from ..calib.cameras import make_camera
    from ..core.pattern_sets import read_pattern_folder
    from ..core.errors import DisplayError, InputError
    from ..render.present import open_presenter
    from ._progress import progress_bar

    if args.settle is not None and not 0 <= args.settle <= 60:
        raise InputError(f"{args.settle} seconds is out of range", source="--settle", hint="use 0..60")
    if not 0 <= args.retakes <= 20:
        raise InputError(f"{args.retakes} is out of range", source="--retakes", hint="use 0..20")
    directory = Path(args.directory)
    pattern_set = read_pattern_folder(directory)
    size = (pattern_set.width, pattern_set.height)
    kind = args.camera.split(":", 1)[0]
    display = args.display if args.display is not None else ("offscreen" if kind == "sim" else None)
    settle = args.settle if args.settle is not None else (0.0 if kind == "sim" else 0.5)
    options = {"timeout": args.timeout}
    if kind == "sim":
        options.update(resolution=None if args.resolution is None else _resolution(args.resolution),
                       conditions=args.conditions, folder=directory)  # the folder's virtual panel, named below
        if args.layout is not None:
            options["layout"] = args.layout
        if args.subsamples is not None:
            options["subsamples"] = args.subsamples
    elif args.layout is not None:
        raise InputError("applies only to --camera sim", source="--layout",
                         hint="a real panel's layout is what it is; drop --layout")
    elif args.subsamples is not None:
        raise InputError("applies only to --camera sim", source="--subsamples",
                         hint="a real camera takes one photo per pattern; drop --subsamples")
    if kind == "manual" and ":" not in args.camera:
        options["wait_for_user"] = lambda name: wait_for_key(presenter, name)
    camera = make_camera(args.camera, **options)  # the spec and options checked; no hardware touched yet
    presenter = open_presenter(display, size)
    camera.open()
    with camera:  # the camera first: a camera that will not open fails before the panel goes full screen
        try:
            presenter.open()
        except DisplayError as exc:
            if args.display is None and kind == "sim":  # no OpenGL here: the virtual panel needs none
                print(f"note: {exc.message}; showing without graphics (--display none)")
                presenter = open_presenter("none", size)
                presenter.open()
            else:
                raise
        try:
            for line in camera.settings():
                print(f"camera: {safe_line(line)}")  # names and values the camera reports
            with progress_bar(len(pattern_set.patterns), "capturing") as bar:
                report = capture_set(directory, presenter, camera, settle=settle, retakes=args.retakes,
                                     restart=args.restart, progress=bar.update,
                                     notify=lambda message: print(f"note: {safe_line(message)}", file=sys.stderr))
        finally:
            presenter.close()
    retaken = sum(report.retakes.values())
    print(f"captured {len(report.taken)} photo(s), kept {len(report.kept)} from before, {retaken} retaken, "
          f"in {report.seconds:.1f} s: {directory / 'captures'}")
    if hasattr(pattern_set, "bands"):  # crosstalk patterns
        print(f"next: lenticalib crosstalk measure {directory} -o crosstalk.json --report crosstalk-report")
    else:
        print(f"next: lenticalib fit {directory} -o profile.json")
    return 0


def _resolution(text: str) -> tuple[int, int]:
    from ..core.sizes import MIN_CAMERA_SIDE, parse_size

    return parse_size(text, "--resolution", MIN_CAMERA_SIDE, example="4000x3000")
