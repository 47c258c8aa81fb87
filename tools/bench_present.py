#!/usr/bin/env python3
"""Benchmark the presenter: upload + present time of a panel raster, and frames per second.

Shows ``--frames`` different 3840x2160 RGB8 rasters (two alternating random ones, so nothing
is cached) and prints the medians of the upload (host -> pixel buffer -> texture), present
(draw + swap, each finished on the GPU) and their sum, and the frame rate that sum allows.

    python tools/bench_present.py [--display SPEC | --display offscreen[:egl]] [--frames 120]
                                  [--size 3840x2160] [--no-vsync]

On a machine with no monitor: run it under Xvfb with a screen of the raster's size
(``xvfb-run -s "-screen 0 3840x2160x24" python tools/bench_present.py``; CPU rendering by
Mesa), or with ``--display offscreen:egl`` on a headless GPU.  Vsync is on by default for a
window (the display's refresh paces the frames); pass ``--no-vsync`` to time the pipeline.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--display", default=None, help="monitor, or offscreen[:egl]")
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--size", default="3840x2160")
    parser.add_argument("--no-vsync", action="store_true")
    args = parser.parse_args()

    import numpy as np

    from lenticalib.core.errors import LenticalibError
    from lenticalib.render.present.displays import open_presenter

    width, height = (int(v) for v in args.size.split("x"))
    rng = np.random.default_rng(0)
    rasters = [rng.integers(0, 256, (height, width, 3), dtype=np.uint8) for _ in range(2)]
    try:
        presenter = open_presenter(args.display, (width, height), vsync=not args.no_vsync)
        with presenter:
            info = presenter.ctx.info
            for k in range(5):  # warm-up: first texture allocation, shader compile
                presenter.show(rasters[k % 2])
            presenter.timings.clear()
            start = time.perf_counter()
            for k in range(args.frames):
                presenter.show(rasters[k % 2])
            wall = time.perf_counter() - start
            timings = list(presenter.timings)
    except LenticalibError as exc:
        print(f"bench_present: {exc}", file=sys.stderr)
        return 2
    upload = statistics.median(t.upload_ms for t in timings)
    present = statistics.median(t.present_ms for t in timings)
    total = statistics.median(t.upload_ms + t.present_ms for t in timings)
    print(f"presenter {presenter.kind} ({info.get('GL_RENDERER', '?')}), {width}x{height} RGB8, "
          f"{len(timings)} frames, vsync {'on' if presenter.vsync else 'off'}")
    print(f"median upload {upload:.2f} ms, present {present:.2f} ms, upload+present {total:.2f} ms "
          f"-> {1e3 / total:.1f} frames/s (wall: {len(timings) / wall:.1f} frames/s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
