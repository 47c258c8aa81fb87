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
import sys

# tools/ is on sys.path when a tool runs as a script
from bench_support import add_demo_arguments, median_ms, posed_demo_frames, time_renderer, view_size


def _worst_psnr(got, expected) -> float:
    import numpy as np

    worst = math.inf
    for view in range(len(got)):
        mse = float(np.mean((got[view, ..., :3].astype(np.float64) - expected[view, ..., :3]) ** 2))
        worst = min(worst, math.inf if mse == 0 else 10 * math.log10(1.0 / mse))
    return worst


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_demo_arguments(parser)
    parser.add_argument("--precision", choices=("fp32", "fp16"), default="fp32", help="the compute path's staging")
    parser.add_argument("--paths", default="triangles,compute", help="which paths to time, comma-separated")
    parser.add_argument("--skip-cpu", action="store_true", help="no cpu reference (no PSNR column)")
    args = parser.parse_args()
    width, height = view_size(args.size)
    paths = [p.strip() for p in args.paths.split(",") if p.strip()]

    from lenticalib.render.gpu.gl_context import headless_context
    from lenticalib.render.renderers.cpu import render_cpu
    from lenticalib.render.renderers.gl_compute import GLComputeRenderer, compute_missing
    from lenticalib.render.renderers.gl_renderer import GLSplatRenderer

    rig, posed, vm, ks = posed_demo_frames(args.count, args.warmup + args.frames, args.views, width, height)
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
            psnr = [float("nan")]

            def first_psnr(k, out):
                if k == 0 and expected is not None:
                    psnr[0] = _worst_psnr(out, expected)

            rows = time_renderer(ctx, renderer, posed, vm, ks, args.warmup, on_read=first_psnr)
            renderer.release()
            rows.setdefault("draw", rows.get("composite", []))  # the column "draw/comp"
            cells = [median_ms(rows.get(name, [])) for name in
                     ("render", "read", "project", "sort", "intersect", "tile_sort", "draw")]
            print(f"{label:<22}{cells[0]:9.1f}{cells[1]:8.1f}{cells[2]:9.1f}{cells[3]:8.1f}{cells[4]:10.1f}"
                  f"{cells[5]:10.1f}{cells[6]:10.1f}{psnr[0]:7.1f}")
    ctx.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
