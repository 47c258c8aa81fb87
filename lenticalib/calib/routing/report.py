"""The fit report: figures a person reads to see why a fit is good or bad, plus a summary.

Written into one folder (each file atomically; ``lenticalib fit`` stages the whole folder, see
:func:`lenticalib.core.files.outputs.staged_folder`):

    panel.png       the panel as found in the photos (axes in photo pixels): mean brightness,
                    the panel outline and measured panel columns/rows at eighths of the panel
    view-map.png    a 24 x 14 panel-pixel crop at the panel centre, each subpixel drawn: the
                    fitted profile's w per subpixel with the measured w* of the samples the fit
                    used as dots at their measured panel position, and those samples' residual;
                    the distribution of the residual (single samples, panel-block means); the
                    residual per panel block over the whole panel -- the summary's
                    ``block_residual_*``, the fit's headline residual
    residual.png    measured - fitted (the samples' residual), smoothed per camera pixel (photo
                    coordinates), and per panel block (panel coordinates), in views
    summary.json    :func:`fit_summary`: the document ``lenticalib fit --json`` prints

Every residual a figure shows is ``PlaneFit.residual`` of the fit's samples (measured minus
fitted, wrapped, in views), the one the quality numbers come from; the numbers a figure states
are those of the summary, recorded in the PNG (:func:`lenticalib.core.figures.read_figure_record`).  Every figure has a
title, axes labelled with units and a colour bar with units; sizes are :data:`FIGURE_SIZES`
(pixels), fonts at least 10 pt.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from ...core.files.documents import FORMATS, write_document
from ...core.figures import jsonable, write_figures
from ...core.routing import view_coordinate

FIGURE_SIZES = {"panel.png": (1800, 1200), "view-map.png": (1800, 1500), "residual.png": (1800, 700)}
REPORT_FILES = tuple(FIGURE_SIZES) + ("summary.json",)
DOCUMENT = FORMATS["lenticalib.fit-report"]  # summary.json
CROP = (24, 14)  # panel pixels (width, height) of the view-map crop: 72 x 14 subpixels, each resolved


def fit_summary(result, capture_dir, report: str | os.PathLike | None = None,
                output: str | os.PathLike | None = None) -> dict:
    """The summary of a fit: ``summary.json`` of the report and what ``lenticalib fit --json`` prints.

    Keys: the envelope (``format`` "lenticalib.fit-report", ``format_version``), ``capture_set``,
    ``trusted``, ``problems``, ``warnings`` (checks that could not measure), ``seconds``,
    ``output`` (the profile path, or None when none was written), ``report`` (folder), ``profile``
    (the profile as written, its provenance without the quality block), ``quality`` (every quality number, once), and
    ``view_direction`` (the evidence of ``--moved-right``) when the fit had a second capture set.
    """
    profile = result.profile.to_dict()
    if "provenance" in profile:
        profile["provenance"] = {k: v for k, v in profile["provenance"].items() if k != "quality"}
    summary = {**DOCUMENT.envelope(), "capture_set": str(capture_dir), "trusted": bool(result.trusted),
               "problems": list(result.problems), "warnings": list(result.warnings),
               "seconds": round(float(result.seconds), 2),
               "output": None if output is None else str(output),
               "report": None if report is None else str(report),
               "profile": profile, "quality": result.quality}
    if getattr(result, "direction", None) is not None:
        summary["view_direction"] = result.direction
    return json.loads(json.dumps(summary, default=jsonable))


def write_report(result, directory: str | os.PathLike, capture_dir: str | os.PathLike,
                 summary: dict | None = None) -> Path:
    """Write the report of ``result`` (a :class:`~lenticalib.calib.routing.fit.FitResult`) into ``directory``.

    ``directory`` is created if missing (its parent must exist).  ``summary`` is written as
    ``summary.json`` (default: :func:`fit_summary` of the result).
    """
    directory = Path(directory)
    directory.mkdir(exist_ok=True)
    write_figures(directory, [("panel.png", _panel_figure), ("view-map.png", _view_map_figure),
                              ("residual.png", _residual_figure)], FIGURE_SIZES, result)
    summary = fit_summary(result, capture_dir, report=directory) if summary is None else summary
    write_document(directory / "summary.json", DOCUMENT, summary)
    return directory


def _colorbar(fig, ax, mappable, label: str, extend: str = "neither"):
    """A colour bar of the height of ``ax``, just right of it."""
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    cax = make_axes_locatable(ax).append_axes("right", size="3%", pad=0.12)
    return fig.colorbar(mappable, cax=cax, label=label, extend=extend)


def _photo_extent(result, shape):
    """(scale x, scale y, extent) mapping working-resolution map indices to photo pixels."""
    h, w = shape
    pw, ph = result.quality.get("photo_resolution", [w, h])
    sx, sy = pw / w, ph / h
    return sx, sy, (0, w * sx, h * sy, 0)


def _sample_residuals(result):
    """(samples, residual, weights) of the fit: the samples it used (:class:`.model.PlaneSamples`,
    panel X in subpixels, Y in rows), measured minus fitted in views, wrapped to [-N/2, N/2)
    (:meth:`.model.PlaneFit.residual`, the residual the quality numbers are computed from), and the
    fit's robust weights."""
    maps = result.maps
    samples = maps["samples"]
    return samples, maps["fit"].residual(samples) * result.profile.views, maps["weights"]


