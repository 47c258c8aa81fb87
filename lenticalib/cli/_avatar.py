"""Options and set-up shared by ``lenticalib play`` and ``lenticalib render``.

Everything a user can get wrong is checked here, before the first frame: the renderer and
encoder (first: a name that is unknown or a backend that cannot run on this machine is refused
before anything is loaded), the avatar file, the driver, the profile, the controls (files are
read in full), the camera options, the background.
"""

from __future__ import annotations

import argparse


def add_avatar_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("avatar", metavar="AVATAR", help="3DGS .ply (static) or lenticalib rig .npz "
                        "(python tools/make_demo_avatar.py demo.npz makes the demo avatar)")
    parser.add_argument("--profile", required=True, metavar="P", help="the panel profile (JSON)")
    parser.add_argument("--controls", default="demo", metavar="SRC",
                        help="'demo' (built-in head turn and talking, default), a file (.npz, .csv, .jsonl), "
                             "'-' (JSON lines on stdin) or udp://HOST:PORT")
    parser.add_argument("--driver", metavar="SPEC", help="deformer: 'rig' (the rig's own, default) or "
                        "module:callable (your own, e.g. a FLAME-based avatar)")
    parser.add_argument("--renderer", default=None, help="cpu (default without a GPU) or gsplat (CUDA)")
    parser.add_argument("--encoder", default=None, help="fast (default on the CPU), torch (default with gsplat), "
                        "reference, tables")
    parser.add_argument("--device", default=None, help="torch device for gsplat/torch (default cuda)")
    parser.add_argument("--camera-model", default="arc", metavar="MODEL",
                        help="virtual cameras: arc (LentiAvatar, default), shear (Looking Glass style) or a "
                             "plug-in's model")
    parser.add_argument("--radius", type=float, help="camera distance from the look-at point (avatar units)")
    parser.add_argument("--fov", type=float, default=20.0, help="vertical field of view, degrees (default 20)")
    parser.add_argument("--yaw-range", type=float, default=50.0, help="yaw range of the N cameras, degrees "
                        "(default 50: -25..+25)")
    parser.add_argument("--view-size", default="960x540", metavar="WxH", help="view size (default 960x540)")
    parser.add_argument("--background", metavar="R,G,B|IMAGE", help="background colour (0..1 or 0..255) or an "
                        "image (resized to the view size; the same behind every view); default black")
    from .encode import add_compensation_arguments

    add_compensation_arguments(parser)
    parser.add_argument("--edge-desaturation", type=float, default=0.0, metavar="S",
                        help="desaturate partly transparent edges by S (0..1; the LentiAvatar chroma attenuation)")


def build_pipeline(args: argparse.Namespace):
    """(pipeline, controls source, avatar) from the parsed options; one-line errors before any frame."""
    from ..core.errors import InputError
    from ..core.profile import load_profile
    from ..render.avatar import load_avatar
    from ..render.camera_models import CAMERA_MODELS, make_cameras
    from ..render.controls import open_controls
    from ..render.encoders import get_encoder
    from ..render.loop import AvatarPipeline, parse_background
    from ..render.renderers import get_renderer

    renderer = args.renderer or "cpu"
    encoder = args.encoder or ("torch" if renderer == "gsplat" else "fast")
    device = args.device or ("cuda" if renderer == "gsplat" else "cpu")
    get_renderer(renderer, device=device)  # one that cannot run here is refused before anything is loaded
    get_encoder(encoder, device=device)
    CAMERA_MODELS.load(args.camera_model, "--camera-model")
    profile = load_profile(args.profile, "--profile")
    if not 0.0 <= args.edge_desaturation <= 1.0:
        raise InputError(f"{args.edge_desaturation} is out of range", source="--edge-desaturation", hint="use 0..1")
    from .encode import compensator_from_args

    compensator = compensator_from_args(args, profile.views)
    view_size = _size(args.view_size)
    background = parse_background(args.background, view_size)
    avatar = load_avatar(args.avatar, args.driver)
    controls = None
    if avatar.kind == "animated":
        controls = open_controls(args.controls, avatar.layout)
    elif args.controls != "demo":
        raise InputError("a static avatar (.ply) takes no controls", source="--controls",
                         hint="drop --controls, or give an animated avatar (a rig .npz)")
    options = {"fov_deg": args.fov, "yaw_range_deg": args.yaw_range, "view_size": view_size}
    if args.radius is not None:
        options["radius"] = args.radius
    cameras = make_cameras(args.camera_model, avatar.bounding_box(), profile.views, **options)
    pipeline = AvatarPipeline(avatar, profile, cameras, renderer=renderer, encoder=encoder, device=device,
                              background=background, edge_desaturation=args.edge_desaturation,
                              compensator=compensator)
    return pipeline, controls, avatar


def _size(text: str) -> tuple[int, int]:
    from ..core.sizes import parse_size

    return parse_size(text, "--view-size", example="960x540")
