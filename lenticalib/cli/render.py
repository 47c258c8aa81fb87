"""``lenticalib render``: the avatar pipeline offline, to PNG panel rasters or a lossless video (and the views).

``-o OUT.png`` (or ``.tif``, ``.npy``) for one frame, ``-o DIR`` for ``--frames N``
(``DIR/frame-00000.png`` ...) or ``-o OUT.mkv`` for a lossless video, at ``--fps`` steps of the
controls' time; ``--views-out VDIR`` also writes the N views of every frame and
``VDIR/cameras.json``.  The work, outputs checked first: :func:`lenticalib.render.pipeline.offline.render_avatar`.
"""

from __future__ import annotations

import argparse

COMPILING = ("lenticalib: compiling the render kernels (a first run only, about half a minute; "
             "they are kept on disk for the next runs)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from .shared.avatar_options import add_avatar_arguments

    add_avatar_arguments(parser)
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="OUT.png (one frame), OUT.mkv (lossless FFV1 video) or a folder of PNGs")
    parser.add_argument("--frames", type=int, default=1, metavar="N", help="frames to render (default 1)")
    parser.add_argument("--fps", type=float, default=30.0, help="frame rate of the controls' time (default 30)")
    parser.add_argument("--views-out", metavar="VDIR", help="also write the N views and cameras.json here")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import sys

    from ..render.pipeline.offline import render_avatar
    from .shared.avatar_options import avatar_options, flags, warning_line
    from .shared.flags import flag_names
    from .shared.progress import compile_notice, progress_bar

    # on a terminal: a bar over the frames, and one line when the kernels compile (a first run only)
    with flag_names(flags()), compile_notice(COMPILING), progress_bar(args.frames, "rendering", "frame") as bar:
        done = render_avatar(args.avatar, args.profile, args.output, options=avatar_options(args), frames=args.frames,
                             fps=args.fps, views_out=args.views_out, step=bar.update)
    pipeline = done.session.pipeline
    told = getattr(done.session.controls, "take_warnings", lambda: [])()  # a UDP port open to the network
    for warning in ([pipeline.warning] if pipeline.warning else []) + pipeline.notes + told:  # empty views among them
        print(f"lenticalib: warning: {warning_line(warning)}", file=sys.stderr)
    what = args.output if done.kind == "image" else f"{args.frames} frame(s) in {args.output}"
    if done.kind == "video":
        what = f"{args.frames} frame(s), lossless, in {args.output}"
    print(f"wrote {what}" + (f" and the views in {args.views_out}" if args.views_out else ""))
    print(done.times.table(f"lenticalib render: {done.session.avatar.source}, {pipeline.profile.views} views "
                           f"{pipeline.cameras.width}x{pipeline.cameras.height}, renderer {pipeline.renderer}, "
                           f"encoder {pipeline.encoder}"))
    return 0