def _panel_figure(fig, result) -> None:
    from matplotlib.colors import PowerNorm
    from matplotlib.lines import Line2D

    maps, profile = result.maps, result.profile
    mask, valid = maps["mask"], maps["valid"]
    dc = maps["dc"]
    sx, sy, extent = _photo_extent(result, dc.shape)
    ax = fig.add_axes((0.06, 0.07, 0.84, 0.86))
    level = max(float(np.percentile(dc, 99.5)), 1e-6)
    im = ax.imshow(np.clip(dc / level, 0, 1), cmap="gray", norm=PowerNorm(1 / 2.2, 0, 1), extent=extent,
                   interpolation="antialiased")
    xs = (np.arange(dc.shape[1]) + 0.5) * sx
    ys = (np.arange(dc.shape[0]) + 0.5) * sy
    ax.contour(xs, ys, mask.astype(float), levels=[0.5], colors=["lime"], linewidths=1.5)
    cols = [profile.width * k / 8 for k in range(1, 8)]
    rows = [profile.height * k / 8 for k in range(1, 8)]
    cx = ax.contour(xs, ys, np.where(valid, maps["x"] / 3.0, np.nan), levels=cols, colors=["orange"],
                    linewidths=1.0)
    cy = ax.contour(xs, ys, np.where(valid, maps["y"], np.nan), levels=rows, colors=["deepskyblue"],
                    linewidths=1.0)
    import matplotlib.patheffects as effects

    # labels upright at each line's end (columns above the panel, rows left of it), on a dark outline
    outline = [effects.withStroke(linewidth=3, foreground="black")]
    for contours, levels, axis in ((cx, cols, 1), (cy, rows, 0)):
        for level, segments in zip(levels, contours.allsegs):
            if not segments:
                continue
            line = max(segments, key=len)
            end = line[int(np.argmin(line[:, axis]))]
            ax.text(end[0] - (8 if axis == 0 else 0), end[1] - (8 if axis == 1 else 0),
                    f"{'x' if axis == 1 else 'y'}={level:.0f}", color="orange" if axis == 1 else "deepskyblue",
                    fontsize=11, fontweight="bold", ha="center" if axis == 1 else "right",
                    va="bottom" if axis == 1 else "center", path_effects=outline)
    ax.set_title(f"Panel found in the photos ({100 * mask.mean():.0f}% of the frame), with the measured "
                 f"panel columns x and rows y at eighths of {profile.width}x{profile.height} panel pixels")
    ax.set_xlabel("camera x (photo pixels)")
    ax.set_ylabel("camera y (photo pixels)")
    ax.legend(handles=[Line2D([], [], color="lime", lw=1.5, label="panel outline (fringes found)"),
                       Line2D([], [], color="orange", lw=1.0, label="measured panel column x (panel pixels)"),
                       Line2D([], [], color="deepskyblue", lw=1.0, label="measured panel row y (panel pixels)")],
              loc="lower left", framealpha=0.85)
    _colorbar(fig, ax, im, "mean brightness, linear light (1 = 99.5th percentile)")


def _crop_box(profile):
    cw, ch = CROP
    x0 = max(0, min(profile.width - cw, int(round(profile.width / 2 - cw / 2))))
    y0 = max(0, min(profile.height - ch, int(round(profile.height / 2 - ch / 2))))
    return x0, y0, min(cw, profile.width), min(ch, profile.height)


