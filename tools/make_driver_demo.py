#!/usr/bin/env python3
"""Write the student driver's demo: training and test videos of the demo avatar with their true controls.

    python tools/make_driver_demo.py DIR [--frames 7200] [--test-frames 600] [--seed 0] [--room 0] [--size 480x360]

DIR/train/ and DIR/test/ (frames, controls.csv, video.json: see
:mod:`lenticalib.sim.driver_video`), two different motions (seeds) in the same room (background),
so the test frames are frames a student trained on DIR/train never saw, as a user's call is, and
DIR/test.avi, the test frames as a video (MJPEG) for
``play --controls 'student:student.pt?video=DIR/test.avi'``.  Then:

    lenticalib driver distill --frames DIR/train --controls DIR/train/controls.csv -o student.pt
    lenticalib driver predict student.pt --frames DIR/test -o predicted.csv

(``--crop auto``, the default, finds the face; ``--crop X,Y,W,H`` with the ``face_box`` this
script prints gives the avatar's true face box instead and spares the detector's time).

Time: about 55 ms a 480 x 360 frame on 2 idle cores (the defaults, 7800 frames, took 7 minutes;
several times that on a busy machine); it says so first, then a bar shows each video's frames on
a terminal, and a line every 10 % otherwise.  7200 training frames (four minutes of motion) is
what the README's measured student was trained on; ``--frames 1800`` makes a quicker demo
(about 2 minutes) to try the commands with, its student not measured.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SECONDS_PER_FRAME = 0.055  # 480 x 360 on 2 idle cores: 7800 frames in about 7 minutes


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], epilog=__doc__.split("\n", 3)[3],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("directory", metavar="DIR", help="the folder to write (train/, test/, test.avi); made if absent")
    ap.add_argument("--frames", type=int, default=7200, metavar="N",
                    help="training frames (30 a second; default 7200, four minutes of motion)")
    ap.add_argument("--test-frames", type=int, default=600, metavar="N",
                    help="test frames, another motion (default 600, twenty seconds)")
    ap.add_argument("--seed", type=int, default=0,
                    help="the training motion's seed; the test motion's is seed + 1 (default 0)")
    ap.add_argument("--room", type=int, default=0, help="the background's seed, one for both videos (default 0)")
    ap.add_argument("--size", default="480x360", metavar="WxH", help="frame size in pixels (default 480x360)")
    return ap


def parse_args(argv=None) -> argparse.Namespace:
    ap = build_parser()
    args = ap.parse_args(argv)
    if args.frames < 64 or args.test_frames < 1:
        ap.error("give --frames 64 or more (what distill needs) and --test-frames 1 or more")
    return args


class Progress:
    """A tqdm bar on a terminal; otherwise a line every 10 % of ``total`` frames."""

    def __init__(self, total: int, name: str):
        self.total, self.name, self.done, self.start = total, name, 0, time.perf_counter()
        self.bar = None
        if sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=name, unit="frame", leave=False, file=sys.stderr)

    def step(self) -> None:
        self.done += 1
        if self.bar is not None:
            self.bar.update(1)
        elif self.done * 10 // self.total != (self.done - 1) * 10 // self.total:
            print(f"  {self.name}: {self.done}/{self.total} frames, {time.perf_counter() - self.start:.0f} s",
                  flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def main(argv=None) -> int:
    args = parse_args(argv)
    from lenticalib.core.sizes import parse_size
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.sim.driver_video import make_driver_video

    size = parse_size(args.size, "--size")
    root = Path(args.directory)
    root.mkdir(exist_ok=True)
    total = args.frames + args.test_frames
    scale = size[0] * size[1] / (480 * 360)
    minutes = max(1, round(total * SECONDS_PER_FRAME * scale / 60))
    print(f"rendering {total} frames of {size[0]}x{size[1]} into {root}: about {minutes} minute"
          f"{'s' if minutes > 1 else ''} on 2 idle cores", flush=True)
    avatar = make_demo_avatar()
    for name, frames, seed in (("train", args.frames, args.seed), ("test", args.test_frames, args.seed + 1)):
        start = time.perf_counter()
        progress = Progress(frames, name)
        try:
            record = make_driver_video(root / name, frames=frames, seed=seed, size=size, avatar=avatar,
                                       room=args.room, step=progress.step)
        finally:
            progress.close()
        print(f"wrote {root / name}: {frames} frames in {time.perf_counter() - start:.0f} s, face box "
              + ",".join(str(v) for v in record["face_box"]), flush=True)
    import cv2

    writer = cv2.VideoWriter(str(root / "test.avi"), cv2.VideoWriter_fourcc(*"MJPG"), record["fps"], size)
    for frame in sorted((root / "test").glob("frame-*.jpg")):
        writer.write(cv2.imread(str(frame)))
    writer.release()
    print(f"wrote {root / 'test.avi'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
