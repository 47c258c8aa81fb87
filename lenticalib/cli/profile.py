"""``lenticalib profile show|validate|import-lkg|export-lkg|compare|set-direction``."""

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
    direction = sub.add_parser("set-direction", help="record which way the profile's views run (+1, -1 or unknown)",
                               description="Record which way the view index runs for a viewer facing the panel: "
                                           "+1 when a viewer moving right sees RIGHT on the pattern of "
                                           "'lenticalib patterns --direction', -1 when they see LEFT.")
    direction.add_argument("profile", metavar="PROFILE")
    direction.add_argument("direction", metavar="+1|-1|unknown")
    direction.set_defaults(run=run_set_direction)


def _print_profile(profile) -> None:
    """The constants of ``profile``, one per line with units and 1-sigma (``profile show``)."""
    from ..profile import describe_provenance, format_constant
    from ..view_direction import describe_direction

    unc = profile.uncertainty or {}
    rows = [("views", profile.views, ""), ("slant", profile.slant, "pixels/row"),
            ("period", profile.period, "subpixels"), ("offset", profile.offset, "subpixels"),
            ("reference_view", profile.reference_view, "views"),
            ("panel", f"{profile.width}x{profile.height}", "pixels"), ("subpixel_order", profile.subpixel_order, "")]
    for name, value, unit in rows:
        sigma = f" +- {unc[name]:.3g}" if name in unc else ""
        print(f"{name:>15}  {format_constant(name, value)}{sigma} {unit}".rstrip())
    how = (profile.provenance or {}).get("view_direction")
    how = (f"; {how['method']}" + (f" on {how['set']}" if how.get("set") else "")
           if isinstance(how, dict) and how.get("method") and profile.view_direction is not None else "")
    print(f"{'view_direction':>15}  {describe_direction(profile.view_direction)}{how}")
    if profile.provenance and set(profile.provenance) - {"view_direction"}:
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
    if profile.view_direction is None:
        import sys

        print(f"lenticalib: warning: {args.profile}: view_direction is unknown; the visual.json says invView = 1 "
              "(view index growing to the viewer's right, as on every Looking Glass)", file=sys.stderr)
    print(f"wrote {args.output}")
    return 0


def run_compare(args) -> int:
    from ..calib.compare import compare_profiles
    from ..profile import load_profile

    a, b = load_profile(args.profile, "A"), load_profile(args.reference, "B")
    diff = compare_profiles(a, b)
    # True/False when both profiles know their direction, None when either does not
    direction_match = (None if a.view_direction is None or b.view_direction is None
                       else a.view_direction == b.view_direction)
    if args.json:
        out = diff.to_dict()
        out.update({"period_error": a.period - b.period, "slant_error": a.slant - b.slant,
                    "view_direction": [a.view_direction, b.view_direction],
                    "view_direction_match": direction_match})
        print(json.dumps(out))
        return 0
    print(f"{args.profile} against {args.reference}, w - w_ref over {diff.subpixels} subpixels:")
    print(f"  non-uniformity  {diff.rms:.4f} views RMS, {diff.worst:.4f} views worst")
    print(f"  centring        {diff.centring:+.4f} views")
    print(f"  period          {a.period:.6f} vs {b.period:.6f} subpixels ({a.period - b.period:+.2e})")
    print(f"  slant           {a.slant:.7f} vs {b.slant:.7f} pixels/row ({a.slant - b.slant:+.2e})")
    print(f"  subpixel order  {a.subpixel_order} vs {b.subpixel_order}"
          f"{'' if diff.order_match else '  MISMATCH'}")
    note = {True: "", False: "  MISMATCH (one of them shows inverted depth)",
            None: "  (not compared: unknown)"}[direction_match]
    print(f"  view direction  {_direction_text(a.view_direction)} vs {_direction_text(b.view_direction)}{note}")
    return 0


def _direction_text(direction) -> str:
    return {1: "+1", -1: "-1"}.get(direction, "unknown")


def run_set_direction(args) -> int:
    from ..profile import load_profile, save_profile
    from ..view_direction import describe_direction, parse_direction, with_direction

    direction = parse_direction(args.direction, "DIRECTION")  # before the file is read
    profile = load_profile(args.profile, "PROFILE")
    updated = with_direction(profile, direction, "set by hand (lenticalib profile set-direction)",
                             previous=profile.view_direction)
    save_profile(updated, args.profile)  # atomic: the old file stays whole if this fails
    print(f"{args.profile}: view_direction {describe_direction(direction)}"
          + ("" if profile.view_direction == direction else
             f" (was {_direction_text(profile.view_direction)})"))
    return 0
