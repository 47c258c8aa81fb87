"""The work of one panel, as a Dask worker runs it: :func:`fit_panel` (and :func:`missing_folders`).

:func:`fit_panel` is the task a fleet run (:mod:`.run`) submits once per capture folder.  It
runs on whichever worker the scheduler chooses, so it takes and returns plain values (paths as
absolute strings, a :class:`~.identity.FitOptions`, a row ``dict``) and reads and writes only
through the paths it is given (on a cluster, a shared file server seen at the same paths).

Per panel it writes the folder ``PANEL`` (``OUT/<capture folder name>/``), whole or not at all
(:func:`lenticalib.core.files.outputs.staged_folder`: a killed worker or Ctrl-C leaves the earlier
folder, never a half-written one):

    profile.json      the profile, as ``lenticalib fit DIR -o PANEL/profile.json`` writes it
                      (trusted fits, or every fit with ``force``)
    profile-report/   the fit's report (figures, ``summary.json``), as that command writes it
    batch.json        the panel's record (:data:`.identity.RECORD_NAME`): its row, the identity
                      of its inputs and the options (how a later run knows it is done)

The fit is :func:`lenticalib.calib.routing.fit_pipeline.fit_capture_sets`, the library call of
``lenticalib fit``, with the same defaults; the profile's provenance names the batch command
(``command``) instead of the worker process's.  A panel whose fit refuses its photos or cannot
fit (a :class:`~lenticalib.core.errors.LenticalibError`) is a ``failed`` row with the reason, and
its folder holds just the record; anything else (a bug) escapes, for Dask's retries and then the
run's row.
"""

from __future__ import annotations

import dataclasses
import os
import socket
import time
from pathlib import Path
from typing import Any

from ...core.files.documents import write_document
from ...core.errors import LenticalibError
from ...core.files.outputs import staged_folder
from ...core.profile import save_profile
from ..routing.fit_pipeline import fit_capture_sets
from ..routing.report import REPORT_FILES, fit_summary, write_report
from .identity import RECORD, RECORD_NAME, FitOptions, input_identity, is_done, read_record

PROFILE_NAME = "profile.json"
REPORT_NAME = "profile-report"  # beside the profile, as ``lenticalib fit`` names it (NAME-report/)
PANEL_CONTENTS = (PROFILE_NAME, REPORT_NAME, *(f"{REPORT_NAME}/{name}" for name in REPORT_FILES), RECORD_NAME)
"""What a panel folder holds (patterns, :func:`lenticalib.core.files.outputs.check_output_folder`): a folder
holding anything else is not replaced."""


def worker_name() -> str:
    """``HOST:PID`` of the process running the task (the row's ``worker``)."""
    return f"{socket.gethostname()}:{os.getpid()}"


def missing_folders(paths: list[str]) -> list[str]:
    """Those of ``paths`` that this process does not see as folders (run on every worker before a
    fleet run starts: a worker that cannot see the capture folders or the output folder refuses)."""
    return [p for p in paths if not os.path.isdir(p)]


def failed_row(name: str, capture_dir: str, error: str, **extra: Any) -> dict[str, Any]:
    """The row of a panel that has no fit: ``status`` failed and the reason (one line)."""
    return {"name": name, "status": "failed", "error": error, "capture_set": capture_dir, "fitted": False,
            "profile": None, "report": None, **extra}


def fitted_row(name: str, capture_dir: str, panel: Path, result, profile_written: bool) -> dict[str, Any]:
    """The row of a fitted panel: verdict, paths, and the fit's figures (the profile's constants with
    their 1-sigma uncertainties, the quality numbers the gates judge)."""
    profile, quality = result.profile, result.quality
    unc = profile.uncertainty or {}
    row = {"name": name, "status": "ok" if result.trusted else "untrusted",
           "error": None if result.trusted else "; ".join(result.problems),
           "capture_set": capture_dir, "fitted": True,
           "profile": str(panel / PROFILE_NAME) if profile_written else None, "report": str(panel / REPORT_NAME),
           "seconds": round(float(result.seconds), 2), "views": int(profile.views),
           "subpixel_order": profile.subpixel_order if profile.is_stripe else "cells"}
    for key in ("period", "slant", "offset", "reference_view"):
        row[key] = float(getattr(profile, key))
        row[f"{key}_sigma"] = None if unc.get(key) is None else float(unc[key])
    for key in ("block_residual_rms_views", "predicted_error_worst_views", "predicted_error_centre_views",
                "coherence"):
        row[key] = None if quality.get(key) is None else float(quality[key])
    return row


