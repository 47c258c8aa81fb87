"""``lenticalib profile show|validate|import-lkg|export-lkg|compare|set-direction|set-physical|retarget``."""

from __future__ import annotations

import argparse
import json
import sys

from ..core.terminal_text import safe_line
from ..core.terminal_text import terminal_safe as shown  # text a profile or a visual.json holds


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
    imp.add_argument("--views", type=int, metavar="N",
                     help="number of views (a visual.json does not record it; default: the views of the quilt "
                          "Looking Glass renders for the model its serial names, 48 on a Portrait)")
    imp.add_argument("-o", "--output", required=True, metavar="PROFILE")
    imp.add_argument("--json", action="store_true", help="print a JSON summary instead of the constants")
    imp.set_defaults(run=run_import)
    exp = sub.add_parser("export-lkg", help="write a profile as a Looking Glass visual.json")
    exp.add_argument("profile", metavar="PROFILE")
    exp.add_argument("--dpi", type=float, help="panel pixels per inch (if the profile does not record it)")
    exp.add_argument("-o", "--output", required=True, metavar="VISUAL_JSON")
    exp.set_defaults(run=run_export, flags={"dpi": "--dpi"})  # the library's names
    cmp_ = sub.add_parser("compare", help="how far profile A is from profile B, in views, over every subpixel",
                          description="How far profile A is from profile B, in views, over every subpixel, and "
                                      "whether they agree (the same view on at least 90%% of the subpixels). "
                                      "Either may be a Looking Glass visual.json (with the other's number of "
                                      "views): a unit's calibration against the layout 'fit --cells' measured.")
    cmp_.add_argument("profile", metavar="A", help="a profile, or a Looking Glass visual.json")
    cmp_.add_argument("reference", metavar="B", help="the reference (e.g. a simulation's truth.json, or a fitted "
                                                     "profile), or a Looking Glass visual.json")
    cmp_.add_argument("--json", action="store_true", help="print JSON")
    cmp_.set_defaults(run=run_compare)
    direction = sub.add_parser("set-direction", help="record which way the profile's views run (+1, -1 or unknown)",
                               description="Record which way the view index runs for a viewer facing the panel: "
                                           "+1 when a viewer moving right sees RIGHT on the pattern of "
                                           "'lenticalib patterns --direction', -1 when they see LEFT.")
    direction.add_argument("profile", metavar="PROFILE")
    direction.add_argument("direction", metavar="+1|-1|unknown")
    direction.set_defaults(run=run_set_direction)
    physical = sub.add_parser("set-physical", help="record the panel's physical constants from a data sheet",
                              description="Write the profile's physical block (docs/physical.md) from a data "
                                          "sheet: what 'profile retarget' needs is the pixel pitch, the gap (or the "
                                          "view-cone angle and lens pitch) and the eye the constants are for.")
    physical.add_argument("profile", metavar="PROFILE")
    physical.add_argument("--pixel-pitch", type=float, metavar="MM", help="pixel pitch, mm")
    physical.add_argument("--gap", type=float, metavar="MM", help="effective lens-to-pixel gap, mm")
    physical.add_argument("--lens-pitch", type=float, metavar="MM", help="horizontal lens pitch, mm")
    physical.add_argument("--view-cone", type=float, metavar="DEG", help="full view-cone angle in air, degrees "
                          "(gives the gap with --lens-pitch)")
    physical.add_argument("--design-distance", type=float, metavar="MM", help="the viewing distance the profile's "
                          "constants are for, when no eye position is recorded (a centred viewer)")
    physical.set_defaults(run=run_set_physical)
    retarget = sub.add_parser("retarget", help="the routing constants for a viewer at another distance/position",
                              description="Carry a profile to another eye position: the period and offset a viewer "
                                          "at --distance (and --lateral/--vertical) needs.  Needs the profile's "
                                          "physical block with the gap (lenticalib fit --camera ... "
                                          "--second-distance, or profile set-physical).")
    retarget.add_argument("profile", metavar="PROFILE")
    retarget.add_argument("--distance", type=float, required=True, metavar="MM",
                          help="the viewer's distance from the panel surface, mm")
    retarget.add_argument("--lateral", type=float, default=0.0, metavar="MM",
                          help="the viewer's position right of the panel centre, mm (default 0)")
    retarget.add_argument("--vertical", type=float, default=0.0, metavar="MM",
                          help="the viewer's eye height below the panel centre, mm (default 0; above: negative)")
    retarget.add_argument("-o", "--output", required=True, metavar="PROFILE2")
    retarget.add_argument("--json", action="store_true", help="print the new profile's JSON")
    retarget.set_defaults(run=run_retarget)


