"""``lenticalib show``: put an image, a pattern set or a folder of rasters on the panel, pixel-exact;
with ``--profile``, play quilt images, quilt videos and folders of them on the unit.

Everything is checked before a window opens: the path, the rasters' size (or the quilts' grids
and the profile), the display and the monitor (whose current mode must be the rasters' size:
nothing is ever scaled).  Quilt playback: :mod:`lenticalib.render.pipeline.quilt_player`.
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
    quilts = parser.add_argument_group("quilts (with --profile: FILE|DIR are quilt images or videos, or a folder)")
    quilts.add_argument("--profile", metavar="P", help="play quilts encoded for this panel profile (JSON)")
    quilts.add_argument("--quilt-cols", type=int, metavar="C", help="quilt columns (default: the _qsCxRaA name)")
    quilts.add_argument("--quilt-rows", type=int, metavar="R", help="quilt rows (with --quilt-cols)")
    quilts.add_argument("--quilt-aspect", type=float, metavar="A", help="the aspect the quilt was made for")
    quilts.add_argument("--stretch", action="store_true", help="play quilts made for another aspect ratio")
    quilts.add_argument("--encoder", default="auto", help="auto (default: gl on a GPU, fast where OpenGL renders "
                        "in software), gl (OpenGL, CPU fallback) or a CPU encoder (fast, ...)")
    quilts.add_argument("--fps", type=float, metavar="F", help="video frame rate (default: the video's)")
    quilts.add_argument("--json", action="store_true", help="print the playback summary as JSON")
    parser.set_defaults(run=run, flags=FLAGS)  # the library's argument names, as flags


FLAGS = {"display": "--display", "profile": "--profile", "allow_stretch": "--stretch", "encoder": "--encoder",
         "grid": "--quilt-cols C --quilt-rows R"}


def run(args: argparse.Namespace) -> int:
    import statistics

    from ..core.errors import InputError
    from ..render.gpu.monitors import list_monitors
    from ..render.present.displays import open_presenter
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
    if args.profile is not None:
        return run_quilts(args, offscreen)
    for flag, value in (("--quilt-cols", args.quilt_cols), ("--quilt-rows", args.quilt_rows),
                        ("--quilt-aspect", args.quilt_aspect), ("--fps", args.fps), ("--json", args.json or None),
                        ("--stretch", args.stretch or None)):
        if value is not None:
            raise InputError("is for quilts", source=flag, hint="add --profile P to play quilts")
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


def with_flags_text(text: str) -> str:
    """A library note in the command line's words (```encoder``` -> ``--encoder``)."""
    return text.replace("`encoder` ", "--encoder ")


def _quilt_grid(args: argparse.Namespace):
    """The QuiltGrid the options give (None: from the names), refused in one line when partial."""
    from ..core.errors import InputError
    from ..core.profile import MAX_VIEWS
    from ..render.compose.views import QuiltGrid

    if (args.quilt_cols is None) != (args.quilt_rows is None):
        raise InputError("gives half a grid", source="--quilt-cols" if args.quilt_rows is None else "--quilt-rows",
                         hint="give both --quilt-cols and --quilt-rows")
    for flag, value in (("--quilt-cols", args.quilt_cols), ("--quilt-rows", args.quilt_rows)):
        if value is not None and not 1 <= value <= MAX_VIEWS:
            raise InputError(f"{value} tiles is out of range", source=flag, hint=f"use 1..{MAX_VIEWS}")
    if args.quilt_aspect is not None and not 0.01 <= args.quilt_aspect <= 100:
        raise InputError(f"{args.quilt_aspect} is out of range", source="--quilt-aspect", hint="e.g. 0.75 or 1.7778")
    if args.quilt_cols is None:
        return None
    return QuiltGrid(args.quilt_cols, args.quilt_rows, args.quilt_aspect)


def run_quilts(args: argparse.Namespace, offscreen: bool) -> int:
    """``show --profile P QUILT|VIDEO|DIR``: everything checked, then played (module docstring)."""
    import json

    from ..core.errors import InputError
    from ..core.profile import load_profile
    from ..core.view_defaults import quilt_model
    from ..render.encoders import get_encoder
    from ..render.present.displays import open_presenter
    from ..render.pipeline.quilt_player import play_quilts
    from ..render.pipeline.quilt_sources import QuiltMapping, check_video, quilt_items
    from ..render.compose.views import QuiltGrid

    if args.fps is not None and not 0.1 <= args.fps <= 1000:
        raise InputError(f"{args.fps} frames a second is out of range", source="--fps", hint="use 0.1 .. 1000")
    if offscreen and args.loop:
        raise InputError("an offscreen show with --loop never ends", source="--display", hint="drop --loop")
    grid = _quilt_grid(args)
    profile = load_profile(args.profile, "`profile`")
    if args.encoder not in ("gl", "auto"):
        get_encoder(args.encoder)  # an unknown encoder is refused before anything opens
    model = quilt_model(profile)  # a quilt named without _qs: the one Looking Glass renders for the model
    default = None if model is None else QuiltGrid(model.columns, model.rows, profile.width / profile.height)
    items = quilt_items(args.path, grid, args.quilt_aspect, default=default)
    for item in items:  # the grids' aspects and the videos' frame sizes, before a window opens
        mapping = QuiltMapping(profile, item.grid, args.stretch)
        mapping.check_aspect(None, item.source)
        if item.video:
            check_video(item, mapping)
    if offscreen and args.interval is None and not all(item.video for item in items):
        raise InputError("an offscreen show has no keys to step with", source="--display", hint="add --interval S")
    presenter = open_presenter(args.display, (profile.width, profile.height), vsync=not args.no_vsync)
    with presenter:
        report = play_quilts(presenter, items, profile, encoder=args.encoder, allow_stretch=args.stretch,
                             fps="video" if args.fps is None else args.fps, interval=args.interval, loop=args.loop)
    if args.json:
        print(json.dumps(report.summary()))
        return 0
    for note in report.notes:
        print(safe_line(f"note: {with_flags_text(note)}"))
    print(f"played {report.items} item(s) on {profile.width}x{profile.height} ({report.encoder} encoder): "
          f"{report.presented} frame(s) presented, {report.dropped} dropped, {report.fps:.1f} fps")
    return 0
