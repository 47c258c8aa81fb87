"""``lenticalib simulate``: photograph the test patterns on a virtual panel (a synthetic capture set).

Reads ``DIR/patterns.json`` (from ``lenticalib patterns`` or ``lenticalib crosstalk patterns``), draws a random but plausible panel
and camera (or loads one with ``--scene``), writes ``DIR/captures/NAME.jpg`` for every pattern,
``DIR/truth.json`` (the ideal profile for the camera position) and ``DIR/simulation.json``
(everything needed to reproduce the set); for crosstalk patterns also ``DIR/crosstalk-truth.json``,
the panel's true mixing matrix for the profile the patterns were drawn from.  To photograph
crosstalk patterns from the fit's camera position, pass the fit's scene: ``--scene
FITDIR/simulation.json``.

A folder from ``lenticalib camera patterns`` (``board.json`` of a panel board, no patterns.json) is
photographed as a camera-calibration set instead: ``--photos`` views of its board on a virtual
panel of its size and pixel pitch, by a known camera (``DIR/captures/board-NN.jpg``,
``DIR/truth.cameramodel``, ``DIR/simulation.json``; :mod:`lenticalib.sim.board_set`).

Every option is checked, and the folder found writable, before the first photo is taken.  The
three results are all or nothing: a run that fails (or is interrupted) removes what it wrote and
puts an earlier simulation of the folder back as it was (:func:`lenticalib.core.outputs.restored_on_failure`),
so the fit never meets a half set, or photos of two scenes under one truth.json.
"""

from __future__ import annotations

import argparse
import json

MAX_PIXELS = 64_000_000  # camera pixels in all (the simulator holds several float images of this size)
MAX_SEED = 2 ** 63 - 1
DEFAULT_SUBSAMPLES = 3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("directory", metavar="DIR", help="pattern folder written by 'lenticalib patterns'")
    parser.add_argument("--conditions", choices=("standard", "hard"), default="standard",
                        help="camera behaviour: 'standard' (locked exposure, steady tripod, near-sRGB) or 'hard' "
                             "(a phone: S-shaped tone curve, +-4%% exposure drift and 0.3 px shake between "
                             "photos, high-ISO noise)")
    parser.add_argument("--seed", type=int, metavar="N", help="seed of the random scene (default: a fresh one, "
                        "recorded in simulation.json)")
    parser.add_argument("--resolution", metavar="WxH", help="camera resolution in pixels (default 4000x3000; at "
                        "least the 1 megapixel the fit needs)")
    parser.add_argument("--scene", metavar="FILE", help="reuse a scene: a simulation.json or scene JSON "
                        "(not combinable with --seed/--resolution/--slant/--period/--order/--distance)")
    parser.add_argument("--slant", type=float, metavar="C", help="lens slant C_r in pixels per row (signed)")
    parser.add_argument("--period", type=float, metavar="D", help="lens period Delta_r in subpixels at the "
                        "camera distance")
    parser.add_argument("--order", choices=("RGB", "BGR"), help="subpixel order of the panel")
    parser.add_argument("--distance", type=float, metavar="MM", help="camera distance to the panel in mm")
    parser.add_argument("--jpeg-quality", type=int, metavar="Q", help="JPEG quality 1..100 (default: random "
                        "80..95)")
    parser.add_argument("--subsamples", type=int, metavar="K",
                        help="rays per sensor pixel side, K x K per pixel, 1..16 (default 3, or the --scene's)")
    parser.add_argument("--raw", action="store_true", help="write 16-bit linear PNG photos (captures/NAME.png) as a "
                        "raw converter makes them, instead of camera JPEGs (for 'crosstalk measure --photos linear')")
    parser.add_argument("--photos", type=int, default=24, metavar="K", help="for a camera board folder ('lenticalib "
                        "camera patterns'): the number of board photos, 3..500 (default 24)")
    parser.add_argument("--json", action="store_true", help="print a JSON summary instead of sentences")
    parser.set_defaults(run=run)


def parse_resolution(text: str) -> tuple[int, int]:
    """``"4000x3000"`` -> (4000, 3000) camera pixels; InputError naming ``--resolution`` otherwise."""
    from ..core.sizes import parse_size

    width, height = parse_size(text, "--resolution", example="4000x3000")
    check_resolution(width, height, "--resolution")
    return width, height


def check_resolution(width: int, height: int, source: str) -> None:
    """InputError naming ``source`` unless a ``width`` x ``height`` camera makes photos the fit takes.

    The lower limit is the fit's own (:data:`lenticalib.calib.captures.MIN_PHOTO_PIXELS`), so a
    simulated set is never refused by the fit for its size; the upper limits bound memory.
    """
    from ..calib.captures import MIN_PHOTO_PIXELS
    from ..core.errors import InputError
    from ..core.sizes import MAX_SIDE

    pixels = width * height
    if pixels < MIN_PHOTO_PIXELS:
        raise InputError(f"a {width}x{height} camera ({pixels / 1e6:.2f} megapixels) is below the "
                         f"{MIN_PHOTO_PIXELS / 1e6:g} megapixel the fit needs", source=source,
                         hint=f"give at least {MIN_PHOTO_PIXELS / 1e6:g} megapixel, e.g. 1250x800; the default is "
                              "4000x3000")
    if not (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE) or pixels > MAX_PIXELS:
        raise InputError(f"a {width}x{height} camera is too large to simulate", source=source,
                         hint=f"use at most {MAX_SIDE} pixels per side and {MAX_PIXELS / 1e6:g} megapixels")