def _view_map_figure(fig, result) -> dict:
    """The fitted w at every subpixel of a crop with the measured samples on it, the samples'
    residuals, and the fit's residual per panel block (the summary's ``block_residual_*``)."""
    from matplotlib.patches import Rectangle

    maps, profile, quality = result.maps, result.profile, result.quality
    n = profile.views
    samples, resid, weights = _sample_residuals(result)
    x0, y0, cw, ch = _crop_box(profile)
    grid = fig.add_gridspec(2, 3, height_ratios=(1.0, 2.0), width_ratios=(1.0, 1.0, 0.8), left=0.05, right=0.95,
                            top=0.9, bottom=0.05, wspace=0.32, hspace=0.3)
    px, py = samples.x / 3.0, samples.y
    inside = (px >= x0) & (px < x0 + cw) & (py >= y0) & (py < y0 + ch)
    measured = (samples.psi * n + n / 2) % n
    spread = float(np.percentile(np.abs(resid[weights > 0]), 99.5)) if np.any(weights > 0) else 1.0
    limit = min(n / 2, max(1.0, math.ceil(2 * spread) / 2))  # views; a fit a view off stands out

    # the profile's w at every subpixel of the crop (the routing the encoder uses), measured w* on it
    ax = fig.add_subplot(grid[0, 0])
    wfit = view_coordinate(profile, np.arange(y0, y0 + ch))[:, 3 * x0:3 * (x0 + cw)] % n
    im = ax.imshow(wfit, cmap="hsv", vmin=0, vmax=n, interpolation="nearest", extent=(x0, x0 + cw, y0 + ch, y0),
                   aspect="equal")
    groups = np.unique(samples.group)
    ax.set_xlim(x0, x0 + cw)
    ax.set_ylim(y0 + ch, y0)
    ax.apply_aspect()
    # dots about 0.7 of their spacing across (points^2), smaller for each further fine group on the same pixels
    box = ax.get_position()
    area = box.width * box.height * fig.get_figwidth() * fig.get_figheight() * 72.0 ** 2
    per_group = max(1, int(np.count_nonzero(inside & (samples.group == groups[0]))))
    size = float(np.clip(0.5 * area / per_group, 6.0, 64.0))
    sizes = {g: size / (1 + 1.2 * k) for k, g in enumerate(groups)}
    for g in groups:
        sel = inside & (samples.group == g)
        ax.scatter(px[sel], py[sel], c=measured[sel], cmap="hsv", vmin=0, vmax=n, s=sizes[g], edgecolors="black",
                   linewidths=0.7)
    ax.set_title(f"fitted w of each subpixel ({3 * cw}x{ch}); dots:\nmeasured w* of the {int(inside.sum())} "
                 f"samples here ({groups.size} fine group{'s' if groups.size != 1 else ''})")
    _colorbar(fig, ax, im, f"view (cyclic, 0..{n})")
    # the same samples' residuals, on the subpixel grid
    ax2 = fig.add_subplot(grid[0, 1])
    for xs in np.arange(3 * x0, 3 * (x0 + cw) + 1) / 3.0:
        ax2.axvline(xs, color="0.85" if xs % 1 else "0.6", lw=0.5, zorder=0)
    for ys in range(y0, y0 + ch + 1):
        ax2.axhline(ys, color="0.6", lw=0.5, zorder=0)
    for g in groups:
        sel = inside & (samples.group == g)
        im2 = ax2.scatter(px[sel], py[sel], c=resid[sel], cmap="coolwarm", vmin=-limit, vmax=limit, s=sizes[g],
                          edgecolors="black", linewidths=0.7)
    ax2.set_title("measured w* - fitted w of those samples;\ngrid: subpixels (light) and pixels")
    _colorbar(fig, ax2, im2, f"measured - fitted (views; ±{limit:g})", "both")
    for a in (ax, ax2):
        a.set_xlim(x0, x0 + cw)
        a.set_ylim(y0 + ch, y0)
        a.set_aspect("equal")
        a.set_xlabel("panel x (pixels)")
        a.set_ylabel("panel y (pixels)")

    # one sample's noise against the block means: the first averages out, the second is the misfit
    block = maps["block_residual_map"]
    finite = block[np.isfinite(block)]
    pixel_rms, block_rms = quality["pixel_residual_rms_views"], quality["block_residual_rms_views"]
    worst = quality["block_residual_worst_views"]
    ax3 = fig.add_subplot(grid[0, 2])
    bins = np.linspace(-limit, limit, 81)
    ax3.hist(np.clip(resid, -limit, limit), bins=bins, weights=weights, density=True, color="tab:gray",
             alpha=0.7, label=f"single samples: RMS {pixel_rms:.3f}")
    ax3.hist(np.clip(finite, -limit, limit), bins=np.linspace(-limit, limit, 60 * int(2 * limit) + 1), density=True,
             histtype="step", color="tab:red", lw=2, label=f"panel-block means: RMS {block_rms:.3f}")
    ax3.set_yscale("log")
    ax3.set_ylim(1e-4, 10 ** (math.ceil(math.log10(max(ax3.get_ylim()[1], 1e-3))) + 2))  # room for the legend
    ax3.set_xlim(-limit, limit)
    ax3.set_xlabel("measured - fitted (views)")
    ax3.set_ylabel("density (1/view, log scale)")
    ax3.set_title("residual: single samples (noise)\nand panel-block means (misfit)")
    ax3.legend(loc="upper left", fontsize=10, title="RMS in views", title_fontsize=10)

    lim = max(0.15, float(np.max(np.abs(finite))) if finite.size else 0.15)
    ax4 = fig.add_subplot(grid[1, :])
    im4 = ax4.imshow(block, cmap="coolwarm", vmin=-lim, vmax=lim, extent=(0, profile.width, profile.height, 0),
                     interpolation="nearest")
    ax4.add_patch(Rectangle((x0, y0), cw, ch, fill=False, edgecolor="black", linewidth=1.5))
    ax4.annotate("crop above", (x0 + cw, y0), xytext=(8, -4), textcoords="offset points", fontsize=11)
    ax4.set_title(f"Residual of the fit per panel block ({block.shape[1]}x{block.shape[0]} blocks; weighted mean of "
                  f"measured - fitted, less the mean):\nRMS {block_rms:.3f} views, worst {worst:.3f} views "
                  f"(summary: block_residual_rms_views, block_residual_worst_views)")
    ax4.set_xlabel("panel x (pixels)")
    ax4.set_ylabel("panel y (pixels)")
    _colorbar(fig, ax4, im4, f"mean measured - fitted (views; colours end at ±{lim:.2f})")
    fig.suptitle(f"View map: the fitted view coordinate w against the measured w* ({n} views, "
                 f"{samples.x.size} samples from the fine groups)\ntop: a {cw}x{ch} pixel crop at the panel centre "
                 f"(x {x0}..{x0 + cw}, y {y0}..{y0 + ch}), each subpixel drawn; right: how the residual is "
                 "distributed", fontsize=14)
    ax.apply_aspect()
    subpixel = ax.get_position().width * fig.get_figwidth() * fig.dpi / (3 * cw)  # figure pixels per subpixel
    return {"pixel_residual_rms_views": pixel_rms, "block_residual_rms_views": block_rms,
            "block_residual_worst_views": worst, "crop_pixels": [x0, y0, cw, ch], "crop_samples": int(inside.sum()),
            "colour_limit_views": limit, "subpixel_width_figure_pixels": subpixel}


