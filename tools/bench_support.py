"""Helpers of the OpenGL renderer benchmarks (tools/bench_gl_render.py, tools/bench_gl_compute.py).

tools/ is on sys.path when a tool runs as a script, so a benchmark imports this as ``bench_support``.
The heavy imports (the library, numpy) happen inside the functions, after a tool has parsed its
arguments, so ``--help`` stays instant.
"""

from __future__ import annotations

import statistics
import time


def add_demo_arguments(parser) -> None:
    """The options every OpenGL renderer benchmark takes: --frames (timed), --warmup (frames before),
    --count (Gaussians in the demo avatar), --views (N), --size (view size "WxH", pixels)."""
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--warmup", type=int, default=1)
    parser.add_argument("--count", type=int, default=100_000, help="Gaussians in the demo avatar")
    parser.add_argument("--views", type=int, default=32)
    parser.add_argument("--size", default="960x540", help="view size WxH")


def view_size(text: str) -> tuple[int, int]:
    """(width, height) pixels of a "WxH" size (e.g. "960x540"; any case)."""
    width, height = (int(v) for v in text.lower().split("x"))
    return width, height


def median_ms(samples: list[float]) -> float:
    """The median of ``samples`` (milliseconds), NaN when there are none."""
    return statistics.median(samples) if samples else float("nan")


def posed_demo_frames(count: int, frames: int, views: int, width: int, height: int):
    """(rig, posed, viewmats, Ks): the demo avatar of ``count`` Gaussians (made on the fly), posed by
    the demo motion at 30 frames a second for ``frames`` frames (numpy Gaussians), and the
    LentiAvatar camera arc of ``views`` views of ``width`` x ``height`` pixels around the first pose
    (viewmats (N, 4, 4) world-to-camera, Ks (N, 3, 3) pixels)."""
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.cameras.models import make_cameras
    from lenticalib.render.controls.streams import DemoControls

    rig = make_demo_avatar(count=count)
    controls = DemoControls(rig.layout)
    posed = []
    for k in range(frames):
        _, vector = controls.latest(k / 30.0)
        posed.append(rig.deform(vector).to_numpy())
    cameras = make_cameras("arc", posed[0], views, view_size=(width, height))
    return rig, posed, cameras.viewmats, cameras.K


def time_renderer(ctx, renderer, posed, viewmats, Ks, warmup: int, on_read=None) -> dict[str, list[float]]:
    """Milliseconds per frame of ``posed`` after the first ``warmup``, by row: "render" (``render``
    then ctx.finish(): what the live path pays), "read" (the read-back to numpy on top), and one row
    per stage of the renderer's ``stage_ms`` (the same render again with ``profile`` set).
    ``on_read(k, views)`` sees every frame's read-back (the warm-up frames' too)."""
    rows: dict[str, list[float]] = {}
    for k, gaussians in enumerate(posed):
        t0 = time.perf_counter()
        renderer.render(gaussians, viewmats, Ks)
        ctx.finish()
        t1 = time.perf_counter()
        views = renderer.read()
        t2 = time.perf_counter()
        if on_read is not None:
            on_read(k, views)
        renderer.profile = True
        renderer.render(gaussians, viewmats, Ks)
        renderer.profile = False
        if k >= warmup:
            rows.setdefault("render", []).append(1e3 * (t1 - t0))
            rows.setdefault("read", []).append(1e3 * (t2 - t1))
            for name, ms in renderer.stage_ms.items():
                rows.setdefault(name, []).append(ms)
    return rows
