"""Benchmark: the fit in millimetres and retargeting, against the virtual panel's truth, over seeds.

For every seed: a random panel and camera (1920x1080 patterns, 1500x1000 camera); two capture
sets of the same patterns from D1 (drawn in 450..650 mm) and 1.45 D1, one camera (same
intrinsics); the camera model either the truth (``--model truth``) or calibrated by
``lenticalib.calib.intrinsics.pipeline.calibrate_camera`` (what ``lenticalib camera calibrate``
runs) from simulated photos of a board shown on the same panel (``--model calibrated``, the
user's path); both sets fitted with ``lenticalib.calib.routing.fit_pipeline.fit_capture_sets`` (what
``lenticalib fit --camera --pixel-pitch --second-distance`` runs).  Reports per seed and as medians / worst:

    distance error (mm, and in reported sigmas), lateral error (sigmas), gap error (% and
    sigmas), lens pitch error (ppm), and the retargeted profile's w - w* (views, RMS and worst,
    centring included) at 400, 500, 750 and 900 mm, centred and 50 mm to the side.

Usage:  python tools/bench_physical.py [--seeds 1-6] [--model truth|calibrated] [--jobs 2]
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import json
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

TARGETS = [(0.0, 400.0), (50.0, 500.0), (0.0, 750.0), (50.0, 900.0)]


def _camera_model(kind: str, scene, root: Path, seed: int) -> Path:
    import mrcal

    path = root / "camera.cameramodel"
    cam = scene.camera
    if kind == "truth":
        intrinsics = np.array([cam.fx, cam.fy, cam.cx, cam.cy, *cam.distortion])
        mrcal.cameramodel(intrinsics=("LENSMODEL_OPENCV5", intrinsics), imagersize=(cam.width, cam.height)).write(
            str(path))
        return path
    from lenticalib.calib.intrinsics.pipeline import calibrate_camera
    from lenticalib.sim.board_set import simulate_board_set

    boards = root / "boards"
    boards.mkdir()
    simulate_board_set(boards, kind="panel", seed=seed, photos=20, scene=scene)
    calibrate_camera([boards / "captures"], path, jobs=1)
    return path


def one_seed(seed: int, model_kind: str) -> dict:
    from lenticalib.calib.routing.fit_pipeline import PhysicalOptions, fit_capture_sets
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.core.profile import load_profile
    from lenticalib.core.retarget import retarget_profile
    from lenticalib.sim.capture import simulate_capture_set
    from lenticalib.sim.truth import routing_error
    from lenticalib.sim.scene import random_scene

    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    d1 = float(rng.uniform(450, 650))
    root = Path(tempfile.mkdtemp(prefix=f"bench-physical-{seed}-"))
    try:
        write_patterns(root / "patterns", design_patterns(1920, 1080, 32))
        scene = random_scene(seed, width=1920, height=1080, resolution=(1500, 1000), distance=d1)
        sets = []
        for distance in (d1, 1.45 * d1):
            cam = scene.camera
            moved = dataclasses.replace(scene, camera=cam.replace(position=(cam.position[0], cam.position[1],
                                                                            -distance)))
            folder = root / f"set-{distance:.0f}"
            shutil.copytree(root / "patterns", folder)
            simulate_capture_set(folder, moved)
            sets.append(folder)
        model = _camera_model(model_kind, scene, root, seed)
        optics = scene.optics
        fit_capture_sets(sets[0], output=root / "profile.json", force=True,
                         physical=PhysicalOptions(camera_model=model, pixel_pitch_mm=optics.pixel_pitch,
                                                  second_distance=sets[1]))
        profile = load_profile(root / "profile.json")
        block = profile.physical
        unc = block["uncertainty"]
        true_eye = np.array([scene.camera.position[0], scene.camera.position[1], d1])
        eye, sigma = np.array(block["eye_mm"]), np.array(unc["eye_mm"])
        out = {"seed": seed, "distance_mm": d1, "gap_true_mm": optics.gap,
               "distance_error_mm": float(eye[2] - true_eye[2]),
               "distance_error_sigmas": float((eye[2] - true_eye[2]) / sigma[2]),
               "distance_error_percent": float(100 * (eye[2] - true_eye[2]) / true_eye[2]),
               "lateral_error_sigmas": float(np.max(np.abs(eye[:2] - true_eye[:2]) / sigma[:2])),
               "gap_error_percent": float(100 * (block["gap_mm"] / optics.gap - 1)),
               "gap_error_sigmas": float((block["gap_mm"] - optics.gap) / unc["gap_mm"]),
               "lens_pitch_error_ppm": float(1e6 * (block["lens_pitch_mm"] / optics.lens_pitch - 1))}
        retarget = []
        for lateral, distance in TARGETS:
            moved = retarget_profile(profile, (lateral, 0.0, distance))
            err = routing_error(optics, (lateral, 0.0, -distance), moved, rows=50, cols=240)
            retarget.append({"lateral_mm": lateral, "distance_mm": distance, "rms_views": float(np.sqrt(np.mean(err ** 2))),
                             "worst_views": float(np.abs(err).max())})
        out["retarget"] = retarget
        out["seconds"] = time.perf_counter() - start
        return out
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _seeds(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi or lo) + 1))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1-6")
    parser.add_argument("--model", choices=("truth", "calibrated"), default="calibrated")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--json", metavar="FILE", help="also write every result as JSON")
    args = parser.parse_args()
    seeds = _seeds(args.seeds)
    with concurrent.futures.ProcessPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(one_seed, seeds, [args.model] * len(seeds)))
    print(f"camera model: {args.model}; {len(results)} seeds")
    print(f"{'seed':>4} {'D mm':>6} {'dD mm':>7} {'dD %':>7} {'dD/s':>6} {'lat/s':>6} {'gap %':>7} {'gap/s':>6} "
          f"{'P_h ppm':>8} {'rt RMS':>7} {'rt worst':>8} {'s':>5}")
    for r in results:
        rms = max(t["rms_views"] for t in r["retarget"])
        worst = max(t["worst_views"] for t in r["retarget"])
        print(f"{r['seed']:>4} {r['distance_mm']:>6.0f} {r['distance_error_mm']:>7.2f} {r['distance_error_percent']:>7.3f} "
              f"{r['distance_error_sigmas']:>6.2f} {r['lateral_error_sigmas']:>6.2f} {r['gap_error_percent']:>7.3f} "
              f"{r['gap_error_sigmas']:>6.2f} {r['lens_pitch_error_ppm']:>8.1f} {rms:>7.4f} {worst:>8.4f} "
              f"{r['seconds']:>5.0f}")

    def summary(key, fn=abs):
        values = [fn(r[key]) for r in results]
        return statistics.median(values), max(values)

    for key in ("distance_error_percent", "distance_error_sigmas", "lateral_error_sigmas", "gap_error_percent",
                "gap_error_sigmas", "lens_pitch_error_ppm"):
        med, worst = summary(key)
        print(f"|{key}|: median {med:.3f}, worst {worst:.3f}")
    rms = [t["rms_views"] for r in results for t in r["retarget"]]
    worst = [t["worst_views"] for r in results for t in r["retarget"]]
    print(f"retargeted w - w* over {len(rms)} (seed, eye) pairs: RMS median {statistics.median(rms):.4f}, worst "
          f"{max(rms):.4f} views; worst |error| median {statistics.median(worst):.4f}, worst {max(worst):.4f} views "
          "(target 0.05 RMS, 0.15 worst)")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