def _print_profile(profile) -> None:
    """The constants of ``profile``, one per line with units and 1-sigma (``profile show``)."""
    from ..core.profile import describe_provenance, format_constant
    from ..core.view_direction import describe_direction

    unc = profile.uncertainty or {}
    rows = [("views", profile.views, ""), ("slant", profile.slant, "pixels/row"),
            ("period", profile.period, "subpixels"), ("offset", profile.offset, "subpixels"),
            ("reference_view", profile.reference_view, "views"),
            ("panel", f"{profile.width}x{profile.height}", "pixels"), ("subpixel_order", profile.subpixel_order, "")]
    if profile.subpixel_layout is not None:
        rows[-1] = ("subpixel_layout", profile.layout_name, "")
    for name, value, unit in rows:
        sigma = f" +- {unc[name]:.3g}" if name in unc else ""
        print(f"{name:>15}  {format_constant(name, value)}{sigma} {unit}".rstrip())
    if profile.subpixel_layout is not None:
        for index, cell in enumerate(profile.subpixel_layout.cells):
            where = ", ".join(f"{ch} ({dx:+.3f}, {dy:+.3f})" for ch, (dx, dy) in zip("RGB", cell))
            print(f"{'cell ' + str(index):>15}  {where} pixels from the pixel centre (x right, y down)")
        print(f"{'cell pattern':>15}  " + " / ".join(" ".join(map(str, row)) for row in profile.subpixel_layout.pattern)
              + "  (rows from the top, cell of column x % columns)")
    flags = [text for flag, text in ((profile.views_reversed, "view numbers reversed (Looking Glass invView = 0)"),
                                     (profile.flip_image_x, "views shown mirrored left-right"),
                                     (profile.flip_image_y, "views shown mirrored top-bottom")) if flag]
    if flags:
        print(f"{'routing':>15}  " + "; ".join(flags))
    how = (profile.provenance or {}).get("view_direction")
    how = (f"; {shown(how['method'])}" + (f" on {shown(how['set'])}" if how.get("set") else "")
           if isinstance(how, dict) and how.get("method") and profile.view_direction is not None else "")
    print(f"{'view_direction':>15}  {describe_direction(profile.view_direction)}{how}")
    phys = profile.physical or {}
    if phys:
        parts = [f"{k} {v:g}" for k, v in phys.items() if isinstance(v, float)]
        if phys.get("eye_mm"):
            parts.append("eye_mm [" + ", ".join(f"{v:.1f}" for v in phys["eye_mm"]) + "]")
        print(f"{'physical':>15}  " + ", ".join(parts) + (f" ({shown(phys['source'])})" if phys.get("source") else ""))
    if profile.provenance and set(profile.provenance) - {"view_direction"}:
        for label, line in zip(("made by", "from"), describe_provenance(profile.provenance)):
            print(f"{label:>15}  {safe_line(line)}")  # the file's own words: method, dates, device, serial


def run_show(args) -> int:
    from ..core.profile import load_profile

    profile = load_profile(args.profile, "PROFILE")
    if args.json:
        print(profile.to_json(), end="")
        return 0
    _print_profile(profile)
    return 0


def run_validate(args) -> int:
    from ..core.profile import load_profile

    profile = load_profile(args.profile, "PROFILE")
    print(f"{shown(args.profile)}: valid ({profile.views} views, {profile.width}x{profile.height})")
    return 0


def run_import(args) -> int:
    from ..core.errors import InputError
    from ..core.looking_glass.convert import import_visual_json, read_visual_json
    from ..core.files.outputs import check_output_file
    from ..core.profile import MAX_VIEWS, save_profile
    from ..core.view_defaults import default_views

    if args.views is not None and not 2 <= args.views <= MAX_VIEWS:
        raise InputError(f"must be between 2 and {MAX_VIEWS}, got {args.views}", source="--views")
    check_output_file(args.output, "profile", example="profile.json", inputs=[args.visual])
    views = args.views if args.views is not None else default_views(read_visual_json(args.visual))
    if views is None:
        raise InputError(f"{args.visual} does not say how many views the quilts have, and its serial names no "
                         "model whose quilt lenticalib knows", source="--views", hint="give it, e.g. --views 45")
    profile = import_visual_json(args.visual, views)
    save_profile(profile, args.output)
    for note in (profile.provenance or {}).get("assumptions", []):
        print(f"lenticalib: warning: {safe_line(f'{args.visual}: {note}')}", file=sys.stderr)
    if args.json:
        print(json.dumps({"output": args.output, "period": profile.period, "slant": profile.slant,
                          "offset": profile.offset, "reference_view": profile.reference_view}))
        return 0
    print(f"wrote {args.output} from {args.visual} ({views} views):")
    _print_profile(profile)
    return 0


def run_export(args) -> int:
    from ..core.looking_glass.convert import export_visual_json
    from ..core.files.outputs import check_output_file
    from ..core.profile import load_profile

    profile = load_profile(args.profile, "PROFILE")
    check_output_file(args.output, "visual.json", example="visual.json", inputs=[args.profile])
    export_visual_json(profile, args.output, dpi=args.dpi)
    if profile.view_direction is None:
        print(f"lenticalib: warning: {args.profile}: view_direction is unknown; the visual.json says invView = 1 "
              "(view index growing to the viewer's right, as on every Looking Glass)", file=sys.stderr)
    print(f"wrote {args.output}")
    return 0


