#!/usr/bin/env python3
"""Benchmark the ``gl-compute`` renderer (compute shaders, tiles) against the ``gl`` triangles, same run.

The demo avatar (made on the fly), posed by the demo motion, N views on the LentiAvatar camera
arc (as tools/bench_gl_render.py); medians over ``--frames`` frames after ``--warmup``,
milliseconds, per path:

    render     ``render`` into the renderer's texture array, then ctx.finish(): what the live path
               pays (the views stay on the GPU)
    read       the read-back of the float views to numpy on top (tests and offline only)
    stages     the same render with ctx.finish() after each stage: triangles project / sort / draw;
               compute project / sort (depth) / intersect / tile_sort / composite
    psnr       the worst view's RGB PSNR against the ``cpu`` renderer (first frame; --skip-cpu: none)

    python tools/bench_gl_compute.py [--frames 5] [--warmup 1] [--count 100000] [--views 32]
                                     [--size 960x540] [--precision fp32|fp16] [--skip-cpu]
                                     [--paths triangles,compute]

The context is headless_context() (EGL: a GPU driver's, or Mesa's llvmpipe); the first lines say
which driver (GL_RENDERER, GL_VERSION) ran, and which path each row is (the triangles' sort
kind, and whether the compute path could run at all on this driver).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time


def _median_ms(samples: list[float]) -> float:
    return statistics.median(samples) if samples else float("nan")


def _worst_psnr(got, expected) -> float:
    import numpy as np

    worst = math.inf
    for view in range(len(got)):
        mse = float(np.mean((got[view, ..., :3].astype(np.float64) - expected[view, ..., :3]) ** 2))
        worst = min(worst, math.inf if mse == 0 else 10 * math.log10(1.0 / mse))
    return worst


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--warmup", type=int, default=1)
    parser.add_argument("--count", type=int, default=100_000, help="Gaussians in the demo avatar")
    parser.add_argument("--views", type=int, default=32)
    parser.add_argument("--size", default="960x540", help="view size WxH")
    parser.add_argument("--precision", choices=("fp32", "fp16"), default="fp32", help="the compute path's staging")
    parser.add_argument("--paths", default="triangles,compute", help="which paths to time, comma-separated")
    parser.add_argument("--skip-cpu", action="store_true", help="no cpu reference (no PSNR column)")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))
    paths = [p.strip() for p in args.paths.split(",") if p.strip()]

    from lenticalib.render.cameras.models import make_cameras
    from lenticalib.render.controls.streams import DemoControls
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.gpu.gl_context import headless_context
    from lenticalib.render.renderers.cpu import render_cpu
    from lenticalib.render.renderers.gl_compute import GLComputeRenderer, compute_missing
    from lenticalib.render.renderers.gl_renderer import GLSplatRenderer

    rig = make_demo_avatar(count=args.count)
    controls = DemoControls(rig.layout)
    posed = []
    for k in range(args.warmup + args.frames):
        _, vector = controls.latest(k / 30.0)
        posed.append(rig.deform(vector).to_numpy())
    cameras = make_cameras("arc", posed[0], args.views, view_size=(width, height))
    vm, ks = cameras.viewmats, cameras.K
    expected = None if args.skip_cpu else render_cpu(posed[0], vm, ks, width, height)

    ctx = headless_context()
    with ctx:
        print(f"demo avatar: {rig.count} Gaussians; {args.views} views {width}x{height}; "
              f"OpenGL: {ctx.info['GL_RENDERER']} ({ctx.info['GL_VERSION']})")
        missing = compute_missing(ctx)
        if missing:
            print(f"compute path cannot run on this driver: {missing}")
        makers = {"triangles": lambda: GLSplatRenderer(ctx, args.views, width, height),
                  "compute": lambda: GLComputeRenderer(ctx, args.views, width, height, precision=args.precision)}
        print(f"{'path':<22}{'render':>9}{'read':>8}{'project':>9}{'sort':>8}{'intersect':>10}{'tile_sort':>10}"
              f"{'draw/comp':>10}{'psnr':>7}   (ms, medians of {args.frames} frames)")
        for path in paths:
            if path == "compute" and missing:
                continue
            renderer = makers[path]()
            label = (f"gl triangles ({renderer.sort_kind} sort)" if path == "triangles"
                     else f"gl-compute {args.precision}")
            if getattr(renderer, "fallback_reason", None):
                print(renderer.fallback_reason)
            rows: dict[str, list[float]] = {}
            psnr = float("nan")
            for k, gaussians in enumerate(posed):
                t0 = time.perf_counter()
                renderer.render(gaussians, vm, ks)
                ctx.finish()
                t1 = time.perf_counter()
                out = renderer.read()
                t2 = time.perf_counter()
                if k == 0 and expected is not None:
                    psnr = _worst_psnr(out, expected)
                renderer.profile = True
                renderer.render(gaussians, vm, ks)
                renderer.profile = False
                if k >= args.warmup:
                    rows.setdefault("render", []).append(1e3 * (t1 - t0))
                    rows.setdefault("read", []).append(1e3 * (t2 - t1))
                    for name, ms in renderer.stage_ms.items():
                        rows.setdefault("draw" if name == "composite" else name, []).append(ms)
            renderer.release()
            cells = [_median_ms(rows.get(name, [])) for name in
                     ("render", "read", "project", "sort", "intersect", "tile_sort", "draw")]
            print(f"{label:<22}{cells[0]:9.1f}{cells[1]:8.1f}{cells[2]:9.1f}{cells[3]:8.1f}{cells[4]:10.1f}"
                  f"{cells[5]:10.1f}{cells[6]:10.1f}{psnr:7.1f}")
    ctx.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
