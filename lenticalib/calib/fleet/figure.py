"""The fleet figure ``fleet.png``: each constant's and quality number's distribution across the panels.

One panel of the figure per quantity of :data:`.summary.QUANTITIES` (period, slant, offset, the
block residual, the predicted errors): each fitted panel is a dot at its value (y) against its
place in the run (x, the order the capture folders were given: a drift along the line shows
as a slope), with the fleet's median (solid), the limits (dashed red: the fleet's median +- 5
spreads for a constant, the fit's quality gate for a quality number, :func:`.summary.fleet_statistics`)
and every panel outside a limit drawn in red and named.  Failed panels have no values: a grey
band marks their places, and the figure's title counts them.  Written with :func:`lenticalib.core.figures.write_figures` (a
:data:`FIGURE_SIZE` pixel PNG, fonts of at least 10 pt, its texts and numbers recorded in the PNG).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ...core.figures import write_figures
from .summary import QUANTITIES

FIGURE_NAME = "fleet.png"
FIGURE_SIZE = (1800, 1000)
_YLABELS = {"block_residual_rms_views": "RMS residual", "predicted_error_worst_views": "1-sigma error",
            "predicted_error_centre_views": "1-sigma error"}
_MAX_NAMED = 12  # outliers named on one plot; more are counted


def _draw(fig, summary: dict[str, Any]) -> dict[str, Any]:
    from matplotlib.ticker import MaxNLocator  # lazy: matplotlib is imported only when a figure is drawn

    rows, counts, stats = summary["panels"], summary["counts"], summary["quantities"]
    fitted = [(i + 1, r) for i, r in enumerate(rows) if r.get("status") in ("ok", "untrusted")]
    fig.suptitle(f"Fleet of {len(rows)} panels: each constant across the panels ({counts['ok']} ok, "
                 f"{counts['untrusted']} untrusted, {counts['failed']} failed)")
    axes = fig.subplots(2, 3)
    numbers: dict[str, Any] = {"panels": len(rows), **counts}
    for ax, (key, (label, unit, gate)) in zip(axes.flat, QUANTITIES.items()):
        entry = stats[key]
        points = [(x, r[key], r["name"]) for x, r in fitted if isinstance(r.get(key), (int, float))]
        outliers = set(entry["outliers"])
        inside = [(x, v) for x, v, n in points if n not in outliers]
        outside = [(x, v, n) for x, v, n in points if n in outliers]
        if inside:
            ax.plot(*zip(*inside), "o", color="tab:blue", label="panel")
        if outside:
            ax.plot([x for x, _, _ in outside], [v for _, v, _ in outside], "o", color="tab:red", label="outlier")
            for x, v, name in outside[:_MAX_NAMED]:
                ax.annotate(name, (x, v), textcoords="offset points", xytext=(5, 5), fontsize=10, color="tab:red")
            if len(outside) > _MAX_NAMED:
                ax.text(0.02, 0.02, f"+{len(outside) - _MAX_NAMED} more outliers", transform=ax.transAxes,
                        fontsize=10, color="tab:red")
        if entry["median"] is not None:
            ax.axhline(entry["median"], color="0.3", lw=1, label=f"median {entry['median']:.6g}")
        for which in ("low", "high"):
            limit = entry[which]
            if limit is not None:
                name = "quality gate" if gate is not None else "fleet limit (median \u00b1 5 spreads)"
                ax.axhline(limit, color="tab:red", ls="--", lw=1.2,
                           label=name if which == "high" or entry["high"] is None else None)
        failed = [i + 1 for i, r in enumerate(rows) if r.get("status") == "failed"]
        for n, x in enumerate(failed):
            ax.axvspan(x - 0.4, x + 0.4, color="0.85", zorder=0, label="failed panel (no fit)" if n == 0 else None)
        if not points:
            ax.text(0.5, 0.5, "no fitted panel", transform=ax.transAxes, ha="center", va="center", fontsize=11)
        ax.set_title(label)
        ax.set_xlabel("panel (in the order given)")
        ax.set_ylabel(f"{_YLABELS.get(key, key)} ({unit})")
        ax.set_xlim(0.5, max(len(rows), 1) + 0.5)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.legend(loc="best", fontsize=10)
        numbers[key] = {k: entry[k] for k in ("median", "low", "high")} | {"outliers": sorted(outliers)}
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return numbers


def write_fleet_figure(folder: Path, summary: dict[str, Any]) -> Path:
    """Draw ``fleet.png`` of ``summary`` (the ``summary.json`` document, :func:`.summary.fleet_summary`)
    into ``folder``, atomically; its path."""
    write_figures(folder, [(FIGURE_NAME, _draw)], {FIGURE_NAME: FIGURE_SIZE}, summary)
    return folder / FIGURE_NAME
