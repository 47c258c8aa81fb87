"""``lenticalib patterns``: write the calibration test patterns and their manifest.

The options and the output folder are checked before the first pattern is drawn.  The folder
may be new (its parent must exist: no missing folders are created) or an existing one; the
pattern PNGs and ``patterns.json`` are all or nothing: a run that fails (or is interrupted)
puts the earlier ones back (or removes a folder it created), so a folder never holds patterns
of two sets.
"""

from __future__ import annotations

import argparse

MAX_SIDE = 16384  # panel raster pixels per side (16K panels)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--width", type=int, default=3840, help="panel raster width in pixels (default 3840)")
    parser.add_argument("--height", type=int, default=2160, help="panel raster height in pixels (default 2160)")
    parser.add_argument("--views", type=int, default=32, help="number of views (default 32)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for the PNGs and patterns.json")
    parser.set_defaults(run=run)


def check_options(args: argparse.Namespace) -> None:
    """InputError naming the option when the panel size or the view count is out of range."""
    from ..errors import InputError
    from ..profile import MAX_VIEWS

    for flag, value in (("--width", args.width), ("--height", args.height)):
        if not 64 <= value <= MAX_SIDE:
            raise InputError(f"{value} pixels is out of range", source=flag,
                             hint=f"give the panel raster size in pixels, 64..{MAX_SIDE}")
    if not 2 <= args.views <= MAX_VIEWS:
        raise InputError(f"{args.views} views is out of range", source="--views", hint=f"use 2..{MAX_VIEWS}")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..calib.patterns import MANIFEST_NAME, design_patterns, write_patterns
    from ..outputs import check_output_folder, restored_on_failure
    from ._progress import progress_bar

    check_options(args)
    folder = check_output_folder(args.output, "patterns")
    pattern_set = design_patterns(args.width, args.height, args.views)
    written = ([folder / p.file for p in pattern_set.patterns] + [folder / MANIFEST_NAME]
               if folder.exists() else [folder])
    with restored_on_failure(written, "patterns"), \
            progress_bar(len(pattern_set.patterns), "writing patterns") as bar:
        write_patterns(folder, pattern_set, progress=bar.wrap(pattern_set.patterns))
    manifest = Path(args.output) / MANIFEST_NAME
    print(f"wrote {len(pattern_set.patterns)} patterns and {manifest} (set {pattern_set.set_id})")
    print("next: show each PNG full screen on the panel, photograph it from the viewing position with the "
          f"camera on a tripod, and save the photos as {args.output}/captures/NAME.jpg; then run "
          f"'lenticalib fit {args.output} -o profile.json'")
    return 0
