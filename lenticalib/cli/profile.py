"""``lenticalib profile show|validate|import-lkg|export-lkg|compare``."""

from __future__ import annotations

import argparse
import json


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="profile_command", metavar="ACTION")
    sub.required = True
    show = sub.add_parser("show", help="print a profile's constants")
    show.add_argument("profile", metavar="PROFILE")
    show.add_argument("--json", action="store_true", help="print the normalized JSON")
    show.set_defaults(run=run_show)
    validate = sub.add_parser("validate", help="check a profile; exit 0 when it is valid")
    validate.add_argument("profile", metavar="PROFILE")
    validate.set_defaults(run=run_validate)
    imp = sub.add_parser("import-lkg", help="convert a Looking Glass visual.json into a profile")
    imp.add_argument("visual", metavar="VISUAL_JSON")
    imp.add_argument("--views", type=int, required=True, metavar="N",
                     help="number of views (a visual.json does not record it)")
    imp.add_argument("-o", "--output", required=True, metavar="PROFILE")
    imp.add_argument("--json", action="store_true", help="print a JSON summary instead of the constants")
    imp.set_defaults(run=run_import)
    exp = sub.add_parser("export-lkg", help="write a profile as a Looking Glass visual.json")
    exp.add_argument("profile", metavar="PROFILE")
    exp.add_argument("--dpi", type=float, help="panel pixels per inch (if the profile does not record it)")
    exp.add_argument("-o", "--output", required=True, metavar="VISUAL_JSON")
    exp.set_defaults(run=run_export)
    cmp_ = sub.add_parser("compare", help="how far profile A is from profile B, in views, over every subpixel")
    cmp_.add_argument("profile", metavar="A")
    cmp_.add_argument("reference", metavar="B", help="the reference (e.g. a simulation's truth.json)")
    cmp_.add_argument("--json", action="store_true", help="print JSON")
    cmp_.set_defaults(run=run_compare)


def _print_profile(profile) -> None:
    """The constants of ``profile``, one per line with units and 1-sigma (``profile show``)."""
    from ..profile import describe_provenance, format_constant

    unc = profile.uncertainty or {}
    rows = [("views", profile.views, ""), ("slant", profile.slant, "pixels/row"),
            ("period", profile.period, "subpixels"), ("offset", profile.offset, "subpixels"),
            ("reference_view", profile.reference_view, "views"),
            ("panel", f"{profile.width}x{profile.height}", "pixels"), ("subpixel_order", profile.subpixel_order, "")]
    for name, value, unit in rows:
        sigma = f" +- {unc[name]:.3g}" if name in unc else ""
        print(f"{name:>15}  {format_constant(name, value)}{sigma} {unit}".rstrip())
    if profile.provenance:
        for label, line in zip(("made by", "from"), describe_provenance(profile.provenance)):
            print(f"{label:>15}  {line}")


def run_show(args) -> int:
    from ..profile import load_profile

    profile = load_profile(args.profile, "PROFILE")
    if args.json:
        print(profile.to_json(), end="")
        return 0
    _print_profile(profile)
    return 0


def run_validate(args) -> int:
    from ..profile import load_profile

    profile = load_profile(args.profile, "PROFILE")
    print(f"{args.profile}: valid ({profile.views} views, {profile.width}x{profile.height})")
    return 0


def run_import(args) -> int:
    from ..errors import InputError
    from ..lkg import import_visual_json
    from ..outputs import check_output_file
    from ..profile import MAX_VIEWS, save_profile

    if not 2 <= args.views <= MAX_VIEWS:
        raise InputError(f"must be between 2 and {MAX_VIEWS}, got {args.views}", source="--views")
    check_output_file(args.output, "profile")
    profile = import_visual_json(args.visual, args.views)
    save_profile(profile, args.output)
    if args.json:
        print(json.dumps({"output": args.output, "period": profile.period, "slant": profile.slant,
                          "offset": profile.offset, "reference_view": profile.reference_view}))
        return 0
    print(f"wrote {args.output} from {args.visual} ({args.views} views):")
    _print_profile(profile)
    return 0


def run_export(args) -> int:
    from ..lkg import export_visual_json
    from ..outputs import check_output_file
    from ..profile import load_profile

    profile = load_profile(args.profile, "PROFILE")
    check_output_file(args.output, "visual.json")
    export_visual_json(profile, args.output, dpi=args.dpi)
    print(f"wrote {args.output}")
    return 0


def run_compare(args) -> int:
    from ..calib.compare import compare_profiles
    from ..profile import load_profile

    a, b = load_profile(args.profile, "A"), load_profile(args.reference, "B")
    diff = compare_profiles(a, b)
    if args.json:
        out = diff.to_dict()
        out.update({"period_error": a.period - b.period, "slant_error": a.slant - b.slant})
        print(json.dumps(out))
        return 0
    print(f"{args.profile} against {args.reference}, w - w_ref over {diff.subpixels} subpixels:")
    print(f"  non-uniformity  {diff.rms:.4f} views RMS, {diff.worst:.4f} views worst")
    print(f"  centring        {diff.centring:+.4f} views")
    print(f"  period          {a.period:.6f} vs {b.period:.6f} subpixels ({a.period - b.period:+.2e})")
    print(f"  slant           {a.slant:.7f} vs {b.slant:.7f} pixels/row ({a.slant - b.slant:+.2e})")
    print(f"  subpixel order  {a.subpixel_order} vs {b.subpixel_order}"
          f"{'' if diff.order_match else '  MISMATCH'}")
    return 0
