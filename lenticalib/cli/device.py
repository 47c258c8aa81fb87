"""``lenticalib device list|info|read|flash|verify``: the calibration record in a panel controller,
and the factory calibration of a Looking Glass unit (list, info and read only: units are read-only)."""

from __future__ import annotations

import argparse
import json

from ..core.terminal_text import safe_line
from ..core.terminal_text import terminal_safe as shown  # what units, drives and controllers report


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="device_command", metavar="ACTION")
    sub.required = True
    lst = sub.add_parser("list", help="list connected controllers, Looking Glass units and emulators")
    lst.add_argument("--json", action="store_true", help="print JSON")
    lst.set_defaults(run=run_list)
    info = sub.add_parser("info", help="identify a controller and show its current record (a Looking Glass "
                                       "unit: its serial and calibration version)")
    info.add_argument("url", metavar="URL")
    info.add_argument("--json", action="store_true", help="print JSON")
    info.set_defaults(run=run_info)
    read = sub.add_parser("read", help="read the calibration record (or a Looking Glass unit's calibration) into "
                                       "a profile file")
    read.add_argument("url", metavar="URL")
    read.add_argument("-o", "--output", required=True, metavar="PROFILE")
    read.add_argument("--views", type=int, metavar="N",
                      help="number of quilt views of a Looking Glass unit (default: the views of the quilt Looking "
                           "Glass renders for its model, from the serial: 48 on a Portrait; a controller's record "
                           "holds its own)")
    read.set_defaults(run=run_read, flags={"views": "--views N"})
    flash = sub.add_parser("flash", help="write a profile into the controller (verified by read-back)")
    flash.add_argument("url", metavar="URL")
    flash.add_argument("profile", metavar="PROFILE")
    flash.add_argument("--force", action="store_true",
                       help="flash a profile made for another panel (size, subpixel order or view count) "
                            "anyway, for panel bring-up")
    flash.set_defaults(run=run_flash, flags={"force": "--force"})  # the library's names
    verify = sub.add_parser("verify", help="check that the controller holds a profile; exit 1 if not")
    verify.add_argument("url", metavar="URL")
    verify.add_argument("profile", metavar="PROFILE")
    verify.set_defaults(run=run_verify)
    for p in (lst, info, read, flash, verify):
        p.epilog = ("URLs: serial:///dev/ttyACM0, socket://HOST:PORT, hid://VID:PID[/SERIAL], "
                    "usb://VID:PID[/SERIAL], emu://NAME[?via=serial|hid|usb]; Looking Glass units (read-only): "
                    "lkg-hid://04d8:ef7e[/SERIAL], lkg-drive:///MOUNT/POINT, lkg-emu://NAME")


def run_list(args) -> int:
    import dataclasses

    from ..device.discovery import list_devices
    from ..device.looking_glass.unit import FAMILY as LOOKING_GLASS_FAMILY

    found, notes = list_devices()
    if args.json:
        print(json.dumps({"devices": [dataclasses.asdict(d) for d in found], "notes": notes}, indent=2))
        return 0
    for d in found:
        # a Looking Glass unit's USB serial is not its calibration's serial ('device info' shows both)
        label = "USB serial" if d.family == LOOKING_GLASS_FAMILY else "serial"
        serial = f"  {label} {shown(d.serial)}" if d.serial else ""
        print(f"{shown(d.url):<40} {shown(d.family):<6} {shown(d.description)}{serial}")
    if not found:
        print("no controllers or Looking Glass units found (start an emulated one with 'lenticalib emulate')")
    for note in notes:
        print(f"note: {safe_line(note)}")
    return 0


def _looking_glass(url: str) -> bool:
    from ..device.looking_glass import is_looking_glass

    return is_looking_glass(url)


def _url_file(url: str) -> str | None:
    from ..device.url_files import url_file

    return url_file(url)


def _refuse_looking_glass(url: str, message: str, then: str = "") -> None:
    """One line: a Looking Glass unit is read-only to lenticalib."""
    from ..core.errors import InputError

    raise InputError(f"is a Looking Glass unit: {message}", source=url,
                     hint=f"read its calibration with 'lenticalib device read {url} -o profile.json --views N'{then}")


def _print_looking_glass_info(out: dict) -> None:
    kind = out["kind"].removeprefix("Looking Glass (").removesuffix(")")
    usb = (f", USB serial {shown(out['usb_serial'])}"
           if out["usb_serial"] and out["usb_serial"] != out["serial"] else "")
    print(f"Looking Glass unit ({shown(kind)}), serial {shown(out['serial'] or '?')}{usb}")
    print(f"calibration version {shown(out['config_version'] or '? (no configVersion)')}, "
          f"visual.json of {out['calibration_bytes']} bytes")
    cal = out["calibration"]
    if cal:
        print(", ".join(f"{key} {shown(value)}" for key, value in cal.items()))
    print(f"read it into a profile with 'lenticalib device read {shown(out['url'])} -o profile.json --views N'")


