#!/usr/bin/env python3
"""Write the student driver's demo: training and test videos of the demo avatar with their true controls.

    python tools/make_driver_demo.py DIR [--frames 7200] [--test-frames 600] [--seed 0] [--room 0] [--size 480x360]

DIR/train/ and DIR/test/ (frames, controls.csv, video.json: see
:mod:`lenticalib.sim.driver_video`), two different motions (seeds) in the same room (background),
so the test frames are frames a student trained on DIR/train never saw, as a user's call is, and DIR/test.avi, the test frames as a video (MJPEG)
for ``play --controls 'student:student.pt?video=DIR/test.avi'``.  Then:

    lenticalib driver distill --frames DIR/train --controls DIR/train/controls.csv --crop X,Y,W,H -o student.pt
    lenticalib driver predict student.pt --frames DIR/test -o predicted.csv

with X,Y,W,H the ``face_box`` this script prints.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> int:
    from lenticalib.core.sizes import parse_size
    from lenticalib.render.demo_avatar import make_demo_avatar
    from lenticalib.sim.driver_video import make_driver_video

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("directory")
    ap.add_argument("--frames", type=int, default=7200)
    ap.add_argument("--test-frames", type=int, default=600)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--room", type=int, default=0, help="the background's seed, one for both videos")
    ap.add_argument("--size", default="480x360")
    args = ap.parse_args()
    size = parse_size(args.size, "--size")
    root = Path(args.directory)
    root.mkdir(exist_ok=True)
    avatar = make_demo_avatar()
    for name, frames, seed in (("train", args.frames, args.seed), ("test", args.test_frames, args.seed + 1)):
        start = time.perf_counter()
        record = make_driver_video(root / name, frames=frames, seed=seed, size=size, avatar=avatar, room=args.room)
        print(f"wrote {root / name}: {frames} frames in {time.perf_counter() - start:.0f} s, face box "
              + ",".join(str(v) for v in record["face_box"]))
    import cv2

    writer = cv2.VideoWriter(str(root / "test.avi"), cv2.VideoWriter_fourcc(*"MJPG"), record["fps"], size)
    for frame in sorted((root / "test").glob("frame-*.jpg")):
        writer.write(cv2.imread(str(frame)))
    writer.release()
    print(f"wrote {root / 'test.avi'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
