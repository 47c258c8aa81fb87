"""``lenticalib batch fit CAPTURES... -o OUT``: calibrate a fleet of panels on a Dask cluster.

One panel per capture folder, fitted as ``lenticalib fit DIR -o OUT/NAME/profile.json`` fits it
(``NAME``: the capture folder's name), on a local cluster (``--workers N`` processes, default one
per core) or on a running one (``--scheduler tcp://HOST:PORT``; its workers see the folders at the
same paths, as on a shared file server: a worker that cannot is refused in one line before any
fit).  The work is :func:`lenticalib.calib.fleet.run.fit_fleet`; this module parses the options,
shows a progress bar over the panels, prints one line per panel and the counts.

Writes ``OUT/NAME/`` per panel (written whole), ``OUT/summary.json``, ``OUT/summary.csv`` and
``OUT/fleet.png``.  Running the same command again fits only panels whose inputs (photos,
patterns, options) changed or that failed.  Exit 0 when every panel is ok; 3 when any panel is
untrusted or failed (its row says why); 2 for an error before the work starts.  See ``docs/batch.md``.
"""

from __future__ import annotations

import argparse

from ..core.terminal_text import safe_line

FLAGS = {"captures": "CAPTURES", "scheduler": "--scheduler ADDRESS", "workers": "--workers N",
         "views": "--views N"}  # the library's argument names, as this command's flags


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="batch_command", metavar="STEP")
    sub.required = True
    text = "fit a profile for every capture folder, on a Dask cluster, with one summary"
    f = sub.add_parser("fit", help=text, description=text)
    f.add_argument("captures", nargs="+", metavar="CAPTURES", help="capture folders, one per panel (patterns.json "
                   "and captures/, as for 'lenticalib fit'); each folder's name names its panel")
    f.add_argument("-o", "--output", required=True, metavar="OUT", help="folder for the panels' results and the "
                   "summary (created; its parent must exist)")
    f.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler (tcp://HOST:PORT) whose workers "
                   "see the capture folders and OUT at the same paths (default: a local cluster)")
    f.add_argument("--workers", type=int, metavar="N", help="local cluster: worker processes (default: one per "
                   "core); with --scheduler: wait for N workers to join before starting (default 1)")
    f.add_argument("--views", type=int, metavar="N", help="number of views, 2..254 (default: each pattern set's)")
    f.add_argument("--force", action="store_true", help="write each profile even when its fit fails a quality "
                   "gate (the panel stays 'untrusted')")
    f.add_argument("--json", action="store_true", help="print the summary (OUT/summary.json)")
    f.set_defaults(run=run_fit, flags=FLAGS)


def _row_line(row: dict) -> str:
    name, status = safe_line(row["name"]), row["status"]
    if status == "failed":
        return f"{name}: failed: {safe_line(row.get('error') or '')}"
    done = "fitted" if row.get("fitted") else "already done"
    line = (f"{name}: {status}, period {row['period']:.6f}, slant {row['slant']:.7f}, offset {row['offset']:.4f}, "
            f"residual {row['block_residual_rms_views']:.3f} views ({done})")
    return line + (f": {safe_line(row['error'])}" if status == "untrusted" and row.get("error") else "")


def run_fit(args: argparse.Namespace) -> int:
    import json
    import sys
    from pathlib import Path

    from ..calib.fleet.identity import FitOptions
    from ..calib.fleet.run import fit_fleet
    from .shared.flags import flag_names
    from .shared.progress import progress_bar

    command = " ".join([Path(sys.argv[0]).name] + sys.argv[1:]) if sys.argv and sys.argv[0] else None
    with progress_bar(0, "panels", unit="panel") as bar, flag_names(FLAGS):
        run = fit_fleet(args.captures, args.output, scheduler=args.scheduler, workers=args.workers,
                        options=FitOptions(views=args.views, force=args.force), command=command,
                        progress=bar.update, progress_total=bar.set_total)
    if args.json:
        print(json.dumps(run.summary, indent=2))
    else:
        for row in run.rows:
            print(_row_line(row))
        c = run.summary["counts"]
        for outlier in run.summary["outliers"]:
            print(f"outlier: {safe_line(outlier['name'])}: {outlier['quantity']} {outlier['value']:.6g} outside "
                  + " .. ".join("-" if x is None else f"{x:.6g}" for x in (outlier["low"], outlier["high"])))
        print(f"{c['ok']} ok, {c['untrusted']} untrusted, {c['failed']} failed ({c['fitted']} fitted now, "
              f"{c['reused']} already done) on {run.cluster['workers']} workers")
        print(f"wrote {run.summary_path}, {run.csv_path.name} and {run.figure_path.name}")
    return 0 if run.all_ok else 3