def _with_command(result, command: str | None):
    """``result`` whose profile's provenance names ``command`` (the batch command line)."""
    profile = result.profile
    if command is None or not profile.provenance:
        return result
    return dataclasses.replace(result, profile=profile.replace(provenance={**profile.provenance, "command": command}))


def _write_panel(panel: Path, capture_dir: str, inputs: tuple, record: dict, result=None,
                 write_profile: bool = False) -> None:
    """Write the panel folder whole (staged): the report and profile of ``result`` (when given) and
    the record."""
    with staged_folder(panel, "panel folder", PANEL_CONTENTS, inputs=inputs) as stage:
        if result is not None:
            summary = fit_summary(result, capture_dir, report=panel / REPORT_NAME,
                                  output=panel / PROFILE_NAME if write_profile else None)
            write_report(result, stage / REPORT_NAME, capture_dir, summary)
            if write_profile:
                save_profile(result.profile, stage / PROFILE_NAME)
        write_document(stage / RECORD_NAME, RECORD, record)


def fit_panel(capture_dir: str, panel_dir: str, options: FitOptions, command: str | None = None) -> dict[str, Any]:
    """Fit the panel photographed in ``capture_dir`` into ``panel_dir`` unless it is done already.

    ARGUMENTS: ``capture_dir``: a capture folder (``patterns.json``, ``captures/``), absolute;
    ``panel_dir``: the panel's output folder (module docstring), absolute; ``options``: the fit
    options; ``command``: the command line for the profile's provenance.

    RETURNED VALUE: the panel's row (``name``, ``status`` ok/untrusted/failed, ``error``,
    ``fitted``: whether this call fitted it (False: the record of an earlier fit of the same
    inputs, :func:`.identity.is_done`), ``worker``, ``identity``, the paths and the fit's figures).
    """
    panel, name, started = Path(panel_dir), Path(panel_dir).name, time.monotonic()
    try:
        identity = input_identity(capture_dir, options)
    except LenticalibError as exc:  # this worker cannot read the folder: nothing written, tried again next run
        return failed_row(name, capture_dir, str(exc), worker=worker_name())
    record = read_record(panel)
    if is_done(record, identity):  # the earlier fit's row (its worker, its seconds), at this folder's paths
        row = record["row"]
        return {**row, "fitted": False, "capture_set": capture_dir, "report": str(panel / REPORT_NAME),
                "profile": str(panel / PROFILE_NAME) if row.get("profile") else None}
    base = {"identity": identity, "worker": worker_name()}
    inputs = (capture_dir,)
    try:
        run = fit_capture_sets(capture_dir, views=options.views)  # no outputs: the panel folder is written below
    except LenticalibError as exc:
        row = {**failed_row(name, capture_dir, str(exc)), **base,
               "seconds": round(time.monotonic() - started, 2)}
        _write_panel(panel, capture_dir, inputs, {**RECORD.envelope(), "identity": identity,
                                                 "options": options.to_dict(), "row": row})
        return row
    result = _with_command(run.result, command)
    write_profile = bool(result.trusted or options.force)
    row = {**fitted_row(name, capture_dir, panel, result, write_profile), **base}
    _write_panel(panel, capture_dir, inputs, {**RECORD.envelope(), "identity": identity,
                                             "options": options.to_dict(), "row": row},
                 result=result, write_profile=write_profile)
    return row
