#!/usr/bin/env python3
"""Benchmark the student driver on the demo: training time, held-out accuracy per group, inference speed.

Makes (or, with ``--keep DIR`` holding them, reuses) the demo videos of ``tools/make_driver_demo.py``
(a training video and a test video of another motion in the same room), distils a student on the training video
on the CPU (``--threads``, default 2: the acceptance's 2 cores) within ``--minutes``, predicts every test frame and
prints:

- training: seconds, epochs run, the best epoch;
- per group on the test frames (never seen in training): the mean absolute error in control units
  and as a share of each component's range (mean over the group's moving components); for the
  head, the geodesic angle between the predicted and the true head rotation (mean, 95th
  percentile, degrees);
- inference: median milliseconds per frame (crop and network, one 224 x 224 frame at a time) on
  the CPU with ``--threads`` threads, and on CUDA when torch sees a GPU.

    python tools/bench_driver.py [--keep DIR] [--frames 3600] [--test-frames 600] [--epochs 40]
                                 [--minutes 15] [--input-size 224] [--threads 2]

Targets (issue 25): trained in at most 15 minutes on 2 CPU cores; head pose under 2 degrees,
jaw and expression under 10 % of their range; inference at most 15 ms per frame on 2 cores (the
paper: 4.68 ms on an RTX 4090).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def rotation_angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Geodesic angle (degrees) between the rotations of axis-angle vectors a and b (T, 3)."""
    from scipy.spatial.transform import Rotation

    return np.degrees((Rotation.from_rotvec(a).inv() * Rotation.from_rotvec(b)).magnitude())


def main() -> int:
    import torch

    from lenticalib.render.controls import load_controls
    from lenticalib.render.rig import DEFAULT_LAYOUT
    from lenticalib.render.student.distill import DistillOptions, distill_student
    from lenticalib.render.student.frames import open_frames
    from lenticalib.render.student.predict import StudentPredictor
    from lenticalib.render.student.student_file import load_student

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--keep", help="folder for the demo videos and the student (reused when there)")
    ap.add_argument("--frames", type=int, default=3600)
    ap.add_argument("--test-frames", type=int, default=600)
    ap.add_argument("--epochs", type=int, default=40)
    ap.add_argument("--minutes", type=float, default=15.0, help="the training's time budget (0: none)")
    ap.add_argument("--input-size", type=int, default=224)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench-driver-"))
    if not (root / "test" / "video.json").exists():
        from lenticalib.render.demo_avatar import make_demo_avatar
        from lenticalib.sim.driver_video import make_driver_video

        root.mkdir(exist_ok=True)
        avatar = make_demo_avatar()
        for name, frames, seed in (("train", args.frames, 0), ("test", args.test_frames, 1)):
            start = time.perf_counter()
            make_driver_video(root / name, frames=frames, seed=seed, avatar=avatar)
            print(f"made {root / name}: {frames} frames, {time.perf_counter() - start:.0f} s", flush=True)
    box = json.loads((root / "train" / "video.json").read_text())["face_box"]
    options = DistillOptions(epochs=args.epochs, input_size=args.input_size, threads=args.threads,
                             minutes=args.minutes or None)

    def report(r):
        head = r["groups"].get("head", {})
        print(f"  epoch {r['epoch']:3d}  loss {r['training_loss']:.4f} / {r['validation_loss']:.4f}  head {head.get('mae_deg', 0):.2f} deg  "
              f"jaw {100 * r['groups'].get('jaw', {}).get('share_of_range', 0):.1f} %  "
              f"expression {100 * r['groups'].get('expression', {}).get('share_of_range', 0):.1f} %  "
              f"[{r['seconds']:.0f} s]" + (f"  (budget: {r['planned_epochs']} epochs)" if "planned_epochs" in r else ""),
              flush=True)

    summary = distill_student(root / "train", root / "train" / "controls.csv", root / "student.pt",
                              crop=",".join(map(str, box)), options=options, on_epoch=report)
    print(f"training: {summary['seconds']:.0f} s ({summary['seconds'] / 60:.1f} min), {summary['epochs']} epochs, "
          f"best {summary['best_epoch']}, {summary['train_frames']} frames ({args.threads} threads)")

    student = load_student(root / "student.pt")
    truth = load_controls(root / "test" / "controls.csv").controls
    train = load_controls(root / "train" / "controls.csv").controls
    span = train.max(0) - train.min(0)
    predictor = StudentPredictor(student)
    pred, ms = [], []
    for _, _, rgb in open_frames(root / "test"):
        pred.append(predictor.predict(rgb))
        ms.append(1e3 * predictor.seconds)
    pred = np.stack(pred)
    L = DEFAULT_LAYOUT
    print(f"held-out frames: {len(pred)} (a motion the student never saw)")
    print(f"  {'group':<12} {'MAE':>10} {'% of range':>11}")
    for name, _ in L.groups:
        s = L.slice(name)
        moving = span[s] > 1e-6
        if not moving.any():
            continue
        err = np.abs(pred[:, s] - truth[:, s])[:, moving]
        share = (err.mean(0) / span[s][moving]).mean()
        unit = " rad" if name in ("head", "jaw", "eyes", "neck") else (" m" if name == "translation" else "")
        print(f"  {name:<12} {err.mean():10.4f}{unit:<4} {100 * share:10.1f} %")
    angle = rotation_angle_deg(pred[:, L.slice("head")], truth[:, L.slice("head")])
    print(f"  head pose: geodesic error {angle.mean():.2f} deg mean, {np.percentile(angle, 95):.2f} deg at the "
          f"95th percentile")
    print(f"inference, {args.input_size} x {args.input_size}, one frame at a time (crop and network):")
    print(f"  cpu ({args.threads} threads): {statistics.median(ms[5:]):.1f} ms (median of {len(ms) - 5})")
    if torch.cuda.is_available():
        gpu = StudentPredictor(load_student(root / "student.pt"), "cuda")
        rgbs = [rgb for _, _, rgb in open_frames(root / "test")][:200]
        times = []
        for rgb in rgbs:
            gpu.predict(rgb)
            torch.cuda.synchronize()
            times.append(1e3 * gpu.seconds)
        print(f"  cuda ({torch.cuda.get_device_name()}): {statistics.median(times[10:]):.2f} ms")
    else:
        print("  cuda: not available (no GPU)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