def run_info(args) -> int:
    from ..core.profile import format_constant
    from ..device.info import device_info
    from ..device.protocol import PanelGeometry

    out = device_info(args.url)
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    if "kind" in out:
        _print_looking_glass_info(out)
        return 0
    print(f"{shown(out['model'])}, firmware {shown(out['firmware_version'])}, serial {shown(out['serial'])}")
    print(f"protocol v{out['protocol_version']}, record layout v{out['record_layout_version']}")
    if out["panel"] is not None:
        geometry = PanelGeometry(**{**out["panel"], "view_counts": tuple(out["panel"]["view_counts"])})
        print(f"panel {shown(geometry.describe())}")
    else:
        print(f"panel not reported (protocol {out['protocol_version']} firmware)")
    r = out["record"]
    if r is None:
        print("no calibration record (flash one with 'lenticalib device flash')")
    else:
        crc = r["crc32"] + ("" if r["crc32_reported_by_device"] else ", from the bytes read back")
        print(f"record #{r['sequence']} in slot {r['slot']} (CRC-32 {crc}), written {shown(r['written'] or '?')}: "
              f"{r['views']} views, slant {format_constant('slant', r['slant'])}, "
              f"period {format_constant('period', r['period'])}, offset {format_constant('offset', r['offset'])}, "
              f"i_ref {format_constant('reference_view', r['reference_view'])}, "
              f"{r['width']}x{r['height']} {r['subpixel_order']}")
    return 0


def run_read_looking_glass(args) -> int:
    from ..core.errors import InputError
    from ..core.files.outputs import check_output_file
    from ..core.profile import MAX_VIEWS, save_profile
    from ..core.view_defaults import default_views
    from ..device.looking_glass import read_calibration

    if args.views is not None and not 2 <= args.views <= MAX_VIEWS:
        raise InputError(f"must be 2..{MAX_VIEWS}, got {args.views}", source="--views")
    # before talking to the device
    check_output_file(args.output, "profile", example="profile.json", inputs=[_url_file(args.url)])
    calibration = read_calibration(args.url)
    serial = calibration.field("serial")  # the calibration's own, as Looking Glass reads it (not the USB serial)
    views = args.views if args.views is not None else default_views({"serial": serial})
    if views is None:
        raise InputError(f"a Looking Glass unit's calibration does not say how many views the quilts have, and its "
                         f"serial {shown(str(serial or '?'))} names no model whose quilt lenticalib knows",
                         source="--views", hint=f"give it, e.g. 'lenticalib device read {args.url} -o "
                                                f"{args.output} --views 45'; 48 on a Portrait")
    profile = calibration.to_profile(views)
    for note in (profile.provenance or {}).get("assumptions", []):
        _warn(f"{args.url}: {note}")
    save_profile(profile, args.output)
    print(f"read the Looking Glass calibration of {shown(args.url)} (serial {shown(calibration.serial or '?')}, "
          f"calibration version {shown(calibration.config_version or '?')}) into {shown(args.output)}: "
          f"{profile.views} views, {profile.width}x{profile.height} {profile.layout_name}")
    return 0


def run_read(args) -> int:
    from ..device import PanelController
    from ..core.errors import InputError
    from ..core.files.outputs import check_output_file
    from ..core.profile import save_profile

    if _looking_glass(args.url):
        return run_read_looking_glass(args)
    if args.views is not None:
        raise InputError("applies to Looking Glass units only; a controller's record holds its view count",
                         source="--views", hint=f"leave it out: 'lenticalib device read {args.url} -o {args.output}'")
    # before talking to the device
    check_output_file(args.output, "profile", example="profile.json", inputs=[_url_file(args.url)])
    with PanelController.open(args.url) as panel:
        profile = panel.read_profile()
    save_profile(profile, args.output)
    print(f"read record #{profile.provenance['record_sequence']} from {args.url} into {args.output}")
    print(f"note: the calibration record has no room for the view direction, so {args.output} says "
          f"view_direction unknown; set it with 'lenticalib profile set-direction {args.output} +1|-1' "
          "(see 'lenticalib patterns --direction')")
    return 0


def _warn(line: str) -> None:
    import sys

    print(f"lenticalib: warning: {safe_line(line)}", file=sys.stderr, flush=True)


def run_flash(args) -> int:
    from ..device import PanelController
    from ..core.profile import load_profile
    from .shared.progress import progress_bar

    if _looking_glass(args.url):
        _refuse_looking_glass(args.url, "lenticalib only reads it and never writes its factory calibration")
    profile = load_profile(args.profile)  # validated before anything is sent
    if profile.view_direction is not None:
        _warn(f"{args.profile}: the calibration record has no room for view_direction "
              f"({profile.view_direction:+d}); a profile read back from the panel says unknown, so keep this file")
    with PanelController.open(args.url) as panel, progress_bar(1, "flashing") as bar:
        def progress(done, total):
            bar.set_total(total)
            bar.update()

        result = panel.flash(profile, progress=progress, force=args.force, warn=_warn, source=args.profile)
    print(f"flashed {args.profile} to {args.url}: record #{result.record.sequence} in slot {result.slot}, "
          f"verified by read-back" + (f" ({result.retries} resends)" if result.retries else ""))
    return 0


def run_verify(args) -> int:
    from ..device import PanelController
    from ..core.profile import load_profile

    if _looking_glass(args.url):
        _refuse_looking_glass(args.url, "it holds its factory calibration, not a lenticalib record to verify",
                              f" and compare it with 'lenticalib profile compare profile.json {args.profile}'")
    profile = load_profile(args.profile)
    with PanelController.open(args.url) as panel:
        result = panel.verify(profile)
    if result.matches:
        print(f"{args.url} holds {args.profile} (record #{result.record.sequence})")
        return 0
    print(f"{shown(args.url)} does not hold {shown(args.profile)}:")
    for line in result.differences:
        print(f"  {safe_line(line)}")
    return 1
