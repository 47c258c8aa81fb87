"""``lenticalib fit DIR -o profile.json``: fit a panel profile from photos of the test patterns."""

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
    parser.add_argument("--views", type=int, help="number of views (default: the pattern set's)")
    parser.add_argument("--force", action="store_true",
                        help="write the profile even when the fit fails a quality gate")
    parser.add_argument("--json", action="store_true", help="print a JSON summary")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    from ..calib.fit import fit_capture_set
    from ..calib.report import write_report
    from ..profile import save_profile
    from ._progress import progress_bar

    output = Path(args.output)
    report_dir = Path(args.report) if args.report else output.with_name(output.stem + "-report")
    with progress_bar(24, "fitting") as bar:
        result = fit_capture_set(args.directory, views=args.views, camera_model=args.camera,
                                 progress=bar.update)
    written = write_report(result, report_dir, args.directory)
    profile = result.profile
    unc = profile.uncertainty or {}
    summary = {"trusted": result.trusted, "problems": result.problems, "seconds": round(result.seconds, 2),
               "period": profile.period, "slant": profile.slant, "offset": profile.offset,
               "reference_view": profile.reference_view, "subpixel_order": profile.subpixel_order,
               "uncertainty": unc, "report": str(report_dir),
               "quality": {k: v for k, v in result.quality.items() if not isinstance(v, (list, dict))}}
    if result.trusted or args.force:
        output.parent.mkdir(parents=True, exist_ok=True)
        save_profile(profile, output)
        summary["output"] = str(output)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f"period {profile.period:.6f} +- {unc.get('period', 0):.2g} subpixels, "
              f"slant {profile.slant:.7f} +- {unc.get('slant', 0):.2g} pixels/row, "
              f"offset {profile.offset:.4f} +- {unc.get('offset', 0):.2g} subpixels, "
              f"reference view {profile.reference_view:g}, order {profile.subpixel_order}")
        q = result.quality
        print(f"residual {q['block_residual_rms_views']:.3f} views RMS (systematic), predicted error "
              f"{q['predicted_error_worst_views']:.3f} views (1 sigma, worst corner); {result.seconds:.1f} s")
        print(f"report: {written}")
    if not result.trusted:
        reasons = "; ".join(result.problems)
        if args.force:
            print(f"lenticalib: warning: the fit is not trustworthy ({reasons}); written anyway (--force)",
                  file=sys.stderr)
            return 0
        print(f"lenticalib: error: {args.directory}: the fit is not trustworthy: {reasons} (see the report; "
              f"retake the photos, or pass --force to write {output} anyway)", file=sys.stderr)
        return 3
    if not args.json:
        print(f"wrote {output}")
    return 0
