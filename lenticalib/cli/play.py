"""``lenticalib play``: the live loop drive -> render -> encode -> present, with per-stage timings.

Output: the panel (full screen, pixel-exact, through the presenter; the monitor whose mode is
the profile's size unless ``--display`` names one), ``--preview`` (a normal window showing the
centre view, for a desk without a panel) or ``--headless`` (no output: timing only).  Esc, q
or closing the window stops; ``--frames`` stops after that many.  On exit the stage table
(drive, render, compose, present, total, fps; headless shows present as "-", not run, and its
total leaves it out) is printed, and for live controls (stdin, UDP) the lines received and
bad; ``--stats`` prints a line a second.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ._avatar import add_avatar_arguments

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
    import time

    import numpy as np

    from ..core.errors import InputError
    from ..render.loop import StageTimes
    from ..render.present import WindowPresenter, open_presenter
    from ..render.present_offscreen import MemoryPresenter
    from ._avatar import build_pipeline

    if args.frames is not None and args.frames < 1:
        raise InputError(f"{args.frames} frames", source="--frames", hint="give at least 1")
    pipeline, controls, avatar = build_pipeline(args)
    profile, cameras = pipeline.profile, pipeline.cameras
    if pipeline.warning:
        print(f"lenticalib: warning: {pipeline.warning}", file=sys.stderr)
    if args.headless:
        presenter = MemoryPresenter((profile.width, profile.height))
    elif args.preview:
        presenter = WindowPresenter(None, windowed=(cameras.width, cameras.height))
    else:
        presenter = open_presenter(args.display, (profile.width, profile.height))
    centre = profile.views // 2
    times = StageTimes()
    start = last_report = time.perf_counter()
    with presenter:
        try:
            while args.frames is None or times.frames < args.frames:
                now = time.perf_counter() - start
                vector = controls.latest(now)[1] if controls is not None else None
                raster, views, stages = pipeline.frame(vector)
                t0 = time.perf_counter()
                if args.preview:
                    view = views[centre]
                    presenter.show(view if isinstance(view, np.ndarray) else view.cpu().numpy())
                elif not args.headless:  # headless presents nothing: no present stage
                    presenter.show(raster)
                if not args.headless:
                    stages["present"] = 1e3 * (time.perf_counter() - t0)
                times.add(**stages)
                if any(k in ("escape", "q") for k in presenter.keys()):
                    break
                if args.stats and time.perf_counter() - last_report >= 1.0:
                    last_report = time.perf_counter()
                    print("  ".join(f"{k} {v:.1f} ms" for k, v in stages.items())
                          + f"  total {sum(stages.values()):.1f} ms", flush=True)
        except KeyboardInterrupt:
            pass
        finally:
            if controls is not None:
                controls.close()
    print(times.table(f"lenticalib play: {avatar.source}, {profile.views} views {cameras.width}x{cameras.height}, "
                      f"renderer {pipeline.renderer}, encoder {pipeline.encoder}, panel {profile.width}x"
                      f"{profile.height}, output {presenter.kind}"))
    summary = controls.summary() if controls is not None else None
    if summary:
        print(summary)
    return 0
