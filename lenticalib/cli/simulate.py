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
puts an earlier simulation of the folder back as it was, so the fit never meets a half set, or
photos of two scenes under one truth.json.  The work: :func:`lenticalib.sim.simulate_folder.simulate_folder`.
"""

from __future__ import annotations

import argparse
import json



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
    parser.add_argument("--layout", metavar="NAME|FILE",
                        help="subpixel layout of the panel: RGB, BGR, lkg-columns (two cells alternating by "
                             "column), lkg-checker (checkerboard), lkg-rows4 (four cells by row), or a JSON layout "
                             "file {\"cells\": [{\"R\": [dx, dy], ...}], \"pattern\": [[0, 1]]} (pixels, y down); "
                             "not with --order")
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


FLAGS = {"seed": "--seed", "resolution": "--resolution", "scene": "--scene", "slant": "--slant", "period": "--period",
         "order": "--order", "distance_mm": "--distance", "jpeg_quality": "--jpeg-quality",
         "subsamples": "--subsamples", "conditions": "--conditions", "raw": "--raw", "photos": "--photos",
         "layout": "--layout"}
"""The library's argument names (:class:`lenticalib.sim.simulate_folder.SimulationOptions`), as this command's flags."""


def parse_resolution(text: str) -> tuple[int, int]:
    """``"4000x3000"`` -> (4000, 3000); InputError naming ``--resolution`` when it is not WxH
    (:func:`lenticalib.core.sizes.parse_size`; the camera's limits are checked by the library)."""
    from ..core.sizes import parse_size

    return parse_size(text, "--resolution", example="4000x3000")


def run(args: argparse.Namespace) -> int:
    from ..sim.layouts import layout_label
    from ..sim.simulate_folder import SimulationOptions, simulate_folder
    from .shared.flags import flag_names
    from .shared.progress import progress_bar

    options = SimulationOptions(seed=args.seed, resolution=parse_resolution(args.resolution) if args.resolution else None,
                                scene=args.scene, slant=args.slant, period=args.period, order=args.order,
                                distance_mm=args.distance, jpeg_quality=args.jpeg_quality, subsamples=args.subsamples,
                                conditions=args.conditions, raw=args.raw, photos=args.photos, layout=args.layout)
    with progress_bar(0, "photographing") as bar, flag_names(FLAGS):
        done = simulate_folder(args.directory, options, progress=bar.update, progress_total=bar.set_total)
    if done.kind == "board":
        return _print_board(args, done)
    summary = done.summary
    if args.json:
        print(json.dumps(summary))
        return 0
    p = summary["profile"]
    cam = done.scene.camera
    optics = done.scene.optics
    label = layout_label(optics.subpixel_order, optics.subpixel_layout)
    print(f"wrote {summary['photos']} photos to {summary['captures']} ({cam.width}x{cam.height}, seed "
          f"{done.seed}, camera at x={cam.position[0]:.1f} y={cam.position[1]:.1f} mm, "
          f"{cam.distance:.1f} mm away; {summary['seconds']:.1f} s)")
    print(f"truth: {summary['truth']}: slant {p['slant']:.6f}, period {p['period']:.6f}, "
          f"offset {p['offset']:.6f}, reference view {p['reference_view']:g}, "
          f"{'order' if optics.subpixel_layout is None else 'layout'} {label}, "
          f"{p['views']} views")
    print(f"scene: {summary['simulation']} (reproduce with: lenticalib simulate DIR --scene {summary['simulation']})")
    return 0


def _print_board(args: argparse.Namespace, done) -> int:
    from ..sim.board_set import CAPTURE_FOLDER, TRUTH_NAME

    folder, (w, h) = done.directory, done.resolution
    if args.json:
        print(json.dumps({"directory": str(folder), "kind": "panel", "seed": done.seed, "photos": done.photos,
                          "resolution": [w, h], "seconds": done.seconds, "truth": str(folder / TRUTH_NAME)}))
        return 0
    print(f"wrote {done.photos} photos of the board of {folder / 'board.json'} on a virtual panel to "
          f"{folder / CAPTURE_FOLDER} ({w}x{h}, seed {done.seed}, {done.summary['seconds_per_photo']:.2f} s "
          f"per photo); the true camera: {folder / TRUTH_NAME}")
    print(f"next: lenticalib camera calibrate {folder / CAPTURE_FOLDER} -o camera.cameramodel")
    return 0
