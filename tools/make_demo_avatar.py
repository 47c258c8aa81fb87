#!/usr/bin/env python3
"""Write the procedural demo avatar (lenticalib.render.avatar.demo_avatar) to a rig file.

    python tools/make_demo_avatar.py demo-avatar.npz [--seed 0] [--count 100000] [--json]

Takes a few seconds; the file (4.9 MB at 100k Gaussians) is not committed: generate it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", help="the rig file to write (.npz); its folder must exist")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--count", type=int, default=100_000, help="number of Gaussians (default 100000)")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    args = parser.parse_args(argv)

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))
    from lenticalib.core.errors import LenticalibError
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig

    try:
        started = time.perf_counter()
        rig = make_demo_avatar(seed=args.seed, count=args.count)
        built = time.perf_counter() - started
        save_rig(args.output, rig)
    except LenticalibError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    summary = {"output": args.output, "gaussians": rig.count, "controls": rig.control_dim,
               "layout": rig.layout.describe(), "blendshapes": rig.blendshape_count, "bones": list(rig.bone_names),
               "build_s": round(built, 2), "total_s": round(time.perf_counter() - started, 2),
               "bytes": os.path.getsize(args.output)}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"wrote {args.output}: {summary['gaussians']} Gaussians, {summary['bytes'] / 1e6:.1f} MB, "
              f"{summary['controls']} controls ({summary['layout']}), built in {summary['build_s']} s, "
              f"{summary['total_s']} s in all")
    return 0


if __name__ == "__main__":
    sys.exit(main())
