"""``lenticalib encode``: views (a folder or a quilt) + profile -> panel raster image."""

from __future__ import annotations

import argparse
import json


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--profile", required=True, metavar="P", help="panel profile (JSON)")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--quilt", metavar="FILE", help="quilt image, view 0 bottom-left")
    source.add_argument("--views", metavar="DIR", help="folder of N view images, natural file-name order")
    parser.add_argument("--grid", metavar="COLSxROWS", help="quilt grid when the file name has no _qs suffix")
    parser.add_argument("-o", "--output", required=True, metavar="OUT", help="panel raster (.png, .tif or .npy)")
    parser.add_argument("--encoder", default="fast", help="encoder name (default: fast; see 'reference', 'tables', 'torch')")
    parser.add_argument("--stretch", action="store_true", help="allow views of another aspect ratio than the panel")
    add_compensation_arguments(parser)
    parser.add_argument("--json", action="store_true", help="print a JSON summary instead of a sentence")
    parser.set_defaults(run=run)


def add_compensation_arguments(parser: argparse.ArgumentParser) -> None:
    """``--compensate FILE`` and its three knobs (shared by encode, play and render)."""
    parser.add_argument("--compensate", metavar="CROSSTALK", help="pre-compensate the views for the crosstalk "
                        "measured by 'lenticalib crosstalk measure' (crosstalk.json)")
    parser.add_argument("--black-lift", type=float, default=0.0, metavar="B",
                        help="with --compensate: lift black to B (linear, 0..0.5) so leaks into dark views can be "
                             "cancelled too (default 0)")
    parser.add_argument("--regularisation", type=float, default=None, metavar="L",
                        help="with --compensate: weight of staying close to the intended views (default 0.02)")
    parser.add_argument("--iterations", type=int, default=None, metavar="K",
                        help="with --compensate: projected-gradient steps of the bounded solve (default 2)")


def compensator_from_args(args: argparse.Namespace, views: int):
    """The :class:`~lenticalib.render.compensation.Compensator` the options ask for, or None; InputError
    for knobs without ``--compensate`` or out of range."""
    from ..core.errors import InputError
    from ..render.compensation import DEFAULT_ITERATIONS, DEFAULT_REGULARISATION, compensator_from_file

    if args.compensate is None:
        for flag, value, default in (("--black-lift", args.black_lift, 0.0), ("--regularisation", args.regularisation, None),
                                     ("--iterations", args.iterations, None)):
            if value != default:
                raise InputError("is only used with --compensate", source=flag, hint="add --compensate crosstalk.json")
        return None
    return compensator_from_file(args.compensate, views,
                                 DEFAULT_REGULARISATION if args.regularisation is None else args.regularisation,
                                 args.black_lift, DEFAULT_ITERATIONS if args.iterations is None else args.iterations)


def run(args: argparse.Namespace) -> int:
    import time

    import numpy as np

    from ..render.encoders import encode, get_encoder
    from ..core.errors import ImageError
    from ..core.imageio import check_image_output, write_image
    from ..core.profile import load_profile
    from ..render.views import load_quilt, load_view_folder, parse_grid

    profile = load_profile(args.profile, "--profile")
    get_encoder(args.encoder)  # an unknown --encoder is refused before the views are read
    compensator = compensator_from_args(args, profile.views)
    check_image_output(args.output, what="panel raster")  # a wrong -o costs nothing
    if args.quilt:
        views, grid = load_quilt(args.quilt, profile.views, parse_grid(args.grid) if args.grid else None)
        panel_aspect = profile.width / profile.height
        if grid.aspect and not args.stretch and abs(grid.aspect / panel_aspect - 1.0) > 0.01:
            raise ImageError(f"quilt was made for aspect {grid.aspect:g}, the profile's panel is "
                             f"{profile.width}x{profile.height} (aspect {panel_aspect:.4f})", source=args.quilt,
                             hint="use the profile of the panel the quilt was made for, or --stretch")
    else:
        views = load_view_folder(args.views, profile.views)
    check_image_output(args.output, views.dtype, what="panel raster")  # e.g. float views into a .png
    compensate_seconds = None
    if compensator is not None:
        if views.dtype != np.uint8:
            raise ImageError(f"--compensate works on 8-bit views, these are {views.dtype}",
                             source=args.views or args.quilt, hint="save the views as 8-bit PNG or JPEG")
        start = time.perf_counter()
        views = compensator.apply(views)
        compensate_seconds = time.perf_counter() - start
    start = time.perf_counter()
    raster = encode(views, profile, args.encoder, allow_stretch=args.stretch)
    elapsed = time.perf_counter() - start
    write_image(args.output, raster)
    summary = {"output": args.output, "width": profile.width, "height": profile.height, "views": profile.views,
               "view_size": [int(views.shape[2]), int(views.shape[1])], "dtype": str(raster.dtype),
               "encoder": args.encoder, "encode_seconds": round(elapsed, 4),
               "compensate": args.compensate,
               "compensate_seconds": None if compensate_seconds is None else round(compensate_seconds, 4)}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"wrote {args.output}: {profile.width}x{profile.height} {raster.dtype} from {profile.views} views of "
              f"{views.shape[2]}x{views.shape[1]} ({args.encoder} encoder, {elapsed * 1000:.0f} ms incl. compile"
              + (f"; crosstalk pre-compensation {compensate_seconds * 1000:.0f} ms" if compensate_seconds is not None
                 else "") + ")")
    return 0
