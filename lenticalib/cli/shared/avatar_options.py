"""Options shared by ``lenticalib play`` and ``lenticalib render``, as
:class:`lenticalib.render.pipeline.session.AvatarOptions` (which checks them all before the first frame).
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
    parser.add_argument("--renderer", default=None, help="cpu (default without a GPU), gl (OpenGL: any GPU, or "
                        "Mesa; compute-shader tiles on a GPU), gl-compute (the tiles wherever OpenGL 4.3 is) or "
                        "gsplat (CUDA)")
    parser.add_argument("--encoder", default=None, help="fast (default on the CPU), gl (default with the gl "
                        "renderer), torch (default with gsplat), reference, tables")
    parser.add_argument("--device", default=None, help="torch device for gsplat/torch (default cuda)")
    parser.add_argument("--camera-model", default="arc", metavar="MODEL",
                        help="virtual cameras: arc (LentiAvatar, default), shear (Looking Glass style) or a "
                             "plug-in's model")
    parser.add_argument("--radius", type=float, help="camera distance from the look-at point (avatar units)")
    parser.add_argument("--fov", type=float, default=20.0, help="vertical field of view, degrees (default 20)")
    parser.add_argument("--yaw-range", type=float, default=None, help="yaw range of the N cameras, degrees "
                        "(default: the Looking Glass calibration's viewCone, else the profile's physical "
                        "view_cone_deg, else 50: -25..+25)")
    parser.add_argument("--target", metavar="X,Y,Z", help="the point the cameras look at, in the avatar's frame "
                        "and units (metres for the demo avatar and most 3DGS captures; write --target=-1,0,0 when X "
                        "is negative); default: the centre of the avatar's robust box (1st-99th percentile of the "
                        "Gaussians, so strays far away do not pull it), lifted to eye level")
    parser.add_argument("--view-size", default=None, metavar="WxH",
                        help="view size, at the panel's aspect (default: as tall as a tile of the quilt Looking "
                             "Glass renders for the unit's model, 420x560 on a Portrait; else about 960x540 at the "
                             "panel's aspect, 960x540 on a 16:9 panel)")
    parser.add_argument("--background", metavar="R,G,B|IMAGE", help="background colour (0..1 or 0..255) or an "
                        "image (resized to the view size; the same behind every view); default black")
    from ..encode import add_compensation_arguments

    add_compensation_arguments(parser)
    parser.add_argument("--edge-desaturation", type=float, default=0.0, metavar="S",
                        help="desaturate partly transparent edges by S (0..1; the LentiAvatar chroma attenuation)")


FLAGS = {"profile": "--profile", "controls": "--controls", "edge_desaturation": "--edge-desaturation",
         "frames": "--frames", "fps": "--fps", "output": "--output", "views_out": "--views-out VDIR",
         "camera_model": "--camera-model", "radius": "--radius", "fov_deg": "--fov", "yaw_range_deg": "--yaw-range",
         "view_size": "--view-size", "background": "--background", "encoder": "--encoder", "device": "--device",
         "driver": "--driver", "renderer": "--renderer", "target": "--target X,Y,Z"}
"""The library's argument names, as the flags of play and render (with those of --compensate)."""


def avatar_options(args: argparse.Namespace):
    """The :class:`~lenticalib.render.pipeline.session.AvatarOptions` the parsed options ask for."""
    from ...render.pipeline.session import AvatarOptions
    from ..encode import compensation_options

    return AvatarOptions(controls=args.controls, driver=args.driver, renderer=args.renderer, encoder=args.encoder,
                         device=args.device, camera_model=args.camera_model, radius=args.radius, fov_deg=args.fov,
                         yaw_range_deg=args.yaw_range, view_size=_size(args.view_size), background=args.background,
                         compensation=compensation_options(args), edge_desaturation=args.edge_desaturation,
                         target=parse_target(args.target))


def parse_target(text: str | None) -> tuple[float, float, float] | None:
    """``--target X,Y,Z`` as three finite floats (None when not given); one InputError naming
    ``target`` otherwise, before anything is loaded."""
    import math

    from ...core.errors import InputError

    if text is None:
        return None
    try:
        values = tuple(float(part) for part in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        shown = repr(text) if len(text) <= 40 else f"{text[:40]!r}... ({len(text)} characters)"
        raise InputError(f"{shown} is not X,Y,Z, three finite numbers", source="target",
                         hint="e.g. --target 0,1.6,0, in the avatar's frame and units: metres for the demo avatar")
    return values


def warning_line(text: str) -> str:
    """A warning of the library (``pipeline.notes``) in the command line's words: its argument
    names become flags (`target` -> --target X,Y,Z); control characters escaped, a long one cut
    (:func:`~lenticalib.core.terminal_text.safe_line`: warnings quote files)."""
    from ...core.errors import LenticalibError
    from ...core.terminal_text import safe_line
    from .flags import with_flags

    return safe_line(with_flags(LenticalibError(text), flags()).message)


def flags():
    """:data:`FLAGS` with those of the compensation options."""
    from ..encode import COMPENSATION_FLAGS

    return {**FLAGS, **COMPENSATION_FLAGS}


def _size(text: str | None) -> tuple[int, int] | None:
    from ...core.sizes import parse_size

    return None if text is None else parse_size(text, "--view-size", example="960x540")
