"""The avatar diagnostics report: per avatar its record as a document and two figures.

Written into one folder (``lenticalib avatar diagnose --report DIR``, staged as a whole, see
:func:`lenticalib.core.files.outputs.staged_folder`); NAME is the avatar file's stem:

    NAME.json          the record of :func:`.diagnose.diagnose_avatars` as a document
                       ("lenticalib.avatar-diagnostics") with its provenance (inputs with SHA-256,
                       options, lenticalib version)
    NAME-metrics.png   each of the seven metrics against the camera's yaw over the whole cone,
                       the -25 and +25 degree side views marked: where on the panel the
                       artifacts appear
    NAME-sides.png     the -25 and +25 degree views over grey, with the dilated mesh mask D
                       (outline), the alpha boundary B, the neck-rear region N and the crop drawn
                       over them, and their metrics

Figures are drawn by :func:`lenticalib.core.figures.write_figures` (title, axes with units,
fonts of at least 10 pt, the numbers they state recorded in the PNG).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ...core.files.documents import FORMATS, write_document
from ...core.figures import write_figures
from ...core.files.outputs import Inputs, staged_folder
from ...core.profile import make_provenance
from .side_metrics import (DILATION_PX, HIGHER_IS_BETTER, METRIC_MEANINGS, METRICS, NECK_REAR, Crop,
    alpha_boundary, dilate)

DOCUMENT = FORMATS["lenticalib.avatar-diagnostics"]
FIGURE_SIZES = {"metrics": (1800, 1500), "sides": (1800, 1000)}
REPORT_WHAT = "avatar diagnostics report"
REPORT_CONTENTS = ("*.json", "*-metrics.png", "*-sides.png")
UNITS = {"O_alpha": "share of the view's alpha", "G_m": "share of the view's alpha", "G_d": "alpha per pixel of N",
         "S_n": "4A(1-A) per pixel of N", "S_alpha": "4A(1-A) per pixel of D", "F_c": "saturation (0..1)",
         "E_c": "|grad C|_1 per pixel (1/px)"}


def write_diagnose_report(directory: str | os.PathLike, records: list[dict], names: list[str], options, *,
                          inputs: Inputs) -> Path:
    """Write the report of ``records`` (with their ``_maps``) under ``names`` into ``directory``, staged
    (``directory`` may neither be nor hold one of the ``inputs``, the files the diagnosis read)."""
    with staged_folder(directory, REPORT_WHAT, REPORT_CONTENTS, inputs=inputs) as stage:
        for record, name in zip(records, names):
            body = {k: v for k, v in record.items() if k != "_maps"}
            read = [record["avatar"]]
            if record["mask_source"].startswith("mesh file "):
                read.append(record["mask_source"][len("mesh file "):].split(" (")[0])
            if record["controls"] and record["controls"]["source"] != "demo":
                read.append(record["controls"]["source"])
            body["provenance"] = make_provenance("avatar diagnose", inputs=read, options=_options(options))
            write_document(stage / f"{name}.json", DOCUMENT, body)
            write_figures(stage, [(f"{name}-metrics.png", _metrics_figure), (f"{name}-sides.png", _sides_figure)],
                          {f"{name}-metrics.png": FIGURE_SIZES["metrics"], f"{name}-sides.png": FIGURE_SIZES["sides"]},
                          record)
    return Path(directory)


def _options(options) -> dict:
    import dataclasses

    out = dataclasses.asdict(options)
    out["view_size"] = list(out["view_size"])
    return out


def _metrics_figure(fig, record: dict) -> dict:
    views = record["views"]
    yaw = np.array([v["yaw_deg"] for v in views])
    fig.suptitle(f"Side-view diagnostics along the view cone: {Path(record['avatar']).name} "
                 f"({len(views)} views, {record['renderer']} renderer)", fontsize=14)
    gs = fig.add_gridspec(4, 2, left=0.07, right=0.98, top=0.92, bottom=0.06, hspace=0.62, wspace=0.22)
    numbers = {}
    for k, m in enumerate(METRICS):
        ax = fig.add_subplot(gs[k // 2, k % 2])
        values = np.array([v[m] for v in views])
        ax.plot(yaw, values, "o-", ms=3, lw=1.2, color="tab:blue", label="view")
        for s in record["side"]["views"]:
            ax.plot([s["yaw_deg"]], [s[m]], "s", ms=7, color="tab:red")
        ax.axvline(-25, color="tab:red", ls="--", lw=0.8)
        ax.axvline(25, color="tab:red", ls="--", lw=0.8)
        better = "higher is better" if m in HIGHER_IS_BETTER else "lower is better"
        ax.set_title(f"{m}: {METRIC_MEANINGS[m]} ({better}); mean at +-25 deg {record['side']['mean'][m]:.4g}",
                     fontsize=11)
        ax.set_xlabel("camera yaw (degrees; + the viewer's right)")
        ax.set_ylabel(UNITS[m], fontsize=10)
        ax.grid(alpha=0.3)
        lo, hi = float(values.min()), float(values.max())
        if hi - lo < 1e-9:
            ax.set_ylim(lo - 0.05 * max(abs(lo), 1e-3), hi + 0.05 * max(abs(hi), 1e-3))
        numbers[m] = record["side"]["mean"][m]
    ax = fig.add_subplot(gs[3, 1])
    ax.axis("off")
    crop = record["crop"]
    ax.text(0.0, 0.95, "\n".join([
        f"mask: {record['mask_source']}",
        f"crop: x {crop['x0']}..{crop['x1'] - 1}, y {crop['y0']}..{crop['y1'] - 1} px of "
        f"{record['view_size'][0]} x {record['view_size'][1]}",
        f"D: the mask dilated by {DILATION_PX} px; red: the +-25 degree side views",
    ]), va="top", fontsize=10, wrap=True)
    return numbers


def _sides_figure(fig, record: dict) -> dict:
    maps = record["_maps"]
    crop = Crop(**{k: record["crop"][k] for k in ("x0", "y0", "x1", "y1")})
    fig.suptitle(f"The side views of {Path(record['avatar']).name} with the regions the metrics use", fontsize=14)
    numbers = {}
    for k, side in enumerate(record["side"]["views"]):
        i = int(np.argmin(np.abs(maps["yaws"] - side["yaw_deg"])))
        rgba = maps["rgba"][i]
        alpha = rgba[..., 3]
        grey = 0.5
        shown = np.clip(rgba[..., :3] + grey * (1 - alpha[..., None]), 0, 1)
        ys, xs = crop.slices()
        ax = fig.add_axes((0.05 + 0.48 * k, 0.10, 0.42, 0.76))
        extent = (crop.x0 - 0.5, crop.x1 - 0.5, crop.y1 - 0.5, crop.y0 - 0.5)
        ax.imshow(shown[ys, xs], extent=extent, interpolation="nearest")
        D = dilate(maps["masks"][i])[ys, xs]
        B = alpha_boundary(alpha)[ys, xs]
        gx, gy = np.arange(crop.x0, crop.x1), np.arange(crop.y0, crop.y1)
        ax.contour(gx, gy, D.astype(float), levels=[0.5], colors=["cyan"], linewidths=1.2)
        by, bx = np.nonzero(B)
        ax.plot(bx + crop.x0, by + crop.y0, ",", color="magenta")
        y0, y1, left, right = NECK_REAR
        for xa, xb in ((0.0, left), (right, 1.0)):
            ax.add_patch(_rect(crop.x0 + xa * crop.width - 0.5, crop.y0 + y0 * crop.height - 0.5,
                               (xb - xa) * crop.width, (y1 - y0) * crop.height))
        ax.set_xlabel("x (view pixels)")
        ax.set_ylabel("y (view pixels)")
        values = ", ".join(f"{m} {side[m]:.3g}" for m in METRICS)
        ax.set_title(f"yaw {side['yaw_deg']:+.1f} degrees\n{values}", fontsize=10)
        numbers[f"yaw_{k}"] = side["yaw_deg"]
    fig.text(0.5, 0.02, f"cyan: the mesh mask dilated by {DILATION_PX} px (D); magenta: the alpha boundary B "
             "(A > 0.03); orange: the neck-rear region N; over grey", ha="center", fontsize=11)
    return numbers


def _rect(x, y, w, h):
    from matplotlib.patches import Rectangle

    return Rectangle((x, y), w, h, fill=True, facecolor="orange", alpha=0.15, edgecolor="orange", lw=1.2)


def _cell(value: float) -> str:
    return f"{value:.4f}" if abs(value) < 100 else f"{value:.4g}"


def diagnose_table(result: dict) -> list[str]:
    """The printed table of :func:`.diagnose.diagnose_avatars`' result: for one avatar its side
    views, their mean and the worst view of the cone per metric (its yaw "-" where every view has the
    same value); for several, one row per avatar
    (the mean over the two side views, as the paper's Table 1) with the best marked ``*`` and the
    second best ``+``."""
    width = 10
    head = f"{'':<14}" + "".join(f"{m:>{width}}" for m in METRICS)
    if "avatars" not in result:
        r = result
        crop = r["crop"]
        lines = [f"{Path(r['avatar']).name}: {len(r['views'])} views, {r['renderer']} renderer, mask: "
                 f"{r['mask_source']}; crop x {crop['x0']}..{crop['x1'] - 1}, y {crop['y0']}..{crop['y1'] - 1}",
                 head]
        for s in r["side"]["views"]:
            lines.append(f"{s['yaw_deg']:+.1f} deg".ljust(14) + "".join(f"{_cell(s[m]):>{width}}" for m in METRICS))
        lines.append("mean +-25".ljust(14) + "".join(f"{_cell(r['side']['mean'][m]):>{width}}" for m in METRICS))
        lines.append("worst view".ljust(14) + "".join(f"{_cell(r['worst'][m]['value']):>{width}}" for m in METRICS))
        # a metric equal in every view has no worst view: its yaw is "-", not the first view's
        lines.append("  at yaw".ljust(14) + "".join(
            f"{'-':>{width}}" if len({v[m] for v in r["views"]}) == 1 else f"{r['worst'][m]['yaw_deg']:>{width}.1f}"
            for m in METRICS))
        lines.append("lower is better, except E_c (contour sharpness: higher is better); yaw in degrees")
        return lines
    records, best = result["avatars"], result["best"]
    names = [Path(r["avatar"]).name for r in records]
    first = max(14, max(len(n) for n in names) + 2)
    lines = ["mean over the -25 and +25 degree side views, one row per avatar",
             f"{'avatar':<{first}}" + "".join(f"{m:>{width + 1}}" for m in METRICS)]
    for k, (name, r) in enumerate(zip(names, records)):
        cells = []
        for m in METRICS:
            mark = "*" if best[m][0] == k else "+" if len(best[m]) > 1 and best[m][1] == k else " "
            cells.append(f"{_cell(r['side']['mean'][m]) + mark:>{width + 1}}")
        lines.append(f"{name:<{first}}" + "".join(cells))
    lines.append("* best, + second best; lower is better, except E_c (contour sharpness: higher is better)")
    return lines