def _residual_figure(fig, result) -> dict:
    import cv2

    maps, profile = result.maps, result.profile
    valid, take = maps["valid"], maps["sample_pixels"]
    samples, resid, weights = _sample_residuals(result)
    # each used fine group sampled the camera pixels of ``take`` (row-major): their weighted mean
    rows, cols = np.nonzero(take)
    num, den = np.zeros(take.shape, np.float32), np.zeros(take.shape, np.float32)
    for group in np.unique(samples.group):
        sel = samples.group == group
        num[rows, cols] += weights[sel] * resid[sel]
        den[rows, cols] += weights[sel]
    sigma = max(3.0, valid.shape[1] / 120)
    den_s = cv2.GaussianBlur(den, (0, 0), sigma)
    smooth = cv2.GaussianBlur(num, (0, 0), sigma) / np.maximum(den_s, 1e-12)
    smooth = np.where(valid & (den_s > 1e-3 * max(float(den_s.max()), 1e-12)), smooth, np.nan)
    block = maps["block_residual_map"]
    values = np.concatenate([smooth[np.isfinite(smooth)], block[np.isfinite(block)]])
    lim = max(0.15, float(np.percentile(np.abs(values), 99))) if values.size else 0.15
    sx, sy, extent = _photo_extent(result, valid.shape)
    axes = fig.subplots(1, 2, gridspec_kw={"left": 0.05, "right": 0.95, "top": 0.86, "bottom": 0.1,
                                           "wspace": 0.3})
    ax = axes[0]
    im = ax.imshow(smooth, cmap="coolwarm", vmin=-lim, vmax=lim, extent=extent)
    ax.set_title(f"per camera pixel, smoothed (Gaussian sigma {sigma * sx:.0f} photo pixels)")
    ax.set_xlabel("camera x (photo pixels)")
    ax.set_ylabel("camera y (photo pixels)")
    _colorbar(fig, ax, im, "measured - fitted (views)", "both")
    ax = axes[1]
    block_rms = result.quality["block_residual_rms_views"]
    im = ax.imshow(block, cmap="coolwarm", vmin=-lim, vmax=lim, extent=(0, profile.width, profile.height, 0))
    ax.set_title(f"per panel block ({block.shape[1]}x{block.shape[0]}), RMS {block_rms:.3f} views")
    ax.set_xlabel("panel x (pixels)")
    ax.set_ylabel("panel y (pixels)")
    _colorbar(fig, ax, im, "mean measured - fitted (views)", "both")
    fig.suptitle("Residual of the fit: measured minus fitted view coordinate, wrapped, in views", fontsize=14)
    return {"block_residual_rms_views": block_rms}
