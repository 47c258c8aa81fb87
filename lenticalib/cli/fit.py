"""``lenticalib fit DIR -o profile.json``: fit a panel profile from photos of the test patterns.

The work is :func:`lenticalib.calib.routing.fit_pipeline.fit_capture_sets`; this module parses the
options, shows the progress, prints the outcome and maps the library's argument names to its
flags (:data:`FLAGS`).  Before the fit starts, the options are range-checked and the profile path and the report
folder are checked (:mod:`lenticalib.core.files.outputs`: no missing folder is created, a folder is not a
profile path, a folder holding anything but a report is not replaced).  The report is written
into a hidden sibling and moved into place complete.  Outcomes:

- trusted (or ``--force``): the report and the profile, exit 0;
- not trustworthy (exit 3): the report (the user needs it to see why), no profile;
- an error (exit 2): nothing at all; an earlier profile and report stay as they were.

``--json`` prints the report's ``summary.json`` document (:func:`lenticalib.calib.routing.report.fit_summary`).

``--moved-right DIR2``: a second capture set of the same patterns, taken after moving the camera
a few centimetres to the right at the same distance.  Both sets are fitted; the difference of
the two fits gives the profile's ``view_direction`` (:mod:`lenticalib.calib.routing.direction`), or
leaves it unknown with a one-line warning saying why.  The profile and report are those of
``DIR``.  ``DIR2`` is checked (a different folder, a complete capture set of the same pattern
set) before the first fit starts.

``--camera MODEL --pixel-pitch MM``: with a calibrated camera (``lenticalib camera calibrate``)
the fit also finds where the camera was, in mm (:mod:`lenticalib.calib.camera.pose`), and writes the
profile's physical block (:mod:`lenticalib.calib.routing.physical_fit`).  The gap, and with it the
camera's distance to the lens surface, the lens pitch and the eye position that
``lenticalib profile retarget`` needs, comes from ``--second-distance DIR2`` (the same patterns
photographed from another distance, fitted too) or from the data sheet (``--gap MM``).
"""

from __future__ import annotations

import argparse
import json

from ..core.terminal_text import safe_line


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("directory", metavar="DIR", help="pattern folder with patterns.json and captures/")
    parser.add_argument("-o", "--output", required=True, metavar="PROFILE", help="profile JSON to write")
    parser.add_argument("--report", metavar="DIR", help="folder for the report figures "
                                                       "(default: next to the profile, NAME-report/)")
    parser.add_argument("--camera", metavar="MODEL", help="optional camera model (mrcal .cameramodel, or OpenCV "
                                                         "YAML/JSON with camera_matrix and distortion)")
    parser.add_argument("--pixel-pitch", type=float, metavar="MM", help="the panel's pixel pitch in mm (panel width "
                        "in mm / pixels); with --camera the fit reports the camera's pose in mm and the panel's "
                        "physical constants")
    parser.add_argument("--second-distance", metavar="DIR2", help="the same patterns photographed from another "
                        "distance (at least 15%% nearer or farther; needs --camera and --pixel-pitch): gives the "
                        "lens-to-pixel gap, so the profile can be retargeted to any viewing distance")
    parser.add_argument("--gap", type=float, metavar="MM", help="the data sheet's effective lens-to-pixel gap in mm "
                        "(instead of --second-distance)")
    parser.add_argument("--views", type=int, help="number of views, 2..254 (default: the pattern set's)")
    parser.add_argument("--force", action="store_true",
                        help="write the profile even when the fit fails a quality gate")
    parser.add_argument("--moved-right", metavar="DIR2",
                        help="a second capture set of the same patterns, taken after moving the camera a few "
                             "centimetres to the RIGHT (same distance): gives the profile's view_direction")
    parser.add_argument("--json", action="store_true", help="print the summary (the report's summary.json)")
    parser.set_defaults(run=run)


FLAGS = {"capture_dir": "DIR", "views": "--views", "report_dir": "--report DIR", "moved_right": "--moved-right DIR2",
         "camera_model": "--camera MODEL", "pixel_pitch_mm": "--pixel-pitch MM", "gap_mm": "--gap MM",
         "second_distance": "--second-distance DIR2"}  # the library's argument names, as this command's flags


