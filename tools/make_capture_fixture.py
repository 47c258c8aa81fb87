#!/usr/bin/env python3
"""Generate the bundled synthetic capture set ``fixtures/capture-demo`` (deterministic).

A virtual 3840x2160, 32-view panel photographed with a 2.2-megapixel camera (a small file
size, not a limit of the fit): ``patterns.json``, ``captures/*.jpg`` (one per pattern),
``truth.json`` (the ideal profile for the camera) and ``simulation.json`` (every scene
parameter).  The pattern PNGs are not kept (``lenticalib patterns`` rewrites them); the fit
needs only the manifest and the photos.

    python tools/make_capture_fixture.py [--out fixtures/capture-demo] [--seed 2026]
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from lenticalib.calib.patterns.calibration_patterns import design_patterns
from lenticalib.core.pattern_sets import write_patterns
from lenticalib.sim.capture import simulate_capture_set
from lenticalib.sim.scene import random_scene


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="fixtures/capture-demo")
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--resolution", default="1800x1200", help="camera WxH")
    args = parser.parse_args()
    out = Path(args.out)
    if out.exists():
        shutil.rmtree(out)
    pattern_set = design_patterns(3840, 2160, 32)
    write_patterns(out, pattern_set)
    w, h = (int(v) for v in args.resolution.split("x"))
    scene = random_scene(args.seed, resolution=(w, h), jpeg_quality=88)
    info = simulate_capture_set(out, scene)
    for pattern in pattern_set.patterns:
        (out / pattern.file).unlink()
    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    print(f"wrote {out}: {info['photos']} photos, {size / 1e6:.1f} MB; truth {info['profile']}")


if __name__ == "__main__":
    main()
