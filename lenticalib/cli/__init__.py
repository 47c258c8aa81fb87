"""The ``lenticalib`` console script: one parser, one small module per subcommand.

cli sits on top of the layers: it may import every one of them, and no layer imports it (only
``lenticalib.__main__`` does).  Each subcommand module parses its arguments and calls the
library; ``print`` is used only here.

Subcommands (one module each)
    encode     views (a folder or a quilt) + profile -> panel raster image
    profile    show, validate, import or export (Looking Glass), compare, set-direction,
               set-physical, retarget panel profiles
    patterns   write the calibration test patterns (or, ``--direction``, a LEFT/RIGHT check)
    simulate   photograph the test patterns on a virtual panel (a synthetic capture set)
    capture    show each calibration pattern on the panel and photograph it
    fit        fit a panel profile from photos of the test patterns
    batch      a fleet of panels: ``batch fit`` fits every capture folder on a Dask cluster, with
               one summary
    camera     calibrate the camera's lens with mrcal: chessboard patterns, calibrate, simulate
    crosstalk  verify per-view crosstalk: patterns, measure, check against limits
    show       show an image, a pattern set or a folder of rasters on the panel, pixel-exact
    play       the live avatar loop drive -> render -> encode -> present, timed per stage
    render     the avatar pipeline offline, to PNG rasters or a lossless video
    avatar     diagnose avatars for the panel: the LentiAvatar side-view metrics along the view cone
    driver     the student driver: distil it per subject, predict controls from frames
    device     list panel controllers and Looking Glass units; info, read, flash and verify their
               calibration (a Looking Glass unit: info and read only)
    emulate    run an emulated panel controller on a pseudo-terminal or TCP port (or save an
               emulated Looking Glass unit)

Helpers (not commands)
    shared             what several subcommands share: the avatar options (``AvatarOptions``),
                       library errors told in flags, progress bars

``__main__`` makes ``python -m lenticalib.cli`` the console script.

:func:`build_parser` imports every subcommand module to build the full parser (their
``add_arguments``); those modules import numpy, OpenCV, numba and the library layers only inside
their run functions, so building the parser loads no third-party library and, of the library,
only ``core.errors`` and ``core.terminal_text``: ``--help`` is instant.  Every
:class:`~lenticalib.core.errors.LenticalibError` ends as one line on stderr and exit status 2,
told in the command's flags: a subcommand's parser may set a default ``flags`` (the library's
argument names -> its flags, :mod:`.shared.flags`), its control characters escaped and a long line cut
(:func:`~lenticalib.core.terminal_text.safe_line`: messages quote files and devices).  Text from
outside that a command prints (a serial, a field, a name a device reports) goes through
:func:`~lenticalib.core.terminal_text.terminal_safe` too.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from .. import __version__
from ..core.errors import LenticalibError
from ..core.terminal_text import safe_line
from .shared.flags import with_flags

_COMMANDS = {
    "encode": ("lenticalib.cli.encode", "encode views or a quilt into the panel raster"),
    "profile": ("lenticalib.cli.profile", "show, validate, import, export or compare panel profiles"),
    "patterns": ("lenticalib.cli.patterns",
                 "write the calibration test patterns for a panel (or, --direction, a LEFT/RIGHT check)"),
    "simulate": ("lenticalib.cli.simulate", "photograph patterns on a virtual panel (a synthetic capture set)"),
    "capture": ("lenticalib.cli.capture", "show each calibration pattern on the panel and photograph it"),
    "fit": ("lenticalib.cli.fit", "fit a panel profile from photos of the test patterns"),
    "batch": ("lenticalib.cli.batch", "a fleet of panels: fit every capture folder on a Dask cluster, with one "
              "summary"),
    "camera": ("lenticalib.cli.camera", "calibrate the camera's lens (mrcal): chessboard patterns, calibrate, "
               "simulate"),
    "crosstalk": ("lenticalib.cli.crosstalk", "verify per-view crosstalk: patterns from a profile, measure from "
                  "photos, check against limits"),
    "show": ("lenticalib.cli.show", "show an image, a pattern set or a folder on the panel, pixel-exact"),
    "play": ("lenticalib.cli.play", "drive a Gaussian avatar live on the panel: drive, render, encode, present"),
    "render": ("lenticalib.cli.render", "render a Gaussian avatar offline into panel rasters (and its views)"),
    "avatar": ("lenticalib.cli.avatar", "diagnose avatars for the panel: side-view artifacts along the view cone"),
    "driver": ("lenticalib.cli.driver", "the student driver: distil it from a subject's frames and controls, "
               "predict controls from frames"),
    "device": ("lenticalib.cli.device", "list panel controllers and Looking Glass units; read, flash and verify "
               "their calibration"),
    "emulate": ("lenticalib.cli.emulate", "run an emulated panel controller (pseudo-terminal or TCP), or save an "
                "emulated Looking Glass unit"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="lenticalib", description="Calibrate, program and drive "
                                     "slanted-lenticular 3D panels.")
    parser.add_argument("--version", action="version", version=f"lenticalib {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name, (module_name, help_text) in _COMMANDS.items():
        module = importlib.import_module(module_name)
        module.add_arguments(sub.add_parser(name, help=help_text, description=help_text))
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except LenticalibError as exc:
        # messages quote files and devices: escaped and cut here, for every error (core.terminal_text)
        print(f"lenticalib: error: {safe_line(with_flags(exc, getattr(args, 'flags', None) or {}))}",
              file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. head: not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except KeyboardInterrupt:
        print("lenticalib: interrupted", file=sys.stderr)
        return 130


def entry_point() -> None:
    sys.exit(main())
