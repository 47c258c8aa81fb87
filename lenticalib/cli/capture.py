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
    parser.set_defaults(run=run, flags={"camera": "--camera", "display": "--display", "layout": "--layout",
                                       "settle": "--settle", "retakes": "--retakes", "subsamples": "--subsamples"})  # library names -> flags


def run(args: argparse.Namespace) -> int:
    import contextlib
    import sys
    from pathlib import Path

    from ..calib.capture.guided import guided_capture
    from ..core.pattern_sets import read_pattern_folder
    from ..render.present.displays import open_presenter
    from .shared.flags import in_flags
    from .shared.progress import progress_bar

    directory = Path(args.directory)
    with contextlib.ExitStack() as stack:
        def started(count: int, settings: list[str]):
            for line in settings:
                print(f"camera: {safe_line(line)}")  # names and values the camera reports
            return stack.enter_context(progress_bar(count, "capturing")).update

        report = guided_capture(
            directory, args.camera, open_presenter, display=args.display, settle=args.settle, retakes=args.retakes,
            restart=args.restart, timeout=args.timeout,
            resolution=None if args.resolution is None else _resolution(args.resolution),
            conditions=args.conditions, subsamples=args.subsamples, layout=args.layout, on_start=started,
            notify=lambda message: print(f"note: {safe_line(message)}", file=sys.stderr),
            note=lambda message: print(f"note: {safe_line(in_flags(message, args.flags))}"))
    pattern_set = read_pattern_folder(directory)
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
