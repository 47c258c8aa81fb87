#!/usr/bin/env python3
"""Benchmark ``lenticalib batch fit``: panels per hour on a local Dask cluster of 1 and 2 workers.

Simulates ``--panels`` capture sets with the virtual panel (seeds 1..P, a 640x360 panel with 8
views photographed at ``--resolution``, default 1200x900: the smallest set the fit takes), then,
for each worker count of ``--workers`` and ``--repeats`` times, fits them all into a fresh
output folder with :func:`lenticalib.calib.fleet.run.fit_fleet` (the library call of ``batch fit``,
a ``distributed.LocalCluster`` of that many one-thread processes) and times the whole call,
cluster start and summary included.  Prints one row per run, then per worker count the medians:
wall seconds, panels per hour, the median fit time per panel (the fit's own ``seconds``), and
the scaling (panels per hour over those of the first worker count).  Then what a 100-panel shift
needs: hours at each worker count, and workers for 100 panels in 8 hours at the measured
per-panel cost and at the cost of a 12 MP set (``--fit-seconds``, default 120 s: the issue's
30-200 s).

    python tools/bench_batch.py [--panels 4] [--workers 1,2] [--repeats 3] [--resolution 1200x900]
                                [--fit-seconds 120] [--keep DIR]

On a shared machine the numbers are under its load: run it on an idle one for a line's planning.
"""

from __future__ import annotations

import argparse
import math
import shutil
import statistics
import tempfile
import time
from pathlib import Path

W, H, VIEWS = 640, 360, 8
SHIFT_PANELS, SHIFT_HOURS = 100, 8.0


def simulate(root: Path, panels: int, resolution: tuple[int, int]) -> list[Path]:
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.sim.capture import simulate_capture_set
    from lenticalib.sim.scene import random_scene

    folders = []
    for seed in range(1, panels + 1):
        folder = root / f"panel-{seed:03d}"
        if not (folder / "captures").is_dir():
            write_patterns(folder, design_patterns(W, H, VIEWS))
            simulate_capture_set(folder, random_scene(seed, width=W, height=H, resolution=resolution, subsamples=1))
        folders.append(folder)
    return folders


def main() -> None:
    from lenticalib.calib.fleet.run import fit_fleet

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--panels", type=int, default=4)
    ap.add_argument("--workers", default="1,2", help="worker counts, comma-separated")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--resolution", default="1200x900", help="camera WxH")
    ap.add_argument("--fit-seconds", type=float, default=120.0, help="one 12 MP fit's CPU seconds, for the shift")
    ap.add_argument("--keep", metavar="DIR", help="keep (and reuse) the simulated sets in DIR")
    args = ap.parse_args()
    resolution = tuple(int(v) for v in args.resolution.lower().split("x"))
    counts = [int(v) for v in args.workers.split(",")]
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench-batch-"))
    root.mkdir(parents=True, exist_ok=True)
    try:
        t0 = time.perf_counter()
        folders = simulate(root / "sets", args.panels, resolution)
        print(f"{len(folders)} panels simulated at {resolution[0]}x{resolution[1]} ({time.perf_counter() - t0:.0f} s)")
        results: dict[int, list[tuple[float, float]]] = {n: [] for n in counts}
        for repeat in range(args.repeats):
            for n in counts:
                out = root / f"out-{n}-{repeat}"
                shutil.rmtree(out, ignore_errors=True)
                start = time.perf_counter()
                run = fit_fleet(folders, out, workers=n)
                wall = time.perf_counter() - start
                fit_s = statistics.median(r["seconds"] for r in run.rows if r.get("seconds") is not None)
                assert run.all_ok and run.summary["counts"]["fitted"] == len(folders), run.summary["counts"]
                results[n].append((wall, fit_s))
                print(f"run {repeat + 1}, {n} worker(s): {wall:.1f} s, {3600 * len(folders) / wall:.0f} panels/h, "
                      f"median fit {fit_s:.1f} s", flush=True)
        base = None
        per_hour = {}
        print("\nmedians:")
        for n in counts:
            wall = statistics.median(w for w, _ in results[n])
            fit_s = statistics.median(f for _, f in results[n])
            per_hour[n] = 3600 * len(folders) / wall
            base = base or per_hour[n]
            print(f"{n} worker(s): {wall:.1f} s for {len(folders)} panels, {per_hour[n]:.0f} panels/h, "
                  f"median fit {fit_s:.1f} s, scaling x{per_hour[n] / base:.2f}")
        print(f"\na shift of {SHIFT_PANELS} panels at these sets' cost:")
        for n in counts:
            print(f"  {n} worker(s): {SHIFT_PANELS / per_hour[n]:.2f} h")
        fit_s = statistics.median(f for _, f in results[counts[0]])  # one fit's time with the machine to itself
        needed = math.ceil(SHIFT_PANELS * args.fit_seconds / (SHIFT_HOURS * 3600))
        print(f"at {args.fit_seconds:.0f} s a panel (a 12 MP set; here {fit_s:.1f} s): {SHIFT_PANELS} panels need "
              f"{SHIFT_PANELS * args.fit_seconds / 3600:.1f} worker-hours, {needed} worker(s) for {SHIFT_HOURS:g} h")
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
