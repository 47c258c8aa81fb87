"""``lenticalib crosstalk patterns|measure|check``: verify per-view crosstalk from photos.

    patterns --profile P -o DIR      the sweep patterns from a fitted profile (show/capture them
                                     like calibration patterns, from the fit's camera position)
    measure DIR -o crosstalk.json    the mixing matrix, the view cone, the derived figures with
                                     uncertainties, provenance; ``--report DIR`` the figures
    check crosstalk.json --max-adjacent A --max-system S --max-eye-pair E
                                     pass (exit 0) or fail (exit 1, one line per failure)

Every option and output path is checked before the long work; outputs are written atomically
(the report folder staged as a whole), so a failed run leaves earlier results as they were.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from ..core.terminal_text import safe_line


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="crosstalk_command", metavar="STEP")
    sub.required = True
    p = sub.add_parser("patterns", help="write the crosstalk patterns for a fitted profile",
                       description="write the crosstalk patterns (band sweeps, halves, black, white) for a profile")
    p.add_argument("--profile", required=True, metavar="P", help="the fitted profile (profile.json)")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for the patterns and patterns.json")
    p.add_argument("--sweep", type=float, metavar="PIXELS", help="columns over which a band sweeps through all "
                   "views (default: half the panel width, or 8 lenses per view if longer)")
    p.set_defaults(run=run_patterns)
    m = sub.add_parser("measure", help="measure the crosstalk from photos of the crosstalk patterns",
                       description="measure the mixing matrix and the view cone from DIR/captures/")
    m.add_argument("directory", metavar="DIR", help="folder from 'crosstalk patterns' with captures/")
    m.add_argument("--profile", metavar="P", help="the profile the patterns were drawn from (checked against "
                   "the patterns' own record)")
    m.add_argument("-o", "--output", required=True, metavar="FILE", help="crosstalk JSON to write")
    m.add_argument("--report", metavar="DIR", help="folder for the report figures")
    m.add_argument("--eye-separation", type=float, metavar="VIEWS",
                   help="eye separation of a viewer in views, for the eye-pair crosstalk")
    m.add_argument("--eye-separation-mm", type=float, metavar="MM",
                   help="eye separation in mm (typically 63-65), with --distance and --cone-angle")
    m.add_argument("--distance", type=float, metavar="MM", help="viewing distance for --eye-separation-mm")
    m.add_argument("--cone-angle", type=float, metavar="DEG", help="the panel's full view-cone angle in degrees "
                   "(data sheet), for --eye-separation-mm")
    m.add_argument("--photos", choices=("srgb", "linear"), default="srgb",
                   help="how the photos encode light: srgb (camera JPEGs, their tone curve measured from the "
                        "photos; default) or linear (16-bit from RAW)")
    m.add_argument("--force", action="store_true", help="measure photos that do not follow the profile's routing "
                   "(another panel photographed, or a wrong profile) anyway, instead of refusing them; the file's "
                   "provenance then says so, and why")
    m.add_argument("--json", action="store_true", help="print the crosstalk document")
    m.set_defaults(run=run_measure)
    c = sub.add_parser("check", help="pass/fail a crosstalk measurement against limits",
                       description="pass (exit 0) or fail (exit 1) a crosstalk.json against limits")
    c.add_argument("file", metavar="FILE", help="crosstalk.json from 'crosstalk measure'")
    c.add_argument("--max-adjacent", type=_fraction, metavar="A", help="limit of the adjacent crosstalk: light "
                   "from the two neighbouring views over the view's own light (fraction 0.9 or percent 90%%; above "
                   "100%% on a sheet whose views overlap)")
    c.add_argument("--max-system", type=_fraction, metavar="S", help="limit of the system crosstalk (IEC 62629): "
                   "light from all other views over the view's own light")
    c.add_argument("--max-eye-pair", type=_eye_pair_fraction, metavar="E", help="limit of the eye-pair crosstalk: light of the "
                   "other eye's view over the eye's own view's light")
    c.set_defaults(run=run_check)


def _fraction(text: str) -> float:
    value = text.strip()
    try:
        number = float(value[:-1]) / 100.0 if value.endswith("%") else float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a fraction (0.08) or a percentage (8%)") from None
    if not (math.isfinite(number) and 0.0 <= number <= 10.0):
        raise argparse.ArgumentTypeError(f"{text!r} is out of range (0..10, or 0%..1000%)")
    return number


def _eye_pair_fraction(text: str) -> float:
    """:func:`_fraction` for the eye-pair crosstalk, a few per cent at most on any panel: a bare number
    above 1 (``5``) is more likely 5 % than 500 %, so it must say which."""
    number = _fraction(text)
    if number > 1.0 and not text.strip().endswith("%"):
        raise argparse.ArgumentTypeError(f"{text!r} is ambiguous: write {text.strip()}% or {number / 100:g}")
    return number


def run_patterns(args: argparse.Namespace) -> int:
    from ..calib.capture.pattern_folders import write_crosstalk_pattern_folder
    from ..core.pattern_sets import MANIFEST_NAME
    from ..core.profile import load_profile
    from .shared.flags import flag_names
    from .shared.progress import progress_bar

    profile = load_profile(args.profile, "--profile")
    with progress_bar(0, "writing patterns") as bar, flag_names({"sweep": "--sweep"}):
        pattern_set = write_crosstalk_pattern_folder(profile, args.output, args.sweep, progress=bar.update,
                                                     progress_total=bar.set_total, inputs=[args.profile])
    folder = Path(args.output)
    print(f"wrote {len(pattern_set.patterns)} crosstalk patterns and {folder / MANIFEST_NAME} (set {pattern_set.set_id})")
    print(f"next: photograph them from the fit's camera position, without moving the camera "
          f"('lenticalib capture {args.output} --camera ...', or show each PNG and save captures/NAME.jpg); then "
          f"'lenticalib crosstalk measure {args.output} -o crosstalk.json --report crosstalk-report'")
    return 0


MEASURE_FLAGS = {"profile": "--profile", "report_dir": "--report DIR", "photos": "--photos",
                 "eye_separation_views": "--eye-separation VIEWS", "eye_separation_mm": "--eye-separation-mm MM",
                 "distance_mm": "--distance MM", "cone_angle_deg": "--cone-angle DEG", "force": "--force"}  # library names -> flags


def run_measure(args: argparse.Namespace) -> int:
    import sys

    from ..calib.crosstalk.pipeline import EyeSeparation, measure_crosstalk_set
    from ..calib.crosstalk.result import FIGURES, HEADLINE, OVER_100, describe_figure
    from ..render.compose.compensation import PREDICTION_BLACK_LIFT, predict_compensation
    from .shared.flags import flag_names
    from .shared.progress import progress_bar

    eye = EyeSeparation(views=args.eye_separation, mm=args.eye_separation_mm, distance_mm=args.distance,
                        cone_angle_deg=args.cone_angle)
    with progress_bar(0, "measuring") as bar, flag_names(MEASURE_FLAGS):
        run = measure_crosstalk_set(args.directory, args.output, profile=args.profile, report_dir=args.report,
                                    eye=eye, photos=args.photos, predict=predict_compensation,
                                    progress=bar.update, progress_total=bar.set_total, force=args.force)
    measurement, document, output, eye = run.measurement, run.document, run.output, run.eye_separation
    for warning in measurement.warnings:
        print(f"lenticalib: warning: {safe_line(warning)}", file=sys.stderr)
    if args.json:
        print(json.dumps(document, indent=2))
        return 0
    f = document["figures"]
    for key in HEADLINE:  # one line each: the figure, what it is, its value with 1-sigma
        if key not in f:
            continue
        line = describe_figure(key, f[key]["value"], f[key]["sigma"])
        print(line + (f", eyes {eye:.2f} views apart" if key == "eye_pair_crosstalk" else ""))
    if any(FIGURES[k][2] == "%" and v["value"] > 1.0 for k, v in f.items()):
        print(f"note: {OVER_100}")
    c = document["compensation_prediction"]
    print(f"pre-compensation (--compensate {output} --black-lift {PREDICTION_BLACK_LIFT:g}) would bring the views "
          f"seen at the zone centres from {c['mean_rms_without']:.4f} to {c['mean_rms_with']:.4f} RMS of the "
          f"intended (linear light 0..1), the system crosstalk of the resulting mixing from "
          f"{100 * c['residual_crosstalk_without']:.1f}% to {100 * c['residual_crosstalk_with']:.1f}%")
    print(f"wrote {output}" + (f" and the report {args.report}" if args.report else "")
          + f" ({measurement.seconds:.1f} s)")
    return 0


def run_check(args: argparse.Namespace) -> int:
    from ..calib.crosstalk.result import check_crosstalk, describe_figure, read_crosstalk
    from ..core.errors import InputError

    if args.max_adjacent is None and args.max_eye_pair is None and args.max_system is None:
        raise InputError("no limit given", source="crosstalk check",
                         hint="give --max-adjacent A, --max-system S and/or --max-eye-pair E")
    data = read_crosstalk(args.file)
    if args.max_eye_pair is not None and (data.get("figures", {}).get("eye_pair_crosstalk") or {}).get("value") is None:
        # a limit on a figure the file does not hold is the user's to fix, not the panel's failure
        raise InputError("has no eye-pair crosstalk: it was measured without an eye separation", source=args.file,
                         hint="measure again with --eye-separation VIEWS (or --eye-separation-mm, --distance and "
                              "--cone-angle), or leave out --max-eye-pair")
    failures = check_crosstalk(data, args.max_adjacent, args.max_eye_pair, args.max_system)
    for line in failures:
        print(f"FAIL {args.file}: {safe_line(line)}")
    if failures:
        return 1
    f = data["figures"]
    parts = [f"{describe_figure(key, f[key]['value'], definition=False)} <= {100 * limit:.2f}%"
             for key, limit in (("adjacent_crosstalk", args.max_adjacent), ("total_crosstalk", args.max_system),
                                ("eye_pair_crosstalk", args.max_eye_pair)) if limit is not None]
    print(f"PASS {args.file}: " + "; ".join(parts))
    return 0
