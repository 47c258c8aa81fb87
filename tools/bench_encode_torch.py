#!/usr/bin/env python3
"""Benchmark the torch encoder: 32 views of 960x540 uint8 -> 3840x2160 panel, bilinear, on a torch device.

The views are put on the device once; each timed run is one ``TorchEncoder.encode`` into a
preallocated raster on the device (no host transfer).  On CUDA each run is timed with CUDA events
(``torch.cuda.Event(enable_timing=True)``), on CPU with ``time.perf_counter``.  Prints the table
build time and size, and the median over the runs; the last line is exactly
``device=<cpu|cuda> dtype=<compute dtype> encode_ms=<median> table_bytes=<bytes>``.

    python tools/bench_encode_torch.py [--device cpu|cuda] [--dtype float64|float32|float16]
                                       [--runs 20] [--rows-per-chunk R] [--threads T] [--check]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu", help="cpu, cuda or cuda:K")
    parser.add_argument("--dtype", default="float64", choices=["float64", "float32", "float16"],
                        help="compute precision (float64: bit-identical to the reference)")
    parser.add_argument("--runs", type=int, default=20, help="timed runs (>= 5)")
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--views", type=int, default=32, help="view count N (32 is the target case)")
    parser.add_argument("--rows-per-chunk", type=int, default=None, help="panel rows per pass (default: encoder's)")
    parser.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's)")
    parser.add_argument("--check", action="store_true", help="also compare one raster with the tables encoder")
    args = parser.parse_args()
    runs = max(5, args.runs)

    import torch

    if args.threads:
        torch.set_num_threads(args.threads)
    from lenticalib.core.profile import PanelProfile
    from lenticalib.render.encoders.torch_encoder import TorchEncoder

    profile = PanelProfile(views=args.views, slant=0.1835, period=19.47, offset=7.3, reference_view=args.views / 2,
                           width=3840, height=2160, subpixel_order="RGB")
    rng = np.random.default_rng(2026)
    host_views = rng.integers(0, 256, (args.views, 540, 960, 3), dtype=np.uint8)

    t0 = time.perf_counter()
    encoder = TorchEncoder(profile, (540, 960), args.device, getattr(torch, args.dtype),
                           rows_per_chunk=args.rows_per_chunk)
    build = time.perf_counter() - t0
    device = encoder.device
    views = torch.from_numpy(host_views).to(device)
    out = torch.empty((2160, 3840, 3), dtype=torch.uint8, device=device)
    cuda = device.type == "cuda"

    for _ in range(args.warmup):
        encoder.encode(views, out=out)
    times = []
    if cuda:
        torch.cuda.synchronize(device)
        events = [(torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)) for _ in range(runs)]
        for start, stop in events:
            start.record()
            encoder.encode(views, out=out)
            stop.record()
        torch.cuda.synchronize(device)
        times = [start.elapsed_time(stop) for start, stop in events]  # ms
    else:
        for _ in range(runs):
            t0 = time.perf_counter()
            encoder.encode(views, out=out)
            times.append((time.perf_counter() - t0) * 1000)

    subpixels = 3 * profile.width * profile.height
    median = statistics.median(times)
    print(f"torch {torch.__version__} on {device}"
          + (f" ({torch.cuda.get_device_name(device)})" if cuda else f", {torch.get_num_threads()} threads")
          + f"; views {args.views}x960x540 uint8 -> 3840x2160, compute {args.dtype}, "
            f"rows per chunk {encoder.rows_per_chunk}, runs {runs}")
    print(f"tables: {encoder.table_bytes / 1e6:.1f} MB ({encoder.table_bytes / subpixels:.2f} bytes per subpixel, "
          f"{subpixels / 1e6:.1f} M subpixels), built in {build:.2f} s")
    print(f"encode: median {median:.3f} ms, min {min(times):.3f} ms, max {max(times):.3f} ms "
          f"({'CUDA events' if cuda else 'perf_counter'})")
    if args.check:
        from lenticalib.render.encoders import encode

        same = np.array_equal(out.cpu().numpy(), encode(host_views, profile, "tables"))
        print(f"equal to the tables (= reference) encoder: {same}")
    print(f"device={device.type} dtype={args.dtype} encode_ms={median:.3f} table_bytes={encoder.table_bytes}")


if __name__ == "__main__":
    main()