def _check_options(args: argparse.Namespace) -> None:
    import math

    from ..core.errors import InputError

    if args.slant is not None and not (math.isfinite(args.slant) and abs(args.slant) < 1.5):
        raise InputError(f"slant {args.slant} is out of range", source="--slant",
                         hint="give C_r in pixels per row, |C_r| < 1.5 (typical panels 0.1..0.35)")
    if args.period is not None and not (math.isfinite(args.period) and 2.0 <= args.period <= 200.0):
        raise InputError(f"period {args.period} is out of range", source="--period",
                         hint="give Delta_r in subpixels, 2..200 (typical panels 14..24)")
    if args.distance is not None and not (math.isfinite(args.distance) and 100.0 <= args.distance <= 10000.0):
        raise InputError(f"distance {args.distance} is out of range", source="--distance",
                         hint="give the camera distance in mm, 100..10000 (typical 450..800)")
    if args.jpeg_quality is not None and not 1 <= args.jpeg_quality <= 100:
        raise InputError(f"JPEG quality {args.jpeg_quality} is out of range", source="--jpeg-quality",
                         hint="use 1..100")
    if args.seed is not None and not 0 <= args.seed <= MAX_SEED:
        raise InputError(f"seed {args.seed} is out of range", source="--seed", hint=f"use 0..{MAX_SEED}")
    if args.resolution is not None:
        parse_resolution(args.resolution)
    if args.subsamples is not None and not 1 <= args.subsamples <= 16:
        raise InputError(f"{args.subsamples} subsamples is out of range", source="--subsamples", hint="use 1..16")


def build_scene(args: argparse.Namespace, pattern_set):
    """The scene the options ask for: loaded with --scene, else drawn by random_scene."""
    import secrets

    from ..core.errors import InputError
    from ..core.documents import read_json_file
    from ..sim.scene import Scene, random_scene

    if args.scene:
        clashing = [flag for flag, value in (("--seed", args.seed), ("--resolution", args.resolution),
                                             ("--slant", args.slant), ("--period", args.period),
                                             ("--order", args.order), ("--distance", args.distance),
                                             ("--conditions", None if args.conditions == "standard" else args.conditions))
                    if value is not None]
        if clashing:
            raise InputError(f"cannot be combined with {', '.join(clashing)}", source="--scene",
                             hint="the scene file fixes the panel and the camera; drop those options")
        data = read_json_file(args.scene, "scene", "check the --scene path")
        scene = Scene.from_dict(data, source=args.scene)
        check_resolution(scene.camera.width, scene.camera.height, args.scene)
        if scene.seed is not None and not 0 <= scene.seed <= MAX_SEED:
            raise InputError(f"seed {scene.seed} is out of range (0..{MAX_SEED})", source=args.scene)
        changes = {}
        if args.jpeg_quality is not None:
            changes["jpeg_quality"] = args.jpeg_quality
        if args.subsamples is not None and args.subsamples != scene.camera.subsamples:
            changes["subsamples"] = args.subsamples
        return scene.replace_camera(**changes) if changes else scene
    seed = args.seed if args.seed is not None else secrets.randbelow(2 ** 31)
    resolution = parse_resolution(args.resolution) if args.resolution else None
    return random_scene(seed, width=pattern_set.width, height=pattern_set.height, resolution=resolution,
                        period=args.period, slant=args.slant, order=args.order, distance=args.distance,
                        jpeg_quality=args.jpeg_quality, conditions=args.conditions,
                        subsamples=DEFAULT_SUBSAMPLES if args.subsamples is None else args.subsamples)


def _check_outputs(directory: str):
    """The paths simulate writes, refused before any work when they cannot be (or must not be) written."""
    from pathlib import Path

    from ..core.errors import InputError
    from ..core.outputs import check_output_file, check_output_folder
    from ..sim.capture import CAPTURE_FOLDER, CROSSTALK_TRUTH_NAME, SIMULATION_NAME, TRUTH_NAME

    folder = Path(directory)
    captures = check_output_folder(folder / CAPTURE_FOLDER, "simulated photos")
    simulation = check_output_file(folder / SIMULATION_NAME, "simulation record")
    truth = check_output_file(folder / TRUTH_NAME, "true profile")
    crosstalk_truth = check_output_file(folder / CROSSTALK_TRUTH_NAME, "true crosstalk")
    # simulate_capture_set refuses this too; checked here so that real photos are never even copied
    if captures.is_dir() and any(captures.iterdir()) and not simulation.exists():
        raise InputError("holds files that the simulator did not write (real photos?)", source=str(captures),
                         hint="simulate into a fresh copy of the pattern folder")
    return [captures, simulation, truth, crosstalk_truth]


