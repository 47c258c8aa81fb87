"""The fleet's summary: one row per panel in ``summary.json`` and ``summary.csv``, with the fleet's
limits and the panels outside them.

``summary.json`` (format ``lenticalib.fleet-summary``)::

    {"format", "format_version",
     "panels": [{"name", "status", "error", ...the fit's figures...}],   # in the order given
     "counts": {"ok": N, "untrusted": N, "failed": N, "fitted": N, "reused": N},
     "options": {"views", "force"},
     "quantities": {"period": {"unit", "median", "spread", "low", "high", "gate", "outliers": [names]}, ...},
     "outliers": [{"name", "quantity", "value", "low", "high"}]}

A row's ``status`` is ``ok`` (a trusted fit), ``untrusted`` (a fit that failed a quality gate:
``error`` lists why) or ``failed`` (no fit: ``error`` is the reason, one line); ``fitted`` says
whether this run fitted the panel (False: its inputs were those of an earlier run's fit, which
was kept).  The fit's figures (:func:`.task.fitted_row`) are the profile's ``period``, ``slant``
and ``offset`` (subpixels, pixels per row, subpixels) and ``reference_view`` with their
1-sigma (``*_sigma``), ``views``, ``subpixel_order`` and the quality numbers in views.

Limits (:func:`fleet_statistics`): for a constant, the fleet's median +- :data:`OUTLIER_SPREADS`
spreads, the spread being the larger of the robust standard deviation across the panels
(1.4826 x the median absolute deviation) and the median of the panels' own 1-sigma (so that a
fleet of identical panels does not call measurement noise an outlier); with fewer than
:data:`MIN_PANELS_FOR_LIMITS` fitted panels there are no such limits.  For a quality number the
limit is the fit's own quality gate (:mod:`lenticalib.calib.routing.fit`).  An outlier is a fitted panel
outside a limit; an outlier on a constant keeps its status (it is a panel to look at, not a
failed fit).  ``summary.csv`` has one line per panel with :data:`COLUMNS`.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from ...core.files.atomic import write_text_atomic
from ...core.files.documents import FORMATS, write_document
from ..routing.fit import MAX_BLOCK_RESIDUAL_RMS, MAX_PREDICTED_CENTRING, MAX_PREDICTED_ERROR
from .identity import STATUSES

DOCUMENT = FORMATS["lenticalib.fleet-summary"]
SUMMARY_NAME, CSV_NAME = "summary.json", "summary.csv"
OUTLIER_SPREADS = 5.0
MIN_PANELS_FOR_LIMITS = 3
ROBUST_SIGMA = 1.4826  # MAD -> standard deviation of a normal distribution

QUANTITIES: dict[str, tuple[str, str, float | None]] = {
    # key: (label, unit, the fit's gate: an upper limit) -- a constant has no gate: the fleet gives its limits
    "period": ("period", "subpixels", None),
    "slant": ("slant", "pixels per row", None),
    "offset": ("offset", "subpixels", None),
    "block_residual_rms_views": ("residual over panel blocks (RMS)", "views", MAX_BLOCK_RESIDUAL_RMS),
    "predicted_error_worst_views": ("predicted error at the worst corner (1-sigma)", "views", MAX_PREDICTED_ERROR),
    "predicted_error_centre_views": ("predicted centring error (1-sigma)", "views", MAX_PREDICTED_CENTRING),
}
COLUMNS = ("name", "status", "error", "fitted", "period", "period_sigma", "slant", "slant_sigma", "offset",
           "offset_sigma", "reference_view", "reference_view_sigma", "views", "subpixel_order",
           "block_residual_rms_views", "predicted_error_worst_views", "predicted_error_centre_views", "coherence",
           "seconds", "worker", "capture_set", "profile", "report", "identity")


def _number(value: Any) -> float | None:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value) else None


def fleet_statistics(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per quantity of :data:`QUANTITIES`: ``unit``, ``median``, ``spread``, ``low``/``high`` (the limits;
    None where there is none), ``gate`` and ``outliers`` (names of the fitted panels outside), over
    the rows with a fit (ok or untrusted)."""
    fitted = [r for r in rows if r.get("status") in ("ok", "untrusted")]
    stats = {}
    for key, (label, unit, gate) in QUANTITIES.items():
        pairs = [(r["name"], _number(r.get(key)), _number(r.get(f"{key}_sigma"))) for r in fitted]
        pairs = [p for p in pairs if p[1] is not None]
        values = np.array([v for _, v, _ in pairs], dtype=float)
        entry: dict[str, Any] = {"label": label, "unit": unit, "gate": gate, "median": None, "spread": None,
                                 "low": None, "high": gate}
        if values.size:
            median = float(np.median(values))
            entry["median"] = median
            if gate is None and values.size >= MIN_PANELS_FOR_LIMITS:
                sigmas = [s for _, _, s in pairs if s is not None]
                spread = max(ROBUST_SIGMA * float(np.median(np.abs(values - median))),
                             float(np.median(sigmas)) if sigmas else 0.0)
                entry.update(spread=spread, low=median - OUTLIER_SPREADS * spread,
                             high=median + OUTLIER_SPREADS * spread)
        low, high = entry["low"], entry["high"]
        entry["outliers"] = [name for name, v, _ in pairs
                             if (low is not None and v < low) or (high is not None and v > high)]
        stats[key] = entry
    return stats


def fleet_summary(rows: list[dict[str, Any]], options: dict[str, Any]) -> dict[str, Any]:
    """The ``summary.json`` document of ``rows`` (module docstring); ``options``: the fit options."""
    counts = {status: sum(r.get("status") == status for r in rows) for status in STATUSES}
    counts["fitted"] = sum(bool(r.get("fitted")) for r in rows)
    counts["reused"] = sum(r.get("status") in ("ok", "untrusted") and not r.get("fitted") for r in rows)
    stats = fleet_statistics(rows)
    outliers = [{"name": name, "quantity": key, "value": next(r[key] for r in rows if r["name"] == name),
                 "low": entry["low"], "high": entry["high"]}
                for key, entry in stats.items() for name in entry["outliers"]]
    return {**DOCUMENT.envelope(), "panels": rows, "counts": counts, "options": dict(options),
            "quantities": stats, "outliers": outliers}


def csv_text(rows: list[dict[str, Any]]) -> str:
    """``summary.csv``: a header of :data:`COLUMNS` and one line per row (empty cells for None)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(COLUMNS)
    for row in rows:
        writer.writerow(["" if row.get(c) is None else row.get(c) for c in COLUMNS])
    return out.getvalue()


def write_summary(folder: Path, summary: dict[str, Any]) -> tuple[Path, Path]:
    """Write ``summary.json`` and ``summary.csv`` into ``folder``, each atomically; their paths."""
    json_path = write_document(folder / SUMMARY_NAME, DOCUMENT, summary)
    csv_path = write_text_atomic(folder / CSV_NAME, csv_text(summary["panels"]))
    return json_path, csv_path
