"""``lenticalib emulate``: run an emulated panel controller on a pseudo-terminal or TCP port.

Prints the device URL on the first line of stdout and serves until stopped (Ctrl-C).  With
``--looking-glass VISUAL.json`` it instead saves an emulated Looking Glass HID unit holding that
calibration (``lkg-emu://NAME``, opened inside the process that reads it), prints its URL and
exits.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--transport", choices=("pty", "tcp"), default="pty",
                        help="pty: a serial device /dev/pts/N (default); tcp: socket://127.0.0.1:PORT")
    parser.add_argument("--port", type=int, default=0, help="TCP port for --transport tcp (default: any free)")
    parser.add_argument("--flash", metavar="IMAGE",
                        help="flash image file, created blank if missing and kept across restarts "
                             "(default: default.flash in the emulator directory)")
    parser.add_argument("--serial", help="serial number for a new flash image (default: from its file name)")
    panel = parser.add_argument_group("the panel the controller drives (reported in IDENTIFY; default: the "
                                      "family's, drivers/lc32.toml)")
    panel.add_argument("--panel", metavar="WxH", help="panel size in pixels, e.g. 3840x2160")
    panel.add_argument("--subpixel-order", metavar="RGB|BGR", help="colour at subpixel positions 0, 1, 2")
    panel.add_argument("--view-counts", metavar="N[,N...]",
                       help="view counts the controller supports, e.g. 32 or 16,32")
    parser.add_argument("--protocol", default=None, metavar="1.0|1.1",
                        help="firmware generation to emulate (default 1.1; 1.0: CRCs over all 128 record bytes, "
                             "no panel in IDENTIFY)")
    lkg = parser.add_argument_group("an emulated Looking Glass unit (HID, calibration in its EEPROM) instead of a "
                                    "controller")
    lkg.add_argument("--looking-glass", metavar="VISUAL_JSON",
                     help="save a unit whose EEPROM holds this visual.json (stored as given), print its URL "
                          "lkg-emu://NAME and exit; faults go in the URL: ?drop=P&short=P&wrong-page=P&seed=S")
    lkg.add_argument("--name", help="with --looking-glass: the unit's name in its URL (default: lkg)")
    faults = parser.add_argument_group("fault injection (rates are probabilities per frame)")
    faults.add_argument("--power-cut-after", type=int, metavar="K",
                        help="the power fails after the K-th flash operation (erase or program): the process "
                             "exits with status 75 and the image keeps what was written")
    faults.add_argument("--torn", action="store_true",
                        help="with --power-cut-after: the K-th operation is cut halfway through")
    faults.add_argument("--drop", type=float, default=0.0, metavar="P", help="lose a request or a reply")
    faults.add_argument("--corrupt", type=float, default=0.0, metavar="P", help="flip a bit in a request or reply")
    faults.add_argument("--duplicate", type=float, default=0.0, metavar="P", help="send a reply twice")
    faults.add_argument("--delay", type=float, default=0.0, metavar="P", help="hold a reply back by --delay-s")
    faults.add_argument("--delay-s", type=float, default=0.2, metavar="S", help="delay in seconds (default 0.2)")
    faults.add_argument("--stale", type=float, default=0.0, metavar="P",
                        help="send an earlier (stale) reply before the real one: the last reply to the same "
                             "command, else the previous reply")
    faults.add_argument("--disconnect-after", type=int, metavar="N",
                        help="the link goes away after N request frames (exit status 76)")
    faults.add_argument("--seed", type=int, default=0, help="random seed of the faults (default 0)")
    parser.set_defaults(run=run, flags=FLAGS)


FLAGS = {"drop_rate": "--drop", "corrupt_rate": "--corrupt", "duplicate_rate": "--duplicate", "delay_rate": "--delay",
         "stale_rate": "--stale", "delay_s": "--delay-s", "disconnect_after": "--disconnect-after",
         "power_cut_after": "--power-cut-after", "serial": "--serial", "port": "--port", "panel": "--panel",
         "image": "--flash", "name": "--name"}  # the library's names


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..device.emulator import config
    from ..device.emulator.controller import EmulatedController, default_image_dir, default_panel, ensure_image
    from ..device.emulator.faults import FaultPlan
    from ..device.emulator.serve import runtime_dir, serve_pty, serve_tcp
    from ..core.errors import InputError
    from ..core.files.outputs import check_output_file

    if args.looking_glass is not None:
        return run_looking_glass(args)
    if args.name is not None:
        raise InputError("names an emulated Looking Glass unit: it needs --looking-glass VISUAL_JSON", source="--name")
    if args.torn and args.power_cut_after is None:
        raise InputError("--torn needs --power-cut-after K", source="--torn")
    if not 0 <= args.port <= 65535:
        raise InputError(f"must be 0..65535, got {args.port}", source="--port")
    faults = FaultPlan(drop_rate=args.drop, corrupt_rate=args.corrupt, duplicate_rate=args.duplicate,
                       delay_rate=args.delay, delay_s=args.delay_s, stale_rate=args.stale,
                       disconnect_after=args.disconnect_after, power_cut_after=args.power_cut_after,
                       torn=args.torn, seed=args.seed)
    try:
        minor = config.parse_protocol(args.protocol or config.CURRENT_PROTOCOL)
    except ValueError as exc:
        raise InputError(str(exc), source="--protocol") from None
    panel = default_panel()
    for option, argument, text in (("--panel", "size", args.panel), ("--subpixel-order", "order", args.subpixel_order),
                                   ("--view-counts", "views", args.view_counts)):
        if text is not None:
            try:
                panel = config.panel_geometry(panel, **{argument: text})
            except ValueError as exc:
                raise InputError(str(exc), source=option) from None
    runtime_dir()  # where the running emulator announces itself: an unsafe folder is refused before anything
    if args.flash:
        image = Path(args.flash)
        # a regular file (or a link to one) or a new name: a missing folder is refused, never created, and a
        # folder, FIFO or device node is never written into; the image is the emulator's own state, read and
        # written in place by design, so it is no input of another output
        check_output_file(image, "flash image", example="panel.flash", inputs=())
    else:
        image = default_image_dir() / "default.flash"
        image.parent.mkdir(parents=True, exist_ok=True)  # the emulators' own state folder
    try:
        ensure_image(image, serial=args.serial)
    except OSError as exc:
        raise InputError(f"cannot create the flash image: {exc.strerror}", source=str(image)) from None
    controller = EmulatedController(image, faults, panel=panel, protocol_minor=minor)
    if args.transport == "pty":
        serve_pty(controller)
    else:
        serve_tcp(controller, port=args.port)
    return 0


def run_looking_glass(args: argparse.Namespace) -> int:
    import re
    from pathlib import Path

    from ..core.files.input_files import read_input
    from ..core.files.outputs import check_output_file
    from ..device.emulator.looking_glass import create_unit, unit_image
    from ..device.looking_glass.unit import MAX_CALIBRATION_BYTES

    source = Path(args.looking_glass)
    name = "lkg" if args.name is None else args.name
    if re.fullmatch(r"[A-Za-z0-9_.-]+", name):  # a bad name is refused by create_unit
        image = unit_image(name)
        image.parent.mkdir(parents=True, exist_ok=True)  # the emulators' own state folder, as create_unit makes it
        check_output_file(image, "Looking Glass EEPROM image", inputs=[source])
    # a regular file (a FIFO or /dev/zero is refused at once) of at most what a unit's EEPROM holds
    text = read_input(source, "visual.json", MAX_CALIBRATION_BYTES, "give the path of a Looking Glass visual.json")
    print(create_unit(name, text), flush=True)
    return 0
