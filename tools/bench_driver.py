#!/usr/bin/env python3
"""Benchmark the student driver on the demo: training time, held-out accuracy per group, inference speed.

Makes (or, with ``--keep DIR`` holding them, reuses) the demo videos of ``tools/make_driver_demo.py``
(a training video, and ``--tests K`` test videos of other motions in the same room: ``test`` (seed 1),
``test-2`` (seed 2), ...), distils a student on the training video on the CPU (``--threads``, default 2:
the acceptance's 2 cores) within ``--minutes``, predicts every test frame and prints:

- training: seconds, epochs run, the best epoch;
- per test video and group (frames never seen in training): the mean absolute error in control
  units and as a share of each component's range (mean over the group's moving components); for
  the head, the geodesic angle between the predicted and the true head rotation (mean, 95th
  percentile, degrees); per moving expression component its share of range and its correlation
  with the truth (a component near 0 is not learnt, whatever the group's mean says);
- inference: median milliseconds per frame (crop and network, one 224 x 224 frame at a time) on
  the CPU with ``--threads`` threads, and on CUDA when torch sees a GPU.

    python tools/bench_driver.py [--keep DIR] [--frames 7200] [--test-frames 600] [--tests 3] [--epochs 40]
                                 [--minutes 15] [--input-size 224] [--threads 2] [--seed 0] [--student FILE]

``--student FILE`` measures a student already trained on DIR/train instead of training one.

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

    from lenticalib.render.controls.sources import load_controls
    from lenticalib.render.avatar.demo_avatar import DEMO_EXPRESSIONS
    from lenticalib.render.avatar.rig import DEFAULT_LAYOUT
    from lenticalib.render.student.distill import DistillOptions, distill_student
    from lenticalib.render.student.frames import open_frames
    from lenticalib.render.student.predict import StudentPredictor
    from lenticalib.render.student.student_file import load_student

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--keep", help="folder for the demo videos and the student (reused when there)")
    ap.add_argument("--frames", type=int, default=7200)
    ap.add_argument("--test-frames", type=int, default=600)
    ap.add_argument("--tests", type=int, default=3, help="test videos (motions never seen), seeds 1..K")
    ap.add_argument("--epochs", type=int, default=40)
    ap.add_argument("--minutes", type=float, default=15.0, help="the training's time budget (0: none)")
    ap.add_argument("--input-size", type=int, default=224)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0, help="the training's seed (initial weights, batches, augmentation)")
    ap.add_argument("--student", help="measure this student (trained on DIR/train) instead of training one")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench-driver-"))
    tests = ["test"] + [f"test-{k}" for k in range(2, args.tests + 1)]
    videos = [("train", args.frames, 0)] + [(name, args.test_frames, k + 1) for k, name in enumerate(tests)]
    missing = [v for v in videos if not (root / v[0] / "video.json").exists()]
    if missing:
        from lenticalib.render.avatar.demo_avatar import make_demo_avatar
        from lenticalib.sim.driver_video import make_driver_video

        root.mkdir(exist_ok=True)
        avatar = make_demo_avatar()
        for name, frames, seed in missing:
            start = time.perf_counter()
            make_driver_video(root / name, frames=frames, seed=seed, avatar=avatar)
            print(f"made {root / name}: {frames} frames, {time.perf_counter() - start:.0f} s", flush=True)
    box = json.loads((root / "train" / "video.json").read_text())["face_box"]
    options = DistillOptions(epochs=args.epochs, input_size=args.input_size, threads=args.threads,
                             minutes=args.minutes or None, seed=args.seed)

    def report(r):
        head = r["groups"].get("head", {})
        print(f"  epoch {r['epoch']:3d}  loss {r['training_loss']:.4f} / {r['validation_loss']:.4f}  head {head.get('mae_deg', 0):.2f} deg  "
              f"jaw {100 * r['groups'].get('jaw', {}).get('share_of_range', 0):.1f} %  "
              f"expression {100 * r['groups'].get('expression', {}).get('share_of_range', 0):.1f} %  "
              f"[{r['seconds']:.0f} s]" + (f"  (budget: {r['planned_epochs']} epochs)" if "planned_epochs" in r else ""),
              flush=True)

    student_path = Path(args.student) if args.student else root / "student.pt"
    if not args.student:
        summary = distill_student(root / "train", root / "train" / "controls.csv", student_path,
                                  crop=",".join(map(str, box)), options=options, on_epoch=report)
        print(f"training: {summary['seconds']:.0f} s ({summary['seconds'] / 60:.1f} min), {summary['epochs']} epochs, "
              f"best {summary['best_epoch']}, {summary['train_frames']} frames ({args.threads} threads)")
    student = load_student(student_path)
    train = load_controls(root / "train" / "controls.csv").controls
    span = train.max(0) - train.min(0)
    predictor = StudentPredictor(student)
    L = DEFAULT_LAYOUT
    names = list(L.default_names())
    for k, expression in enumerate(DEMO_EXPRESSIONS):
        names[L.slice("expression").start + k] = expression
    ms, groups = [], {}
    for name in tests:
        truth = load_controls(root / name / "controls.csv").controls
        pred = []
        for _, _, rgb in open_frames(root / name):
            pred.append(predictor.predict(rgb))
            ms.append(1e3 * predictor.seconds)
        pred = np.stack(pred)
        print(f"held-out video {name}: {len(pred)} frames (a motion the student never saw)")
        print(f"  {'group':<12} {'MAE':>10} {'% of range':>11}")
        for group, _ in L.groups:
            s = L.slice(group)
            moving = span[s] > 1e-6
            if not moving.any():
                continue
            err = np.abs(pred[:, s] - truth[:, s])[:, moving]
            share = (err.mean(0) / span[s][moving]).mean()
            groups.setdefault(group, []).append(share)
            unit = " rad" if group in ("head", "jaw", "eyes", "neck") else (" m" if group == "translation" else "")
            print(f"  {group:<12} {err.mean():10.4f}{unit:<4} {100 * share:10.1f} %")
        angle = rotation_angle_deg(pred[:, L.slice("head")], truth[:, L.slice("head")])
        groups.setdefault("head pose (deg)", []).append(angle.mean())
        print(f"  head pose: geodesic error {angle.mean():.2f} deg mean, {np.percentile(angle, 95):.2f} deg at the "
              f"95th percentile")
        s = L.slice("expression")
        parts = [f"{names[j]} {100 * np.abs(pred[:, j] - truth[:, j]).mean() / span[j]:.1f} % "
                 f"(r {np.corrcoef(pred[:, j], truth[:, j])[0, 1]:.2f})"
                 for j in range(s.start, s.stop) if span[j] > 1e-6]
        print("  expression components (share of range, correlation):", ", ".join(parts))
    if len(tests) > 1:
        print("worst of the test videos: " + ", ".join(
            f"{g} {max(v):.2f}" if g.endswith("(deg)") else f"{g} {100 * max(v):.1f} %" for g, v in groups.items()))
    print(f"inference, {args.input_size} x {args.input_size}, one frame at a time (crop and network):")
    print(f"  cpu ({args.threads} threads): {statistics.median(ms[5:]):.1f} ms (median of {len(ms) - 5})")
    if torch.cuda.is_available():
        gpu = StudentPredictor(load_student(student_path), "cuda")
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
