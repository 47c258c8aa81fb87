#!/usr/bin/env python3
"""Benchmark ``lenticalib avatar diagnose`` on the demo avatar: what the diagnostics cost beyond the render.

Makes the demo avatar (100k Gaussians, with its mesh) in a temporary folder, then runs
:func:`lenticalib.render.diagnose.avatars.diagnose_avatars` ``--repeats`` times (after one warm-up run
that compiles the numba kernels) and prints the medians of its stages: loading and posing (the
avatar file, its mesh, the checks), the render of every view with alpha, the mesh masks and the
crop, the seven metrics of every view, and the total beyond the render.

    python tools/bench_diagnose.py [--views 32] [--view-size 960x540] [--renderer cpu] [--repeats 5]

Target (issue 24): on 2 CPU cores, 32 views of 960 x 540 of the demo avatar diagnosed in under
10 s beyond the render.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> int:
    from lenticalib.core.sizes import parse_size
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.diagnose.avatars import DiagnoseOptions, diagnose_avatars
    from lenticalib.render.avatar.rig_file import save_rig

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--views", type=int, default=32)
    ap.add_argument("--view-size", default="960x540")
    ap.add_argument("--renderer", default="cpu")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    options = DiagnoseOptions(n_views=args.views, view_size=parse_size(args.view_size, "--view-size"),
                              renderer=args.renderer)
    with tempfile.TemporaryDirectory() as tmp:
        avatar = Path(tmp) / "demo.npz"
        save_rig(avatar, make_demo_avatar())
        rows = []
        for k in range(args.repeats + 1):
            start = time.perf_counter()
            result = diagnose_avatars([avatar], options=options)
            total = time.perf_counter() - start
            s = result["seconds"]
            if k:  # the first run compiles the kernels
                rows.append({"load and pose": total - s["render"] - s["masks"] - s["metrics"], "render": s["render"],
                             "masks and crop": s["masks"], "metrics": s["metrics"], "beyond the render": total - s["render"],
                             "total": total})
    print(f"demo avatar, {args.views} views of {args.view_size}, {args.renderer} renderer, median of {args.repeats} runs")
    for name in rows[0]:
        print(f"  {name:<18} {statistics.median(r[name] for r in rows):8.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