def run(args: argparse.Namespace) -> int:
    import time

    from ..calib.patterns import read_pattern_folder
    from ..core.outputs import restored_on_failure
    from ..sim.capture import simulate_capture_set
    from ._progress import progress_bar

    _check_options(args)
    if _is_board_folder(args.directory):
        return run_board(args)
    pattern_set = read_pattern_folder(args.directory)
    scene = build_scene(args, pattern_set)
    written = _check_outputs(args.directory)
    start = time.perf_counter()
    with restored_on_failure(written, "simulation"), \
            progress_bar(len(pattern_set.patterns), "photographing") as bar:
        summary = simulate_capture_set(args.directory, scene, raw=args.raw, progress=bar.wrap)
    summary["seconds"] = round(time.perf_counter() - start, 2)
    if args.json:
        print(json.dumps(summary))
        return 0
    p = summary["profile"]
    cam = scene.camera
    print(f"wrote {summary['photos']} photos to {summary['captures']} ({cam.width}x{cam.height}, seed "
          f"{scene.seed}, camera at x={cam.position[0]:.1f} y={cam.position[1]:.1f} mm, "
          f"{cam.distance:.1f} mm away; {summary['seconds']:.1f} s)")
    print(f"truth: {summary['truth']}: slant {p['slant']:.6f}, period {p['period']:.6f}, "
          f"offset {p['offset']:.6f}, reference view {p['reference_view']:g}, order {p['subpixel_order']}, "
          f"{p['views']} views")
    print(f"scene: {summary['simulation']} (reproduce with: lenticalib simulate DIR --scene {summary['simulation']})")
    return 0


def _is_board_folder(directory: str) -> bool:
    from pathlib import Path

    folder = Path(directory)
    return (folder / "board.json").is_file() and not (folder / "patterns.json").exists()


def run_board(args: argparse.Namespace) -> int:
    """Photograph the panel board of a 'camera patterns' folder (module docstring)."""
    import secrets
    import time
    from pathlib import Path

    from ..calib.intrinsics.board import read_board
    from ..core.errors import InputError
    from ..core.outputs import check_output_file, check_output_folder, restored_on_failure
    from ..sim.board_set import CAPTURE_FOLDER, SIMULATION_NAME, TRUTH_NAME, simulate_board_set
    from ._progress import progress_bar

    folder = Path(args.directory)
    board = read_board(folder / "board.json")
    if board.kind != "panel":
        raise InputError("is a printed board's folder", source=str(folder / "board.json"),
                         hint="simulate the panel board folder (the one with board.png), or use 'lenticalib camera "
                              "simulate DIR --kind print'")
    ignored = [flag for flag, value in (("--scene", args.scene), ("--slant", args.slant), ("--period", args.period),
                                        ("--order", args.order), ("--distance", args.distance),
                                        ("--raw", args.raw or None)) if value is not None]
    if ignored:
        raise InputError(f"does not apply to a camera board folder: {', '.join(ignored)}", source=str(folder),
                         hint="the board folder fixes the panel; the camera moves around it")
    if not 3 <= args.photos <= 500:
        raise InputError(f"{args.photos} photos is out of range", source="--photos", hint="use 3..500 (15-30 is typical)")
    resolution = parse_resolution(args.resolution) if args.resolution else (1600, 1200)
    captures = check_output_folder(folder / CAPTURE_FOLDER, "simulated photos")
    written = [captures, check_output_file(folder / SIMULATION_NAME, "simulation record"),
               check_output_file(folder / TRUTH_NAME, "true camera model")]
    if captures.is_dir() and any(captures.iterdir()) and not (folder / SIMULATION_NAME).exists():
        raise InputError("holds files that the simulator did not write (real photos?)", source=str(captures),
                         hint="simulate into a fresh 'camera patterns' folder")
    seed = args.seed if args.seed is not None else secrets.randbelow(2 ** 31)
    start = time.perf_counter()
    with restored_on_failure(written, "simulation"), progress_bar(args.photos, "photographing") as bar:
        doc = simulate_board_set(folder, kind="panel", seed=seed, photos=args.photos, resolution=resolution,
                                 conditions=args.conditions, subsamples=args.subsamples or 2, progress=bar.update,
                                 board=board)
    seconds = round(time.perf_counter() - start, 2)
    if args.json:
        print(json.dumps({"directory": str(folder), "kind": "panel", "seed": seed, "photos": args.photos,
                          "resolution": list(resolution), "seconds": seconds, "truth": str(folder / TRUTH_NAME)}))
        return 0
    print(f"wrote {args.photos} photos of the board of {folder / 'board.json'} on a virtual panel to "
          f"{folder / CAPTURE_FOLDER} ({resolution[0]}x{resolution[1]}, seed {seed}, {doc['seconds_per_photo']:.2f} s "
          f"per photo); the true camera: {folder / TRUTH_NAME}")
    print(f"next: lenticalib camera calibrate {folder / CAPTURE_FOLDER} -o camera.cameramodel")
    return 0
