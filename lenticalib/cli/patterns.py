"""``lenticalib patterns``: write the calibration test patterns and their manifest.

The options and the output folder are checked before the first pattern is drawn.  The folder
may be new (its parent must exist: no missing folders are created) or an existing one; the
pattern PNGs and ``patterns.json`` are all or nothing: a run that fails (or is interrupted)
puts the earlier ones back (or removes a folder it created), so a folder never holds patterns
of two sets.

``--direction --profile P -o DIR`` writes instead ``DIR/direction.png``: the panel raster of a
pattern whose views say LEFT (index < N/2) or RIGHT (index >= N/2), to find the profile's
``view_direction`` by looking (:mod:`lenticalib.calib.routing.direction`).
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--width", type=int, help="panel raster width in pixels (default 3840)")
    parser.add_argument("--height", type=int, help="panel raster height in pixels (default 2160)")
    parser.add_argument("--views", type=int, help="number of views (default 32)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for the PNGs and patterns.json")
    parser.add_argument("--direction", action="store_true",
                        help="write DIR/direction.png instead: views saying LEFT / RIGHT, encoded with --profile, "
                             "to see which way the views run")
    parser.add_argument("--profile", metavar="P", help="the panel profile (with --direction)")
    parser.add_argument("--cells", action="store_true",
                        help="also the 96 cell patterns (one colour in one of 8 pixel classes each, along x at "
                             "three periods and along y), from which 'fit' finds a subpixel layout that is not a "
                             "stripe (Looking Glass panels with subpixel cells)")
    parser.set_defaults(run=run)


DEFAULTS = {"width": 3840, "height": 2160, "views": 32}


def check_options(args: argparse.Namespace) -> None:
    """InputError naming the option when an option does not belong to the chosen mode (calibration
    patterns, or ``--direction``); the defaults filled in."""
    from ..core.errors import InputError

    if args.direction:
        if args.cells:
            raise InputError("is for the calibration patterns, not --direction", source="--cells", hint="leave it out")
        if args.profile is None:
            raise InputError("needs the panel's profile", source="--direction",
                             hint="e.g. lenticalib patterns --direction --profile profile.json -o check")
        for key in DEFAULTS:
            if getattr(args, key) is not None:
                raise InputError("is taken from the profile with --direction", source=f"--{key}",
                                 hint="leave it out")
        return
    if args.profile is not None:
        raise InputError("is used only with --direction", source="--profile",
                         hint="the calibration patterns need --width, --height and --views, not a profile")
    for key, value in DEFAULTS.items():
        if getattr(args, key) is None:
            setattr(args, key, value)


FLAGS = {"width": "--width", "height": "--height", "width/height": "--width/--height",
         "views": "--views"}  # the library's argument names


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..calib.capture.pattern_folders import write_calibration_patterns
    from ..core.pattern_sets import MANIFEST_NAME
    from .shared.flags import flag_names
    from .shared.progress import progress_bar

    check_options(args)
    if args.direction:
        return run_direction(args)
    with progress_bar(0, "writing patterns") as bar, flag_names(FLAGS):
        pattern_set = write_calibration_patterns(args.output, args.width, args.height, args.views, progress=bar.update,
                                                 progress_total=bar.set_total, cells=args.cells)
    manifest = Path(args.output) / MANIFEST_NAME
    print(f"wrote {len(pattern_set.patterns)} patterns and {manifest} (set {pattern_set.set_id})")
    print("next: show each PNG full screen on the panel, photograph it from the viewing position with the "
          f"camera on a tripod, and save the photos as {args.output}/captures/NAME.jpg; then run "
          f"'lenticalib fit {args.output} -o profile.json'")
    return 0


def run_direction(args: argparse.Namespace) -> int:
    """``--direction``: write DIR/direction.png and say how to read it."""
    from ..calib.capture.pattern_folders import write_direction_pattern
    from ..render.encoders import encode
    from ..core.profile import load_profile
    from ..core.view_direction import describe_direction

    profile = load_profile(args.profile, "--profile")
    target = write_direction_pattern(profile, args.output, encode, inputs=[args.profile])
    last_left = (profile.views - 1) // 2
    print(f"wrote {target} ({profile.width}x{profile.height}, {profile.views} views: views 0..{last_left} "
          f"say LEFT, the others RIGHT; the profile's view_direction is {describe_direction(profile.view_direction)})")
    print(f"next: 'lenticalib show {target}'; close one eye and look at the panel from a little (10-20 cm) "
          "to the RIGHT of where it was calibrated.  RIGHT: the views run left to right, "
          f"'lenticalib profile set-direction {args.profile} +1'.  LEFT: they run right to left, "
          f"'lenticalib profile set-direction {args.profile} -1'.")
    return 0
