#!/usr/bin/env python3
"""Measure ``crosstalk measure``'s routing check on right sets and on sets photographed through a
profile that is not the panel's (issue 45; the table in docs/crosstalk.md, "Photos that do not
follow the profile").

Small sets (a 1280x720 panel with 32 views photographed at 1500x1000, 2 rays per pixel side,
16-bit linear photos unless the name ends in "-jpeg"): right sets (the truth profile with a fit's
errors, "-fit": fitted from photos of the calibration patterns; bench cases of
tools/bench_crosstalk.py at this size) and mismatched ones (scene 31 photographed through its
truth profile with the period, slant, offset or view count changed; another virtual panel's
profile).  Every set is measured with ``force=True`` and prints one JSON line: the values the
check judged (``routing_check.judged``), the measurement's own smear, residual and own-view share
against the truth for the profile the patterns were drawn from, and the verdict.  A set the
band-photo check refuses prints its refusal.

    python tools/bench_crosstalk_routing.py --keep DIR [NAME ...]     (all sets: some 15 minutes on 2 cores)
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

W, H, RES, VIEWS = 1280, 720, (1500, 1000), 32
BENCH = [(101, 0.15, +1, "RGB", 400.0, {}), (102, 0.35, -1, "BGR", 900.0, {}), (104, 0.35, +1, "RGB", 750.0, {}),
         (105, 0.25, +1, "BGR", 500.0, {}), (106, 0.25, -1, "RGB", 850.0, {}), (107, 0.18, +1, "BGR", 700.0, {}),
         (108, 0.32, -1, "RGB", 450.0, {}), (109, 0.60, +1, "RGB", 850.0, {}),
         (110, 0.70, -1, "BGR", 700.0, {"blur_growth": 1.5}), (111, 0.50, +1, "BGR", 800.0, {"offset": 180.0})]


def _scene(seed, **kw):
    from lenticalib.sim.scene import random_scene

    kw.setdefault("subsamples", 2)
    return random_scene(seed, width=W, height=H, resolution=RES, **kw)


def _fitted(truth):
    """The truth with a fit's errors (as tests/test_crosstalk.py's profile)."""
    return truth.replace(offset=truth.offset + 0.05 * truth.period / VIEWS, period=truth.period * (1 + 2e-6))


def cases() -> dict:
    """name -> (scene, profile or "fit", raw)."""
    s31 = _scene(31, distance=620.0)
    t31 = s31.truth_profile(VIEWS)
    out = {"right-31": (s31, _fitted(t31), True), "right-31-jpeg": (s31, _fitted(t31), False),
           "right-31-fit": (s31, "fit", True)}
    for seed, blur, sign, order, distance, fixed in BENCH:
        draw = _scene(seed)
        scene = _scene(seed, blur=(blur, blur), order=order, distance=distance, slant=sign * abs(draw.optics.slant),
                       **fixed)
        out[f"right-{seed}"] = (scene, _fitted(scene.truth_profile(VIEWS)), True)
    out["right-109-fit"] = (out["right-109"][0], "fit", True)
    hard = _scene(103, conditions="hard")
    out["right-103-hard-jpeg"] = (hard, _fitted(hard.truth_profile(VIEWS)), False)
    for factor in (0.9995, 1.0005, 1.001, 1.003, 1.01, 1.03):
        out[f"period-x{factor}"] = (s31, t31.replace(period=t31.period * factor), True)
    for change in (0.0005, 0.001, 0.002, 0.01):
        out[f"slant+{change}"] = (s31, t31.replace(slant=t31.slant + change), True)
    out["slant-negated"] = (s31, t31.replace(slant=-t31.slant), True)
    for name, part in (("quarter", 0.25), ("half", 0.5)):
        out[f"offset-{name}-view"] = (s31, t31.replace(offset=t31.offset + part * t31.period / VIEWS), True)
    out["views-24"], out["views-40"] = (s31, s31.truth_profile(24), True), (s31, s31.truth_profile(40), True)
    s1, s3 = _scene(1), _scene(3)
    out["panel31-through-panel1-profile"] = (s31, _fitted(s1.truth_profile(VIEWS)), True)
    out["panel1-through-panel3-profile"] = (s1, _fitted(s3.truth_profile(VIEWS)), True)  # the case
    out["panel1-through-panel3-profile-jpeg"] = (s1, _fitted(s3.truth_profile(VIEWS)), False)
    return out


def run(name: str, scene, profile, raw: bool, root: Path) -> dict:
    from lenticalib.calib.crosstalk.measure import measure_crosstalk
    from lenticalib.calib.patterns.crosstalk_patterns import design_crosstalk_patterns
    from lenticalib.core.errors import LenticalibError
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.sim.capture import CROSSTALK_TRUTH_NAME, simulate_capture_set

    folder = root / name
    if profile == "fit":
        from lenticalib.calib.routing.fit import fit_capture_set
        from lenticalib.calib.patterns.calibration_patterns import design_patterns
        from lenticalib.core.profile import load_profile, save_profile

        calibration = root / f"{name}-cal"
        if not (calibration / "fitted.json").exists():
            write_patterns(calibration, design_patterns(W, H, VIEWS))
            simulate_capture_set(calibration, scene)
            save_profile(fit_capture_set(calibration).profile, calibration / "fitted.json")
        profile = load_profile(calibration / "fitted.json")
    if not (folder / CROSSTALK_TRUTH_NAME).exists():
        write_patterns(folder, design_crosstalk_patterns(profile))
        simulate_capture_set(folder, scene, raw=raw)
    start = time.perf_counter()
    row = {"set": name}
    try:
        m = measure_crosstalk(folder, profile, photos="linear" if raw else "srgb", force=True)
    except LenticalibError as refusal:  # by the band-photo check: what would the routing check say?
        try:
            measure_crosstalk(folder, profile, photos="linear" if raw else "srgb")
        except LenticalibError as unforced:
            return {**row, "refused": str(refusal), "unforced": str(unforced)}
        return {**row, "refused": str(refusal)}
    truth = json.loads((folder / CROSSTALK_TRUTH_NAME).read_text())
    d = m.diagnostics
    return {**row, **d["routing_check"]["judged"], "verdict": d["routing_check"]["verdict"],
            "smear_views": round(d["sweep_smear_views"], 3), "cone_residual": round(d["cone_residual_rms"], 4),
            "own": round(float(m.row[0]), 4), "own_true": round(truth["own_view_share"], 4),
            "measure_s": round(time.perf_counter() - start, 1)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="sets to measure (default: all)")
    parser.add_argument("--keep", required=True, metavar="DIR", help="folder for the sets (reused when there)")
    args = parser.parse_args()
    table = cases()
    unknown = sorted(set(args.names) - set(table))
    if unknown:
        parser.error(f"unknown sets: {', '.join(unknown)} (known: {', '.join(table)})")
    for name in args.names or list(table):
        print(json.dumps(run(name, *table[name], Path(args.keep))), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
