"""``lenticalib patterns``: write the calibration test patterns and their manifest."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--width", type=int, default=3840, help="panel raster width in pixels (default 3840)")
    parser.add_argument("--height", type=int, default=2160, help="panel raster height in pixels (default 2160)")
    parser.add_argument("--views", type=int, default=32, help="number of views (default 32)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for the PNGs and patterns.json")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..calib.patterns import design_patterns, write_patterns
    from ._progress import progress_bar

    pattern_set = design_patterns(args.width, args.height, args.views)
    with progress_bar(len(pattern_set.patterns), "writing patterns") as bar:
        manifest = write_patterns(args.output, pattern_set, progress=bar.wrap(pattern_set.patterns))
    print(f"wrote {len(pattern_set.patterns)} patterns and {manifest} (set {pattern_set.set_id})")
    print("next: show each PNG full screen on the panel, photograph it from the viewing position with the "
          f"camera on a tripod, and save the photos as {args.output}/captures/NAME.jpg; then run "
          f"'lenticalib fit {args.output} -o profile.json'")
    return 0