def describe_physical(result) -> str:
    """Lines on the camera's pose and the panel's physical constants (after add_physical)."""
    report = result.quality["physical"]
    pose, block = result.pose, result.profile.physical or {}
    unc = block.get("uncertainty") or {}
    x, y = pose.eye_mm[:2]
    sx, sy, sd = pose.sigma_mm
    lines = [f"camera {x:+.1f} +- {sx:.1f} mm right, {y:+.1f} +- {sy:.1f} mm down of the panel centre, "
             f"{report['pixel_plane_distance_mm']:.1f} +- {sd:.1f} mm from the pixel plane"]
    if "gap_mm" in block:
        lines.append(f"gap {block['gap_mm']:.4f} +- {unc.get('gap_mm', 0):.2g} mm ({report['gap_from']}): camera "
                     f"{block['eye_mm'][2]:.1f} mm from the lens surface; lens pitch {block['lens_pitch_mm']:.6f} +- "
                     f"{unc.get('lens_pitch_mm', 0):.2g} mm, slant {block['slant_angle_deg']:.4f} deg, lens position "
                     f"{block['lens_position_mm']:.4f} mm, view cone {block['view_cone_deg']:.1f} deg")
    else:
        lines.append("gap unknown: " + report["note"])
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    import sys

    from ..calib.routing.fit_pipeline import PhysicalOptions, fit_capture_sets
    from ..calib.routing.layout_fit import describe as describe_layout
    from ..core.view_direction import describe_direction
    from .shared.flags import flag_names
    from .shared.progress import progress_bar

    physical = PhysicalOptions(camera_model=args.camera, pixel_pitch_mm=args.pixel_pitch,
                               second_distance=args.second_distance, gap_mm=args.gap)
    with progress_bar(0, "fitting") as bar, flag_names(FLAGS):
        run = fit_capture_sets(args.directory, output=args.output, report_dir=args.report,
                               moved_right=args.moved_right, views=args.views, physical=physical, force=args.force,
                               progress=bar.update, progress_total=bar.set_total)
    result, output, report_dir, summary = run.result, run.profile_path, run.report_dir, run.summary
    for warning in result.warnings:
        print(f"lenticalib: warning: {safe_line(warning)}", file=sys.stderr)
    profile = result.profile
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        unc = profile.uncertainty or {}
        print(f"period {profile.period:.6f} +- {unc.get('period', 0):.2g} subpixels, "
              f"slant {profile.slant:.7f} +- {unc.get('slant', 0):.2g} pixels/row, "
              f"offset {profile.offset:.4f} +- {unc.get('offset', 0):.2g} subpixels, "
              f"reference view {profile.reference_view:g}, "
              + (f"order {profile.subpixel_order}" if profile.is_stripe else "cell layout"))
        if result.layout is not None:
            print(f"subpixel layout from the cell photos: {describe_layout(result.layout)}")
        if result.direction is not None:
            d = result.direction
            sigma = "?" if d["sigma_views"] is None else f"{d['sigma_views']:.3f}"
            print(f"view direction {describe_direction(profile.view_direction)}: the camera moved right sees "
                  f"{d['delta_w_views']:+.3f} +- {sigma} views")
        else:
            print("view direction unknown (one camera position cannot tell it: fit with --moved-right DIR2, or "
                  "use 'lenticalib patterns --direction')")
        q = result.quality
        print(f"residual {q['block_residual_rms_views']:.3f} views RMS over panel blocks "
              f"({q['block_residual_smooth_rms_views']:.3f} smooth); predicted 1-sigma error "
              f"{q['predicted_error_worst_views']:.3f} views at the worst corner, centring "
              f"{q['predicted_error_centre_views']:.3f} views; {result.seconds:.1f} s")
        if result.pose is not None:
            print(describe_physical(result))
        print(f"report: {report_dir}")
    if not result.trusted:
        reasons = safe_line("; ".join(result.problems))
        if args.force:
            print(f"lenticalib: warning: the fit is not trustworthy ({reasons}); written anyway (--force)",
                  file=sys.stderr)
            return 0
        print(f"lenticalib: error: {args.directory}: the fit is not trustworthy: {reasons} (no profile written; "
              f"the report in {report_dir} shows why; retake the photos, or pass --force to write {output} "
              "anyway)", file=sys.stderr)
        return 3
    if not args.json:
        print(f"wrote {output}")
    return 0
