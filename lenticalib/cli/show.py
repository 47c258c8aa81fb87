"""``lenticalib show``: put an image, a pattern set or a folder of rasters on the panel, pixel-exact.

Everything is checked before a window opens: the path, the rasters' size, the display and
the monitor (whose current mode must be the rasters' size: nothing is ever scaled).
"""

from __future__ import annotations

import argparse

from ..core.terminal_text import safe_line


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("path", nargs="?", metavar="FILE|DIR",
                        help="an image, a pattern folder (shown in manifest order) or a folder of images")
    parser.add_argument("--display", metavar="SPEC",
                        help="monitor: index, @X,Y or part of its name (default: the one whose mode is the "
                             "raster's size); 'offscreen' renders with no window (needs --interval)")
    parser.add_argument("--list-displays", action="store_true", help="print the monitors and exit")
    parser.add_argument("--interval", type=float, metavar="S",
                        help="advance every S seconds (keys still work); default: wait for a key")
    parser.add_argument("--loop", action="store_true", help="start again after the last image")
    parser.add_argument("--no-vsync", action="store_true", help="do not wait for the display's refresh")
    parser.set_defaults(run=run, flags={"display": "--display"})  # the library's argument names, as flags


def run(args: argparse.Namespace) -> int:
    import statistics

    from ..core.errors import InputError
    from ..render.present import list_monitors, open_presenter
    from ..core.slides import run_slideshow, slides_from_path

    if args.list_displays:
        for monitor in list_monitors():
            print(safe_line(monitor.describe()))  # names the monitors report (EDID)
        return 0
    if args.path is None:
        raise InputError("give an image or a folder to show", source="FILE|DIR",
                         hint="e.g. lenticalib show patterns/ (or --list-displays)")
    if args.interval is not None and not 0.0 < args.interval <= 86400:
        raise InputError(f"{args.interval} seconds is out of range", source="--interval", hint="use 0 < S <= 86400")
    offscreen = bool(args.display) and args.display.split(":")[0] in ("offscreen", "none")
    if offscreen and args.interval is None:
        raise InputError("an offscreen show has no keys to step with", source="--display",
                         hint="add --interval S")
    slides, size = slides_from_path(args.path)
    presenter = open_presenter(args.display, size, vsync=not args.no_vsync)
    with presenter:
        shown = run_slideshow(presenter, slides, interval=args.interval, loop=args.loop)
    timings = presenter.timings
    if timings:
        upload = statistics.median(t.upload_ms for t in timings)
        present = statistics.median(t.present_ms for t in timings)
        print(f"showed {shown} raster(s) of {size[0]}x{size[1]}; median upload {upload:.1f} ms, "
              f"present {present:.1f} ms")
    return 0
