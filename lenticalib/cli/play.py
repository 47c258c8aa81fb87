"""``lenticalib play``: the live loop drive -> render -> encode -> present, with per-stage timings.

Output: the panel (full screen, pixel-exact, through the presenter; the monitor whose mode is
the profile's size unless ``--display`` names one), ``--preview`` (a normal window showing the
centre view, for a desk without a panel) or ``--headless`` (no output: timing only).  Esc, q
or closing the window stops; ``--frames`` stops after that many.  On exit the stage table
(drive, render, compose, present, total, fps; headless shows present as "-", not run, and its
total leaves it out) is printed, and for live controls (stdin, UDP) the lines received and
bad; ``--stats`` prints a line a second.  The loop: :func:`lenticalib.render.pipeline.live.play_avatar`.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from .shared.avatar_options import add_avatar_arguments

    add_avatar_arguments(parser)
    out = parser.add_mutually_exclusive_group()
    out.add_argument("--display", metavar="SPEC", help="the panel's monitor: index, @X,Y or part of its name")
    out.add_argument("--preview", action="store_true", help="a normal window with the centre view, not the panel")
    out.add_argument("--headless", action="store_true", help="no output at all (timing)")
    parser.add_argument("--frames", type=int, metavar="N", help="stop after N frames (default: run until Esc)")
    parser.add_argument("--stats", action="store_true", help="print the stage times once a second")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import sys

    from ..render.pipeline.live import play_avatar
    from .shared.avatar_options import avatar_options, flags, warning_line
    from .shared.flags import flag_names

    def warn(text: str) -> None:  # the views that show nothing of the avatar come before the first frame
        print(f"lenticalib: warning: {warning_line(text)}", file=sys.stderr, flush=True)

    def stats(stages: dict) -> None:
        print("  ".join(f"{k} {v:.1f} ms" for k, v in stages.items()) + f"  total {sum(stages.values()):.1f} ms",
              flush=True)

    output = "headless" if args.headless else "preview" if args.preview else "panel"
    with flag_names({**flags(), "display": "--display"}):
        done = play_avatar(args.avatar, args.profile, options=avatar_options(args), output=output,
                           display=args.display, frames=args.frames, on_warning=warn,
                           on_stats=stats if args.stats else None)
    pipeline = done.session.pipeline
    profile, cameras = pipeline.profile, pipeline.cameras
    print(done.times.table(f"lenticalib play: {done.session.avatar.source}, {profile.views} views "
                           f"{cameras.width}x{cameras.height}, renderer {pipeline.renderer}, encoder "
                           f"{pipeline.encoder}, panel {profile.width}x{profile.height}, output {done.presenter_kind}"))
    if done.controls_summary:
        print(done.controls_summary)
    return 0
