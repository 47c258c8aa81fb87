"""``lenticalib fit DIR -o profile.json``: fit a panel profile from photos of the test patterns.

Before the fit starts, the options are range-checked and the profile path and the report
folder are checked (:mod:`lenticalib.core.outputs`: no missing folder is created, a folder is not a
profile path, a folder holding anything but a report is not replaced).  The report is written
into a hidden sibling and moved into place complete.  Outcomes:

- trusted (or ``--force``): the report and the profile, exit 0;
- not trustworthy (exit 3): the report (the user needs it to see why), no profile;
- an error (exit 2): nothing at all; an earlier profile and report stay as they were.

``--json`` prints the report's ``summary.json`` document (:func:`lenticalib.calib.report.fit_summary`).

``--moved-right DIR2``: a second capture set of the same patterns, taken after moving the camera
a few centimetres to the right at the same distance.  Both sets are fitted; the difference of
the two fits gives the profile's ``view_direction`` (:mod:`lenticalib.calib.direction`), or
leaves it unknown with a one-line warning saying why.  The profile and report are those of
``DIR``.  ``DIR2`` is checked (a different folder, a complete capture set of the same pattern
set) before the first fit starts.

``--camera MODEL --pixel-pitch MM``: with a calibrated camera (``lenticalib camera calibrate``)
the fit also finds where the camera was, in mm (:mod:`lenticalib.calib.pose`), and writes the
profile's physical block (:mod:`lenticalib.calib.physical_fit`).  The gap, and with it the
camera's distance to the lens surface, the lens pitch and the eye position that
``lenticalib profile retarget`` needs, comes from ``--second-distance DIR2`` (the same patterns
photographed from another distance, fitted too) or from the data sheet (``--gap MM``).
"""

from __future__ import annotations

import argparse
import json


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


def check_arguments(args: argparse.Namespace):
    """(profile path, report folder) once every option and output path is usable; InputError otherwise."""
    import os

    from ..calib.report import REPORT_FILES
    from ..core.errors import InputError
    from ..core.outputs import check_output_file, check_output_folder
    from ..core.profile import MAX_VIEWS

    if args.views is not None and not 2 <= args.views <= MAX_VIEWS:
        raise InputError(f"{args.views} views is out of range", source="--views",
                         hint=f"use 2..{MAX_VIEWS}, or leave it out to use the pattern set's")
    output = check_output_file(args.output, "profile", example="profile.json")
    if args.report:
        report = check_output_folder(args.report, "report", contents=REPORT_FILES)
    else:
        report = output.with_name(output.stem + "-report")
        if report.exists() and not report.is_dir():
            raise InputError("is a file, not a folder for the report", source=str(report),
                             hint="remove it, or choose the report folder with --report")
        check_output_folder(report, "report", contents=REPORT_FILES)
    if os.path.abspath(report) == os.path.abspath(output):
        raise InputError("is also the profile path", source=str(report), hint="give the report another folder")
    if args.moved_right is not None:
        check_moved_right(args.directory, args.moved_right)
    check_physical_options(args)
    return output, report


def check_physical_options(args: argparse.Namespace) -> None:
    """InputError for a missing or out-of-range --pixel-pitch/--gap or a bad --second-distance,
    and load the camera model now (a broken file is one line before the fit starts)."""
    from ..calib.camera_file import load_camera_model
    from ..core.errors import InputError
    from ..core.physical import LIMITS

    for option, key, value in (("--pixel-pitch", "pixel_pitch_mm", args.pixel_pitch), ("--gap", "gap_mm", args.gap)):
        low, high = LIMITS[key]
        if value is not None and not low <= value <= high:
            raise InputError(f"{value:g} mm is out of range", source=option, hint=f"give {low:g}..{high:g} mm")
    needs_camera = [o for o, v in (("--pixel-pitch", args.pixel_pitch), ("--second-distance", args.second_distance),
                                   ("--gap", args.gap)) if v is not None]
    if needs_camera and not args.camera:
        raise InputError("needs a camera model", source=needs_camera[0],
                         hint="calibrate the camera ('lenticalib camera calibrate ...') and pass --camera MODEL")
    args.camera_model = load_camera_model(args.camera) if args.camera else None  # read once for every fit
    if args.camera:
        if args.pixel_pitch is None:
            raise InputError("a camera model gives the camera's pose in mm only with the panel's pixel pitch",
                             source="--camera", hint="pass --pixel-pitch MM (the panel's width in mm / its pixels)")
    if args.second_distance is not None and args.gap is not None:
        raise InputError("give the gap one way", source="--gap", hint="either --second-distance DIR2 or --gap MM")
    if args.second_distance is not None:
        check_second_set(args.directory, args.second_distance, "--second-distance",
                         "photograph the patterns again from another distance, into a copy of the pattern folder")


