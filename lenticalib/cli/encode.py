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
    parser.add_argument("--json", action="store_true", help="print a JSON summary instead of a sentence")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import time

    from ..render.encoders import encode, get_encoder
    from ..errors import ImageError
    from ..imageio import check_image_output, write_image
    from ..profile import load_profile
    from ..render.views import load_quilt, load_view_folder, parse_grid

    profile = load_profile(args.profile, "--profile")
    get_encoder(args.encoder)  # an unknown --encoder is refused before the views are read
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
    start = time.perf_counter()
    raster = encode(views, profile, args.encoder, allow_stretch=args.stretch)
    elapsed = time.perf_counter() - start
    write_image(args.output, raster)
    summary = {"output": args.output, "width": profile.width, "height": profile.height, "views": profile.views,
               "view_size": [int(views.shape[2]), int(views.shape[1])], "dtype": str(raster.dtype),
               "encoder": args.encoder, "encode_seconds": round(elapsed, 4)}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"wrote {args.output}: {profile.width}x{profile.height} {raster.dtype} from {profile.views} views of "
              f"{views.shape[2]}x{views.shape[1]} ({args.encoder} encoder, {elapsed * 1000:.0f} ms incl. compile)")
    return 0
