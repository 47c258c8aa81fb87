"""``lenticalib avatar diagnose``: is an avatar fit for the panel?

    diagnose AVATAR [AVATAR ...] [--mesh FILE] [--controls SRC --frame K] [--views N]
             [--yaw-range DEG] [--radius R] [--fov DEG] [--view-size WxH] [--renderer NAME]
             [--json] [--report DIR]

Renders every view of the arc with alpha and computes the LentiAvatar side-view diagnostics per
view (:mod:`lenticalib.render.diagnose.side_metrics`): a table at -25 and +25 degrees and the worst view,
or, for several avatars, one row each (the mean over the side views) with the best and second
best marked.  Calls :func:`lenticalib.render.diagnose.avatars.diagnose_avatars`.
"""

from __future__ import annotations

import argparse
import json

from ..core.terminal_text import safe_line

FLAGS = {"avatar": "AVATAR", "mesh": "--mesh", "controls": "--controls", "frame": "--frame", "n_views": "--views",
         "yaw_range_deg": "--yaw-range", "radius": "--radius", "fov_deg": "--fov", "view_size": "--view-size",
         "renderer": "--renderer", "device": "--device", "report": "--report", "camera_model": "--camera-model",
         "model": "--camera-model"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="avatar_command", metavar="STEP")
    sub.required = True
    d = sub.add_parser("diagnose", help="the LentiAvatar side-view diagnostics of avatars along the view cone",
                       description="render every view of the camera arc with alpha and measure outside-support "
                                   "opacity, neck-rear ghosts, translucent smear, colour fringes and contour "
                                   "sharpness against the avatar's mesh")
    d.add_argument("avatars", nargs="+", metavar="AVATAR", help="3DGS .ply (static; needs --mesh) or lenticalib "
                   "rig .npz (with its own mesh, or --mesh); several: one row each")
    d.add_argument("--mesh", metavar="FILE", help="the avatar's mesh (OBJ or PLY triangles, in the avatar's frame "
                   "and units), used as given for every avatar")
    d.add_argument("--controls", metavar="SRC", help="pose the avatar: a control file (.npz, .csv, .jsonl) or "
                   "'demo' (default: the canonical pose)")
    d.add_argument("--frame", type=int, default=0, metavar="K", help="which sample of --controls (default 0; "
                   "'demo': K / 30 s)")
    d.add_argument("--views", type=int, default=32, metavar="N", help="views on the arc (default 32)")
    d.add_argument("--camera-model", default="arc", metavar="MODEL", help="arc (LentiAvatar, default) or shear")
    d.add_argument("--yaw-range", type=float, default=50.0, metavar="DEG", help="yaw range of the views, degrees "
                   "(default 50: -25..+25)")
    d.add_argument("--radius", type=float, metavar="R", help="camera distance from the look-at point (avatar units)")
    d.add_argument("--fov", type=float, default=20.0, metavar="DEG", help="vertical field of view, degrees "
                   "(default 20)")
    d.add_argument("--view-size", default="960x540", metavar="WxH", help="view size (default 960x540)")
    d.add_argument("--renderer", default=None, metavar="NAME", help="cpu (default), gl or gsplat")
    d.add_argument("--device", default=None, help="torch device for gsplat (default cuda)")
    d.add_argument("--json", action="store_true", help="print the result as JSON")
    d.add_argument("--report", metavar="DIR", help="folder for the figures and the JSON documents")
    d.set_defaults(run=run_diagnose, flags=FLAGS)


def run_diagnose(args: argparse.Namespace) -> int:
    from ..core.sizes import parse_size
    from ..render.diagnose.avatars import DiagnoseOptions, diagnose_avatars
    from ..render.diagnose.report import diagnose_table
    from .shared.progress import staged_bars

    options = DiagnoseOptions(controls=args.controls, frame=args.frame, camera_model=args.camera_model,
                              n_views=args.views, yaw_range_deg=args.yaw_range, radius=args.radius, fov_deg=args.fov,
                              view_size=parse_size(args.view_size, "--view-size", example="960x540"),
                              renderer=args.renderer, device=args.device)
    with staged_bars() as stage:
        result = diagnose_avatars(args.avatars, mesh=args.mesh, options=options, report=args.report, stage=stage)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    for line in diagnose_table(result):
        print(safe_line(line))  # names of the avatars' files
    if args.report:
        print(f"wrote the report {args.report}")
    return 0
