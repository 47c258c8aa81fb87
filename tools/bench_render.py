#!/usr/bin/env python3
"""Benchmark the avatar pipeline: one line per device with render, encode, present, total and fps.

For the demo avatar (made on the fly, ~100k Gaussians) and the bundled 4K 32-view profile:
N = 32 views of 960x540 on the LentiAvatar camera arc, rendered, encoded into the 3840x2160
raster and presented (offscreen, so no monitor is needed), over ``--frames`` frames of the demo
motion after ``--warmup`` frames; medians in milliseconds.

    python tools/bench_render.py [--devices cpu,gl,cuda] [--frames 10] [--warmup 2] [--count 100000]

Devices: ``cpu`` runs the ``cpu`` renderer (numba) and the ``fast`` encoder; ``gl`` the ``gl``
renderer and encoder in the offscreen presenter's OpenGL context (a GPU driver, or Mesa's
llvmpipe on the CPU cores), the raster drawn straight into its framebuffer; ``cuda`` runs
``gsplat`` and the ``torch`` encoder (needs a CUDA GPU; a device that is not there is reported
on its line, not an error).  For ``gl`` render and encode are GL timer queries (GPU time) and
present the rest of the presenter's call; ``wall_ms`` is every row's wall-clock time per frame.
Targets (issue 11): on 2 CPU cores the cpu renderer <= 2 s per 32-view frame; on one H100 render
<= 10 ms, encode <= 1 ms, end to end >= 60 fps.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _pipeline_kind(device: str) -> tuple[str, str, str]:
    """(renderer, encoder, torch device) of a bench row."""
    if device == "cpu":
        return "cpu", "fast", "cpu"
    if device == "gl":
        return "gl", "gl", "cpu"
    return "gsplat", "torch", device


def bench_device(device: str, rig_path: Path, frames: int, warmup: int) -> str:
    from lenticalib.core.errors import LenticalibError
    from lenticalib.core.profile import load_profile
    from lenticalib.render.avatar.sources import load_avatar
    from lenticalib.render.cameras.models import make_cameras
    from lenticalib.render.controls.streams import DemoControls
    from lenticalib.render.pipeline.avatar_pipeline import AvatarPipeline
    from lenticalib.render.present.displays import open_presenter

    renderer, encoder, torch_device = _pipeline_kind(device)
    try:
        if device not in ("cpu", "gl"):
            import torch

            if not torch.cuda.is_available():
                return f"{device:<6} not available (torch sees no CUDA device)"
        profile = load_profile(REPO / "fixtures" / "panel-4k-32.json")
        avatar = load_avatar(rig_path)
        cameras = make_cameras("arc", avatar.bounding_box(), profile.views, view_size=(960, 540))
        pipeline = AvatarPipeline(avatar, profile, cameras, renderer=renderer, encoder=encoder, device=torch_device)
        controls = DemoControls(avatar.layout)
        presenter = open_presenter("offscreen", (profile.width, profile.height), vsync=False)
        rows, walls = [], []
        with presenter:
            pipeline.use_context(presenter.ctx)  # gl: render, encode and present in the presenter's context
            for k in range(warmup + frames):
                _, vector = controls.latest(k / 30.0)
                start = time.perf_counter()
                raster, _, stages = pipeline.frame(vector, raster_to_host=not pipeline.keeps_raster_on_gpu)
                pipeline.present(presenter, raster, stages)
                end = time.perf_counter()
                if k >= warmup:
                    rows.append(stages)
                    walls.append(1e3 * (end - start))
            pipeline.close()
        notes = "; ".join(pipeline.notes + presenter.notes)
    except LenticalibError as exc:
        return f"{device:<6} failed: {exc}"
    med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
    total = statistics.median(sum(r.values()) for r in rows)
    wall = statistics.median(walls)
    return (f"{device:<6} drive_ms {med['drive']:8.2f}  render_ms {med['render']:8.2f}  encode_ms {med['compose']:8.2f}"
            f"  present_ms {med['present']:7.2f}  total_ms {total:8.2f}  fps {1e3 / total:6.2f}"
            f"  wall_ms {wall:8.2f}  ({len(rows)} frames, {presenter.kind} presenter"
            + (f"; {notes}" if notes else "") + ")")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", default="cpu,gl,cuda")
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--warmup", type=int, default=1)
    parser.add_argument("--count", type=int, default=100_000, help="Gaussians in the demo avatar")
    args = parser.parse_args()

    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig

    with tempfile.TemporaryDirectory() as tmp:
        rig_path = Path(tmp) / "demo.npz"
        save_rig(rig_path, make_demo_avatar(count=args.count))
        print(f"demo avatar: {args.count} Gaussians; 32 views 960x540 -> 3840x2160 (fixtures/panel-4k-32.json)")
        for device in args.devices.split(","):
            print(bench_device(device.strip(), rig_path, args.frames, args.warmup), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
