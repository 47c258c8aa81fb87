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
import statistics
import sys
import time


def _median_ms(samples: list[float]) -> float:
    return 1e3 * statistics.median(samples)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--warmup", type=int, default=1)
    parser.add_argument("--count", type=int, default=100_000, help="Gaussians in the demo avatar")
    parser.add_argument("--views", type=int, default=32)
    parser.add_argument("--size", default="960x540", help="view size WxH")
    parser.add_argument("--sort", choices=("gpu", "cpu"), default=None, help="default: gpu where OpenGL 4.3 is")
    parser.add_argument("--skip-cpu", action="store_true", help="time the gl renderer only")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))

    import numba

    from lenticalib.render.cameras.models import make_cameras
    from lenticalib.render.controls.streams import DemoControls
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.gpu.gl_context import headless_context
    from lenticalib.render.renderers.cpu import render_cpu
    from lenticalib.render.renderers.gl_renderer import GLSplatRenderer

    rig = make_demo_avatar(count=args.count)
    controls = DemoControls(rig.layout)
    posed = []
    for k in range(args.warmup + args.frames):
        _, vector = controls.latest(k / 30.0)
        posed.append(rig.deform(vector).to_numpy())
    cameras = make_cameras("arc", posed[0], args.views, view_size=(width, height))
    vm, ks = cameras.viewmats, cameras.K

    ctx = headless_context()
    with ctx:
        renderer = GLSplatRenderer(ctx, args.views, width, height, sort=args.sort)
        print(f"demo avatar: {rig.count} Gaussians; {args.views} views {width}x{height}; "
              f"{numba.get_num_threads()} numba threads; OpenGL: {ctx.info['GL_RENDERER']}, "
              f"sort {renderer.sort_kind}")
        if renderer.fallback_reason:
            print(renderer.fallback_reason)
        rows: dict[str, list[float]] = {"gl": [], "read": [], "project": [], "sort": [], "draw": [], "cpu": []}
        for k, gaussians in enumerate(posed):
            t0 = time.perf_counter()
            renderer.render(gaussians, vm, ks)
            ctx.finish()
            t1 = time.perf_counter()
            renderer.read()
            t2 = time.perf_counter()
            renderer.profile = True
            renderer.render(gaussians, vm, ks)
            renderer.profile = False
            if k >= args.warmup:
                rows["gl"].append(t1 - t0)
                rows["read"].append(t2 - t1)
                for name, ms in renderer.stage_ms.items():
                    rows[name].append(ms / 1e3)
        renderer.release()
    if not args.skip_cpu:
        for k, gaussians in enumerate(posed):
            t0 = time.perf_counter()
            render_cpu(gaussians, vm, ks, width, height)
            if k >= args.warmup:
                rows["cpu"].append(time.perf_counter() - t0)
    n = len(rows["gl"])
    if rows["cpu"]:
        print(f"cpu    render_ms {_median_ms(rows['cpu']):9.1f}                       ({n} frames)")
    print(f"gl     render_ms {_median_ms(rows['gl']):9.1f}  read_ms {_median_ms(rows['read']):7.1f}"
          f"        ({n} frames)")
    print(f"gl split  project_ms {_median_ms(rows['project']):8.1f}  sort_ms {_median_ms(rows['sort']):8.1f}"
          f"  draw_ms {_median_ms(rows['draw']):8.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
