#!/usr/bin/env python3
"""Benchmark the ``gl`` renderer against the numba ``cpu`` renderer in the same run.

The demo avatar (made on the fly, ~100k Gaussians), posed by the demo motion, N = 32 views of
960x540 on the LentiAvatar camera arc (as tools/bench_render.py); medians over ``--frames``
frames after ``--warmup`` frames, milliseconds:

    cpu      render_cpu, the numpy result
    gl       GLSplatRenderer.render into its texture array, finished (ctx.finish()): what the live
             path pays, the views staying on the GPU; ``read`` the read-back to numpy on top
    split    the same render with ctx.finish() between the stages (project, sort, draw; with the
             CPU sort, project = the host's projection and order, sort = gathering the records)

    python tools/bench_gl_render.py [--frames 5] [--warmup 1] [--count 100000] [--views 32]
                                    [--size 960x540] [--sort gpu|cpu] [--skip-cpu]

The OpenGL context is headless_context() (EGL: a GPU driver's, or Mesa's llvmpipe on the CPU);
its renderer string is printed with the numbers.
"""

from __future__ import annotations

import argparse
import sys
import time

# tools/ is on sys.path when a tool runs as a script
from bench_support import add_demo_arguments, median_ms, posed_demo_frames, time_renderer, view_size


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_demo_arguments(parser)
    parser.add_argument("--sort", choices=("gpu", "cpu"), default=None, help="default: gpu where OpenGL 4.3 is")
    parser.add_argument("--skip-cpu", action="store_true", help="time the gl renderer only")
    args = parser.parse_args()
    width, height = view_size(args.size)

    import numba

    from lenticalib.render.gpu.gl_context import headless_context
    from lenticalib.render.renderers.cpu import render_cpu
    from lenticalib.render.renderers.gl_renderer import GLSplatRenderer

    rig, posed, vm, ks = posed_demo_frames(args.count, args.warmup + args.frames, args.views, width, height)

    ctx = headless_context()
    with ctx:
        renderer = GLSplatRenderer(ctx, args.views, width, height, sort=args.sort)
        print(f"demo avatar: {rig.count} Gaussians; {args.views} views {width}x{height}; "
              f"{numba.get_num_threads()} numba threads; OpenGL: {ctx.info['GL_RENDERER']}, "
              f"sort {renderer.sort_kind}")
        if renderer.fallback_reason:
            print(renderer.fallback_reason)
        rows = time_renderer(ctx, renderer, posed, vm, ks, args.warmup)
        renderer.release()
    rows["cpu"] = []
    if not args.skip_cpu:
        for k, gaussians in enumerate(posed):
            t0 = time.perf_counter()
            render_cpu(gaussians, vm, ks, width, height)
            if k >= args.warmup:
                rows["cpu"].append(1e3 * (time.perf_counter() - t0))
    ms = {name: median_ms(rows.get(name, [])) for name in ("cpu", "render", "read", "project", "sort", "draw")}
    n = len(rows.get("render", []))
    if rows["cpu"]:
        print(f"cpu    render_ms {ms['cpu']:9.1f}                       ({n} frames)")
    print(f"gl     render_ms {ms['render']:9.1f}  read_ms {ms['read']:7.1f}        ({n} frames)")
    print(f"gl split  project_ms {ms['project']:8.1f}  sort_ms {ms['sort']:8.1f}  draw_ms {ms['draw']:8.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