def run_compare(args) -> int:
    from ..calib.routing.compare import AGREE_FRACTION, compare_profiles, load_pair

    a, b = load_pair(args.profile, args.reference)
    diff = compare_profiles(a, b)
    # True/False when both profiles know their direction, None when either does not
    direction_match = (None if a.view_direction is None or b.view_direction is None
                       else a.view_direction == b.view_direction)
    if args.json:
        out = diff.to_dict()
        out.update({"agree": diff.agree, "period_error": a.period - b.period, "slant_error": a.slant - b.slant,
                    "view_direction": [a.view_direction, b.view_direction],
                    "view_direction_match": direction_match})
        print(json.dumps(out))
        return 0
    print(f"{shown(args.profile)} against {shown(args.reference)}, w - w_ref over {diff.subpixels} subpixels:")
    verdict = ("they agree" if diff.agree else
               f"they DISAGREE (another rule or calibration; one panel's descriptions agree on at least "
               f"{AGREE_FRACTION:.0%})")
    print(f"  same view       {diff.same_view:.2%} of the subpixels: {verdict}")
    print(f"  non-uniformity  {diff.rms:.4f} views RMS, {diff.worst:.4f} views worst")
    print(f"  centring        {diff.centring:+.4f} views")
    print(f"  period          {a.period:.6f} vs {b.period:.6f} subpixels ({a.period - b.period:+.2e})")
    print(f"  slant           {a.slant:.7f} vs {b.slant:.7f} pixels/row ({a.slant - b.slant:+.2e})")
    print(f"  subpixel order  {shown(a.layout_name)} vs {shown(b.layout_name)}"
          f"{'' if diff.order_match else '  MISMATCH'}")
    note = {True: "", False: "  MISMATCH (one of them shows inverted depth)",
            None: "  (not compared: unknown)"}[direction_match]
    print(f"  view direction  {_direction_text(a.view_direction)} vs {_direction_text(b.view_direction)}{note}")
    return 0


def _direction_text(direction) -> str:
    return {1: "+1", -1: "-1"}.get(direction, "unknown")


def run_set_direction(args) -> int:
    from ..core.profile import load_profile, save_profile
    from ..core.view_direction import describe_direction, parse_direction, with_direction

    direction = parse_direction(args.direction, "DIRECTION")  # before the file is read
    profile = load_profile(args.profile, "PROFILE")
    updated = with_direction(profile, direction, "set by hand (lenticalib profile set-direction)",
                             previous=profile.view_direction)
    save_profile(updated, args.profile)  # atomic: the old file stays whole if this fails
    print(f"{args.profile}: view_direction {describe_direction(direction)}"
          + ("" if profile.view_direction == direction else
             f" (was {_direction_text(profile.view_direction)})"))
    return 0


def run_set_physical(args) -> int:
    from ..core.errors import InputError
    from ..core.physical import with_data_sheet
    from ..core.profile import load_profile, save_profile

    given = {"pixel_pitch_mm": args.pixel_pitch, "gap_mm": args.gap, "lens_pitch_mm": args.lens_pitch,
             "view_cone_deg": args.view_cone, "design_distance_mm": args.design_distance}
    if all(v is None for v in given.values()):  # before the file is read
        raise InputError("nothing to set", source="set-physical",
                         hint="give --pixel-pitch, --gap, --lens-pitch, --view-cone or --design-distance")
    profile = load_profile(args.profile, "PROFILE")
    block = with_data_sheet(profile.physical, profile.slant, "set-physical", **given)  # names physical.FIELD
    save_profile(profile.replace(physical=block), args.profile)
    print(f"{args.profile}: physical " + ", ".join(f"{k} {v:g}" for k, v in block.items() if isinstance(v, float)))
    return 0


def run_retarget(args) -> int:
    from ..core.files.outputs import check_output_file
    from ..core.profile import format_constant, load_profile, save_profile
    from ..core.retarget import Eye, calibration_eye, retarget_profile, routing_difference
    from .shared.flags import flag_names

    eye = Eye.parse((args.lateral, args.vertical, args.distance), "--distance")
    output = check_output_file(args.output, "profile", example="profile-900mm.json", inputs=[args.profile])
    profile = load_profile(args.profile, "PROFILE")
    fix = {"design_distance_mm": f"'lenticalib profile set-physical {args.profile} --design-distance MM'"}
    with flag_names(fix):  # the library names with_data_sheet's argument; set-physical sets it
        new = retarget_profile(profile, eye, source=args.profile)
    save_profile(new, output)
    if args.json:
        print(new.to_json(), end="")
        return 0
    old = calibration_eye(profile)
    unc = new.uncertainty or {}
    print(f"from the eye at ({old.x:+.1f}, {old.y:+.1f}, {old.distance:.1f}) mm to ({eye.x:+.1f}, {eye.y:+.1f}, "
          f"{eye.distance:.1f}) mm:")
    for name in ("period", "offset"):
        sigma = f" +- {unc[name]:.2g}" if name in unc else ""
        print(f"{name:>8}  {format_constant(name, getattr(profile, name))} -> "
              f"{format_constant(name, getattr(new, name))}{sigma} subpixels")
    print(f"the routing moves by up to {routing_difference(profile, new):.2f} views on the panel")
    print(f"wrote {output}")
    return 0
