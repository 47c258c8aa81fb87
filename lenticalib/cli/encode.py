"""``lenticalib encode``: views (a folder or a quilt) + profile -> panel raster image."""

from __future__ import annotations

import argparse
import json


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--profile", required=True, metavar="P", help="panel profile (JSON)")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--quilt", metavar="FILE", help="quilt image, view 0 bottom-left")
    source.add_argument("--views-dir", metavar="DIR", help="folder of N view images, natural file-name order")
    parser.add_argument("--grid", metavar="COLSxROWS", help="quilt grid when the file name has no _qs suffix")
    parser.add_argument("-o", "--output", required=True, metavar="OUT", help="panel raster (.png, .tif or .npy)")
    parser.add_argument("--encoder", default="fast", help="encoder name (default: fast; see 'reference', 'tables', 'torch')")
    parser.add_argument("--stretch", action="store_true", help="allow views of another aspect ratio than the panel")
    add_compensation_arguments(parser)
    parser.add_argument("--json", action="store_true", help="print a JSON summary instead of a sentence")
    parser.set_defaults(run=run)


def add_compensation_arguments(parser: argparse.ArgumentParser) -> None:
    """``--compensate FILE``, its three knobs and ``--force`` (shared by encode, play and render)."""
    parser.add_argument("--compensate", metavar="CROSSTALK", help="pre-compensate the views for the crosstalk "
                        "measured by 'lenticalib crosstalk measure' (crosstalk.json)")
    parser.add_argument("--black-lift", type=float, default=0.0, metavar="B",
                        help="with --compensate: lift black to B (linear, 0..0.5) so leaks into dark views can be "
                             "cancelled too (default 0)")
    parser.add_argument("--regularisation", type=float, default=None, metavar="L",
                        help="with --compensate: weight of staying close to the intended views (default 0.02)")
    parser.add_argument("--iterations", type=int, default=None, metavar="K",
                        help="with --compensate: projected-gradient steps of the bounded solve (default 2)")
    parser.add_argument("--force", action="store_true",
                        help="with --compensate: use a crosstalk file measured for another panel (or another fit "
                             "of this one) anyway, and say so: a warning, and encode --json's provenance "
                             "(docs/identity.md)")


COMPENSATION_FLAGS = {"crosstalk_file": "--compensate crosstalk.json", "black_lift": "--black-lift",
                      "regularisation": "--regularisation", "iterations": "--iterations", "force": "--force"}
FLAGS = {**COMPENSATION_FLAGS, "profile": "--profile", "views_dir": "--views-dir DIR", "quilt": "--quilt FILE",
         "allow_stretch": "--stretch", "grid": "--grid"}


def compensation_options(args: argparse.Namespace):
    """The :class:`~lenticalib.render.pipeline.encode_file.CompensationOptions` of ``--compensate`` and its knobs."""
    from ..render.pipeline.encode_file import CompensationOptions

    return CompensationOptions(args.compensate, args.black_lift, args.regularisation, args.iterations, args.force)


def compensator_from_args(args: argparse.Namespace, profile):
    """The :class:`~lenticalib.render.compose.compensation.Compensator` the options ask for the panel of
    ``profile``, or None; InputError naming the flag for knobs without ``--compensate`` or out of
    range, or the file for a crosstalk file of another panel without ``--force``."""
    from .shared.flags import flag_names

    with flag_names(COMPENSATION_FLAGS):
        return compensation_options(args).compensator(profile)


def run(args: argparse.Namespace) -> int:
    import sys

    from ..core.identity import forced_note
    from ..render.pipeline.encode_file import encode_to_file
    from ..render.compose.views import parse_grid
    from .shared.flags import flag_names

    grid = parse_grid(args.grid, "--grid") if args.grid else None
    with flag_names(FLAGS):
        done = encode_to_file(args.profile, args.output, views_dir=args.views_dir, quilt=args.quilt, grid=grid,
                              encoder=args.encoder, allow_stretch=args.stretch, compensation=compensation_options(args))
    if args.json:
        print(json.dumps(done.summary()))
    else:
        p, (w, h), compensate = done.profile, done.view_size, done.compensate_seconds
        print(f"wrote {args.output}: {p.width}x{p.height} {done.dtype} from {p.views} views of {w}x{h} "
              f"({done.encoder} encoder, {done.encode_seconds * 1000:.0f} ms incl. compile"
              + (f"; crosstalk pre-compensation {compensate * 1000:.0f} ms" if compensate is not None else "")
              + ("; crosstalk pre-compensation on the GPU" if done.compensated_on == "gpu" else "") + ")")
    note = forced_note(done.compensation_origin or {}, args.compensate)
    if note:
        print(f"lenticalib: warning: {note}", file=sys.stderr)
    return 0
