#!/usr/bin/env python3
"""Benchmark ``lenticalib fit`` on virtual panels with subpixel layouts (and stripes).

For every layout x seed x slant sign: draw a random scene with that seed (``random_scene``: its
period, offset, camera position, blur, noise and JPEG; the drawn |C_r| with the given sign) on
a panel with the layout, photograph the calibration patterns with the cell patterns
(``design_patterns(..., cells=True)``), fit, and compare with the truth over every subpixel.

Prints one row per set: the layout the fit found and whether it is the true one (stripe order,
or the same grouping of cell classes into cells), the largest error of a slot shift
(subpixels, in the layout's gauge: :func:`lenticalib.calib.routing.layout_fit.shift_error`) and its ratio
to the reported 1-sigma, and the routing error in views: non-uniformity RMS and worst, centring.
Targets: RMS <= 0.05, worst <= 0.15, |centring| <= 0.25 view, layout recovered.

    python tools/bench_layouts.py [--seeds 1-4] [--layouts lkg-columns,lkg-checker,lkg-rows4,RGB,BGR]
                                  [--signs +,-] [--panel 1280x720] [--resolution 1250x800]
                                  [--subsamples 1] [--keep DIR [--reuse]] [--jobs 1]

The defaults keep a run of the 5 x 4 x 2 sets near half an hour on two cores: a 1280x720 panel
(the simulated panel's size does not change the method) photographed at 1 megapixel with one
ray per camera pixel, as the test suite's simulated sets are.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

from bench_fit import parse_seeds  # tools/ is on sys.path when a tool runs as a script


def run_one(layout_name: str, seed: int, sign: float, root: Path, panel, resolution, subsamples: int,
            reuse: bool) -> dict:
    from lenticalib.calib.routing.compare import compare_profiles
    from lenticalib.calib.routing.fit import fit_capture_set
    from lenticalib.calib.routing.layout_fit import same_cells, shift_error
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.errors import LenticalibError
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.core.profile import load_profile
    from lenticalib.sim.capture import simulate_capture_set
    from lenticalib.sim.layouts import resolve_layout
    from lenticalib.sim.scene import random_scene

    order, layout = resolve_layout(layout_name)
    width, height = panel
    drawn = random_scene(seed, width=width, height=height, resolution=resolution)
    scene = random_scene(seed, width=width, height=height, resolution=resolution, subsamples=subsamples,
                         slant=sign * abs(drawn.optics.slant), order=None if layout else order, layout=layout)
    folder = root / f"{layout_name}-{seed:03d}-{'p' if sign > 0 else 'm'}"
    done = folder / "simulation.json"
    pattern_set = design_patterns(width, height, 32, cells=True)
    t_sim = 0.0
    record = json.loads(done.read_text()) if reuse and done.exists() else {}
    if not (record.get("status") == "complete" and record["scene"] == scene.to_dict()
            and record["pattern_set"]["set_id"] == pattern_set.set_id):  # the same scene and patterns
        if folder.exists():
            shutil.rmtree(folder)
        write_patterns(folder, pattern_set)
        t0 = time.perf_counter()
        simulate_capture_set(folder, scene)
        t_sim = time.perf_counter() - t0
    truth = load_profile(folder / "truth.json")
    row = {"layout": layout_name, "seed": seed, "slant": truth.slant, "period": truth.period, "sim_s": t_sim}
    t0 = time.perf_counter()
    try:
        result = fit_capture_set(folder)
    except LenticalibError as exc:
        row.update(found="refused: " + exc.message, ok=False, fit_s=time.perf_counter() - t0)
        return row
    fitted = result.profile
    diff = compare_profiles(fitted, truth)
    decision = result.layout
    err = shift_error(fitted, truth)
    sigma = float(decision.cell_sigma.max()) if decision is not None else float("nan")
    found = fitted.layout_name if fitted.is_stripe else \
        "cells " + "/".join("".join(map(str, r)) for r in fitted.subpixel_layout.pattern)
    if truth.is_stripe:
        recovered = fitted.is_stripe and fitted.subpixel_order == truth.subpixel_order
    else:
        recovered = not fitted.is_stripe and same_cells(fitted, truth) and err <= max(3 * sigma, 0.06)
    row.update(found=found, recovered=recovered, shift_err=err, shift_sigma=sigma, rms=diff.rms, worst=diff.worst,
               centring=diff.centring, trusted=result.trusted, problems=result.problems,
               fit_s=time.perf_counter() - t0)
    row["ok"] = (recovered and result.trusted and diff.rms <= 0.05 and diff.worst <= 0.15
                 and abs(diff.centring) <= 0.25)
    return row


def _print_row(row: dict) -> None:
    if "rms" not in row:
        print(f"{row['layout']:>12} {row['seed']:>4} {row['slant']:+7.3f} {row['period']:7.3f}  {row['found']}  NO",
              flush=True)
        return
    print(f"{row['layout']:>12} {row['seed']:>4} {row['slant']:+7.3f} {row['period']:7.3f} {row['found']:>14} "
          f"{'yes' if row['recovered'] else 'NO':>4} {row['shift_err']:6.3f} {row['shift_sigma']:6.3f} "
          f"{row['rms']:6.4f} {row['worst']:6.4f} {row['centring']:+7.4f} {row['fit_s']:5.1f} "
          f"{'yes' if row['ok'] else 'NO'}{'' if row['trusted'] else ' (untrusted: ' + '; '.join(row['problems']) + ')'}",
          flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1-4", help="seeds, e.g. 1-4 or 3,5,8")
    parser.add_argument("--layouts", default="lkg-columns,lkg-checker,lkg-rows4,RGB,BGR",
                        help="comma-separated layouts: RGB, BGR, names of lenticalib.sim.layouts or JSON files")
    parser.add_argument("--signs", default="+,-", help="slant signs to run: +, - or both")
    parser.add_argument("--panel", default="1280x720", help="panel raster WxH")
    parser.add_argument("--resolution", default="1250x800", help="camera WxH")
    parser.add_argument("--subsamples", type=int, default=1, help="rays per camera pixel side")
    parser.add_argument("--keep", metavar="DIR", help="keep the capture sets in DIR")
    parser.add_argument("--reuse", action="store_true", help="with --keep: fit sets already simulated there")
    parser.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    parser.add_argument("--jobs", type=int, default=1, help="sets run at once (processes; rows print as they end)")
    args = parser.parse_args()
    panel = tuple(int(v) for v in args.panel.split("x"))
    resolution = tuple(int(v) for v in args.resolution.split("x"))
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="lenticalib-layouts-"))
    root.mkdir(parents=True, exist_ok=True)
    print(f"{'layout':>12} {'seed':>4} {'C_r':>7} {'Delta_r':>7} {'found':>14} {'rec':>4} {'e err':>6} {'sigma':>6} "
          f"{'rms':>6} {'worst':>6} {'centre':>7} {'fit s':>5} ok", flush=True)
    rows = []
    tasks = [(layout_name, seed, -1.0 if sign.strip() == "-" else 1.0, root, panel, resolution, args.subsamples,
              args.reuse)
             for layout_name in args.layouts.split(",") for seed in parse_seeds(args.seeds)
             for sign in args.signs.split(",")]
    try:
        if args.jobs <= 1:
            for task in tasks:
                rows.append(run_one(*task))
                _print_row(rows[-1])
        else:
            with concurrent.futures.ProcessPoolExecutor(args.jobs) as pool:
                for future in concurrent.futures.as_completed([pool.submit(run_one, *task) for task in tasks]):
                    rows.append(future.result())
                    _print_row(rows[-1])
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))
    fitted = [r for r in rows if "rms" in r]
    if fitted:
        print(f"max: rms {max(r['rms'] for r in fitted):.4f}  worst {max(r['worst'] for r in fitted):.4f}  "
              f"|centring| {max(abs(r['centring']) for r in fitted):.4f}  "
              f"shift error / sigma {max(r['shift_err'] / r['shift_sigma'] for r in fitted):.2f}")
    passed = sum(r["ok"] for r in rows)
    print(f"sets meeting every target and recovering the layout: {passed}/{len(rows)}")
    return 0 if passed == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
