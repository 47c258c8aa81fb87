#!/usr/bin/env python3
"""Benchmark quilt playback (``lenticalib show --profile``): a 4K 8x6 quilt video onto panel rasters.

Writes a synthetic 8x6 quilt video of 4096x4092 pixels (48 tiles of 512x682; moving gradients,
MPEG-4 part 2 in .mp4, ``--seconds`` at 30 fps) once, then plays it unpaced (every frame as fast
as it goes: decode on the reader thread, upload, GL encode into the presenter's framebuffer) into
an offscreen presenter for each raster size, ``--runs`` times, and prints the medians: playback
fps, decode-only fps (the reader alone), and the per-frame encode + present time.  The tiles are
stretched to each panel's aspect, as Looking Glass does with its 4K quilts.

    python tools/bench_show_quilt.py [--sizes 1536x2048,3840x2160] [--seconds 2] [--runs 3]
                                     [--encoder gl] [--display offscreen]

On Mesa (llvmpipe) the GL encoder runs on the CPU; on a GPU pass ``--display offscreen:egl``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

COLS, ROWS, TILE = 8, 6, (512, 682)  # (width, height) of a tile: 4096x4092


def write_video(path: Path, frames: int) -> None:
    import cv2
    import numpy as np

    width, height = COLS * TILE[0], ROWS * TILE[1]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30, (width, height))
    if not writer.isOpened():
        raise SystemExit("this OpenCV build writes no mp4v video")
    ys, xs = np.mgrid[0:height, 0:width]
    base = np.stack([xs // 4, ys // 4, (xs + ys) // 8], axis=-1).astype(np.uint8)  # gradients, wrapping
    step = np.array([4, 2, 8], np.uint8)
    for k in range(frames):
        writer.write(base + (step * k).astype(np.uint8))  # uint8: moves and wraps
    writer.release()


def panel(width: int, height: int):
    from lenticalib.core.profile import PanelProfile

    return PanelProfile(views=COLS * ROWS, slant=-0.1145, period=42.3, offset=7.5, reference_view=24,
                        width=width, height=height)


def decode_fps(items, profile) -> float:
    """Frames per second of the reader alone (decode, colour conversion, split into views)."""
    from lenticalib.render.pipeline.quilt_sources import FrameReader, QuiltMapping

    mapping = QuiltMapping(profile, items[0].grid, allow_stretch=True)
    count, start = 0, time.perf_counter()
    with FrameReader(items[0], mapping) as reader:
        while True:
            frame = reader.frames.get()
            reader.check()
            if frame.views is None:
                break
            count += 1
    return count / (time.perf_counter() - start)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="1536x2048,3840x2160")
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--encoder", default="gl")
    parser.add_argument("--display", default="offscreen")
    args = parser.parse_args()

    from lenticalib.render.present.displays import open_presenter
    from lenticalib.render.pipeline.quilt_player import play_quilts
    from lenticalib.render.pipeline.quilt_sources import quilt_items
    from lenticalib.render.compose.views import QuiltGrid

    with tempfile.TemporaryDirectory() as folder:
        video = Path(folder) / f"bench_qs{COLS}x{ROWS}a0.75.mp4"
        start = time.perf_counter()
        write_video(video, max(2, round(30 * args.seconds)))
        print(f"wrote {video.name}: {COLS * TILE[0]}x{ROWS * TILE[1]}, {round(30 * args.seconds)} frames "
              f"in {time.perf_counter() - start:.1f} s")
        for size in args.sizes.split(","):
            width, height = (int(v) for v in size.split("x"))
            profile = panel(width, height)
            items = quilt_items(video, QuiltGrid(COLS, ROWS), width / height)
            fps, frame_ms, decode = [], [], []
            for _ in range(args.runs):
                decode.append(decode_fps(items, profile))
                with open_presenter(args.display, (width, height), vsync=False) as presenter:
                    report = play_quilts(presenter, items, profile, encoder=args.encoder, fps=None,
                                         allow_stretch=True)
                fps.append(report.fps)
                frame_ms.append(statistics.median(list(report.present_ms)))
            print(f"{width}x{height} ({report.encoder}, {args.display}): playback {statistics.median(fps):.1f} fps "
                  f"(median of {args.runs}), decode alone {statistics.median(decode):.1f} fps, "
                  f"encode + present {statistics.median(frame_ms):.1f} ms a frame; "
                  f"{report.presented} presented, {report.dropped} dropped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
