#!/usr/bin/env python3
"""Benchmark the fast encoder: 32 views of 960x540 uint8 -> 3840x2160 panel, bilinear.

Prints the median over >= 20 timed runs after warm-up, peak memory, and -- measured in the same
run, interleaved with the encodes -- a plain ``numpy.copyto`` of the 3840x2160x3 output buffer
as the floor.  The last line is exactly ``encode_ms=<median> floor_ms=<median> ratio=<encode/floor>``.

    python tools/bench_encode.py [--runs 25] [--encoder fast] [--views 32] [--layout stripe|cells]
                                 [--view-size 960x540] [--kernel permute|gather|scalar]

``--layout cells`` gives the panel a Looking Glass style subpixel layout of two cells alternating
by column (R (-0.25, -0.31), G (-0.25, 0.28), B (0.25, 0) and the mirror image in x; pixels, y
down) instead of the RGB stripe.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time
import tracemalloc

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=25, help="timed runs (>= 20)")
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--encoder", default="fast")
    parser.add_argument("--views", type=int, default=32, help="view count N (32 is the target case)")
    parser.add_argument("--layout", choices=("stripe", "cells"), default="stripe",
                        help="RGB stripe panel, or two cells alternating by column")
    parser.add_argument("--view-size", default="960x540", help="view WxH (the panel is 3840x2160)")
    parser.add_argument("--kernel", choices=("permute", "gather", "scalar"),
                        help="force one kernel of the fast encoder (default: the fastest that applies)")
    args = parser.parse_args()
    view_w, view_h = (int(v) for v in args.view_size.lower().split("x"))
    runs = max(20, args.runs)

    import numba

    from lenticalib.core.layout import SubpixelLayout
    from lenticalib.core.profile import PanelProfile
    from lenticalib.render.encoders import encode
    from lenticalib.render.encoders.fast import encode_fast, usable_kernels

    layout = None
    if args.layout == "cells":
        layout = SubpixelLayout(cells=(((-0.25, -0.31), (-0.25, 0.28), (0.25, 0.0)),
                                       ((0.25, -0.31), (0.25, 0.28), (-0.25, 0.0))), pattern=((0, 1),))
    profile = PanelProfile(views=args.views, slant=0.1835, period=19.47, offset=7.3, reference_view=args.views / 2,
                           width=3840, height=2160, subpixel_order="RGB", subpixel_layout=layout)
    rng = np.random.default_rng(2026)
    views = rng.integers(0, 256, (args.views, view_h, view_w, 3), dtype=np.uint8)
    out = np.empty((2160, 3840, 3), dtype=np.uint8)
    src = rng.integers(0, 256, out.shape, dtype=np.uint8)  # touched pages: a real copy, not zero pages

    if args.kernel:  # the fast encoder's function itself, one kernel
        def run():
            encode_fast(views, profile, out, kernel=args.kernel)
    else:  # through the registry, as a caller does
        def run():
            encode(views, profile, args.encoder, out=out, allow_stretch=True)

    t0 = time.perf_counter()
    run()
    first = time.perf_counter() - t0
    for _ in range(args.warmup):
        run()
        np.copyto(out, src)

    enc_times, copy_times = [], []
    for _ in range(runs):
        t0 = time.perf_counter()
        run()
        enc_times.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        np.copyto(out, src)
        copy_times.append(time.perf_counter() - t0)

    tracemalloc.start()
    run()
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()

    enc_ms = statistics.median(enc_times) * 1000
    floor_ms = statistics.median(copy_times) * 1000
    kernel = args.kernel or (usable_kernels(views, profile)[0] if args.encoder == "fast" else "-")
    print(f"encoder={args.encoder} kernel={kernel} layout={args.layout} views={args.views}x{view_w}x{view_h} uint8 -> "
          f"3840x2160 bilinear, "
          f"threads={numba.get_num_threads()}, runs={runs}")
    print(f"first call (compile or cache load + tables): {first * 1000:.0f} ms")
    print(f"encode: median {enc_ms:.2f} ms, min {min(enc_times) * 1000:.2f} ms, max {max(enc_times) * 1000:.2f} ms")
    print(f"copy floor: median {floor_ms:.2f} ms")
    print(f"peak memory: {traced_peak / 2**20:.1f} MiB allocated during one encode (output preallocated); "
          f"process max RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")
    print(f"encode_ms={enc_ms:.3f} floor_ms={floor_ms:.3f} ratio={enc_ms / floor_ms:.2f}")


if __name__ == "__main__":
    main()