def check_moved_right(directory, moved_right) -> None:
    """InputError/CaptureError unless ``moved_right`` is another complete capture set of the same patterns."""
    check_second_set(directory, moved_right, "--moved-right", "photograph the patterns again after moving the camera "
                     "a few centimetres to the right, into a copy of the pattern folder")


def check_second_set(directory, other, option: str, how: str) -> None:
    """InputError/CaptureError unless ``other`` is another complete capture set of the same patterns."""
    import os

    from ..calib.captures import open_capture_set
    from ..core.errors import InputError

    if os.path.realpath(other) == os.path.realpath(directory):
        raise InputError("is the same capture set as DIR", source=option, hint=how)
    first, second = open_capture_set(directory), open_capture_set(other)
    if first.patterns.set_id != second.patterns.set_id:
        raise InputError(f"holds photos of pattern set {second.patterns.set_id}, {directory} of set "
                         f"{first.patterns.set_id}", source=str(other),
                         hint="photograph the same patterns from both camera positions")


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

    from ..calib.captures import open_capture_set
    from ..calib.fit import fit_capture_set, progress_steps
    from ..calib.report import REPORT_FILES, fit_summary, write_report
    from ..core.outputs import staged_folder
    from ..core.profile import save_profile
    from ..core.view_direction import describe_direction
    from ._progress import progress_bar

    output, report_dir = check_arguments(args)
    directories = [args.directory] + [d for d in (args.moved_right, args.second_distance if args.camera else None) if d]
    total = sum(progress_steps(open_capture_set(d).patterns) for d in directories)  # the fit's first step
    options = dict(views=args.views, camera_model=args.camera_model, pixel_pitch_mm=args.pixel_pitch)
    with progress_bar(total, "fitting") as bar:
        result = fit_capture_set(args.directory, progress=bar.update, **options)
        if args.moved_right:
            from ..calib.direction import add_moved_right

            second = fit_capture_set(args.moved_right, progress=bar.update, **options)
            add_moved_right(result, second, args.moved_right)
        if args.camera:
            from ..calib.physical_fit import add_physical

            other = fit_capture_set(args.second_distance, progress=bar.update, **options) \
                if args.second_distance else None
            add_physical(result, args.pixel_pitch, second=other, gap=args.gap, second_directory=args.second_distance)
    for warning in result.warnings:
        print(f"lenticalib: warning: {warning}", file=sys.stderr)
    profile = result.profile
    write_profile = result.trusted or args.force
    summary = fit_summary(result, args.directory, report=report_dir, output=output if write_profile else None)
    with staged_folder(report_dir, "report", contents=REPORT_FILES) as stage:
        write_report(result, stage, args.directory, summary)
        if write_profile:
            save_profile(profile, output)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        unc = profile.uncertainty or {}
        print(f"period {profile.period:.6f} +- {unc.get('period', 0):.2g} subpixels, "
              f"slant {profile.slant:.7f} +- {unc.get('slant', 0):.2g} pixels/row, "
              f"offset {profile.offset:.4f} +- {unc.get('offset', 0):.2g} subpixels, "
              f"reference view {profile.reference_view:g}, order {profile.subpixel_order}")
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
        reasons = "; ".join(result.problems)
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
