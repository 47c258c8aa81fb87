"""The fit report: figures a person reads to see why a fit is good or bad, plus a summary.

Written into one folder (each file atomically; ``lenticalib fit`` stages the whole folder, see
:func:`lenticalib.outputs.staged_folder`):

    panel.png       the panel as found in the photos (axes in photo pixels): mean brightness,
                    the panel outline and measured panel columns/rows at eighths of the panel
    view-map.png    a 120 x 70 panel-pixel crop at the panel centre, in panel coordinates: the
                    measured view coordinate w* of every camera pixel drawn where that pixel
                    sees the panel, and the fitted profile's w at every subpixel; below, the
                    wrapped difference measured - fitted (views) over the whole panel
    residual.png    measured - fitted, smoothed, per camera pixel (photo coordinates) and per
                    panel block (panel coordinates), in views
    summary.json    :func:`fit_summary`: the document ``lenticalib fit --json`` prints

Every figure has a title, axes labelled with units and a colour bar with units; sizes are
:data:`FIGURE_SIZES` (pixels), fonts at least 10 pt.
"""

from __future__ import annotations

import io
import json
import math
import os
from pathlib import Path

import numpy as np

from ..atomic import write_bytes_atomic, write_text_atomic
from . import model

FIGURE_SIZES = {"panel.png": (1800, 1200), "view-map.png": (1800, 1560), "residual.png": (1800, 700)}
REPORT_FILES = tuple(FIGURE_SIZES) + ("summary.json",)
CROP = (120, 70)  # panel pixels (width, height) of the zoomed view-map crop
_DPI = 100
_STYLE = {"font.size": 12, "axes.titlesize": 13, "axes.labelsize": 12, "xtick.labelsize": 11,
          "ytick.labelsize": 11, "legend.fontsize": 11}


def _jsonable(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def fit_summary(result, capture_dir, report: str | os.PathLike | None = None,
                output: str | os.PathLike | None = None) -> dict:
    """The summary of a fit: ``summary.json`` of the report and what ``lenticalib fit --json`` prints.

    Keys: ``capture_set``, ``trusted``, ``problems``, ``warnings`` (checks that could not measure),
    ``seconds``, ``output`` (the profile path,
    or None when none was written), ``report`` (folder), ``profile`` (the profile as written,
    its provenance without the quality block), ``quality`` (every quality number, once), and
    ``view_direction`` (the evidence of ``--moved-right``) when the fit had a second capture set.
    """
    profile = result.profile.to_dict()
    if "provenance" in profile:
        profile["provenance"] = {k: v for k, v in profile["provenance"].items() if k != "quality"}
    summary = {"capture_set": str(capture_dir), "trusted": bool(result.trusted),
               "problems": list(result.problems), "warnings": list(result.warnings),
               "seconds": round(float(result.seconds), 2),
               "output": None if output is None else str(output),
               "report": None if report is None else str(report),
               "profile": profile, "quality": result.quality}
    if getattr(result, "direction", None) is not None:
        summary["view_direction"] = result.direction
    return json.loads(json.dumps(summary, default=_jsonable))


def write_report(result, directory: str | os.PathLike, capture_dir: str | os.PathLike,
                 summary: dict | None = None) -> Path:
    """Write the report of ``result`` (a :class:`~lenticalib.calib.fit.FitResult`) into ``directory``.

    ``directory`` is created if missing (its parent must exist).  ``summary`` is written as
    ``summary.json`` (default: :func:`fit_summary` of the result).
    """
    directory = Path(directory)
    directory.mkdir(exist_ok=True)
    write_figures(directory, [("panel.png", _panel_figure), ("view-map.png", _view_map_figure),
                              ("residual.png", _residual_figure)], FIGURE_SIZES, result)
    summary = fit_summary(result, capture_dir, report=directory) if summary is None else summary
    write_text_atomic(directory / "summary.json", json.dumps(summary, indent=2) + "\n")
    return directory


def write_figures(directory: Path, drawings, sizes: dict, subject) -> None:
    """Draw each ``(name, draw)`` of ``drawings`` as ``draw(fig, subject)`` on a figure of ``sizes[name]``
    pixels (the report style: fonts of at least 10 pt) and write it as ``directory/name``, atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with plt.rc_context(_STYLE):
        for name, draw in drawings:
            w, h = sizes[name]
            fig = plt.figure(figsize=(w / _DPI, h / _DPI), dpi=_DPI)
            try:
                draw(fig, subject)
                buf = io.BytesIO()
                fig.savefig(buf, format="png", dpi=_DPI)
            finally:
                plt.close(fig)
            write_bytes_atomic(directory / name, buf.getvalue())


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


def _measured_and_fitted(result):
    """(measured w*, fitted w) per camera pixel, views in [0, N) (NaN off the valid panel)."""
    maps, n = result.maps, result.profile.views
    valid, x, y = maps["valid"], maps["x"], maps["y"]
    name, z = next(iter(maps["fine_z"].items()))
    period = float(name[1:])
    measured = np.full(valid.shape, np.nan)
    cycles = np.angle(z[valid]) / (2 * math.pi)
    measured[valid] = (model.wrap(cycles - x[valid] / period) * n + n / 2) % n
    fitted = np.full(valid.shape, np.nan)
    fitted[valid] = (maps["fit"].psi(x[valid], y[valid]) * n + n / 2) % n
    return measured, fitted, name


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
    ax.clabel(cx, fmt="x=%d", fontsize=10)
    ax.clabel(cy, fmt="y=%d", fontsize=10)
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


def _view_map_figure(fig, result) -> None:
    from matplotlib.patches import Rectangle

    maps, profile = result.maps, result.profile
    n = profile.views
    valid, x, y = maps["valid"], maps["x"], maps["y"]
    measured, fitted, group = _measured_and_fitted(result)
    x0, y0, cw, ch = _crop_box(profile)
    grid = fig.add_gridspec(2, 2, height_ratios=(0.8, 1.25), left=0.05, right=0.95, top=0.91, bottom=0.05,
                            wspace=0.22, hspace=0.22)
    cmap = "hsv"

    # measured: every camera pixel drawn where it sees the panel (its measured x/3, y)
    ax = fig.add_subplot(grid[0, 0])
    px, py = x / 3.0, y
    margin = 4.0
    inside = valid & (px >= x0 - margin) & (px <= x0 + cw + margin) & (py >= y0 - margin) & (py <= y0 + ch + margin)
    rows, cols = np.nonzero(inside)
    im = None
    if rows.size:
        r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
        bx, by, bm = px[r0:r1, c0:c1], py[r0:r1, c0:c1], measured[r0:r1, c0:c1]
        if np.all(np.isfinite(bx)) and np.all(np.isfinite(by)) and min(bx.shape) >= 2:
            im = ax.pcolormesh(bx, by, np.ma.masked_invalid(bm), cmap=cmap, vmin=0, vmax=n, shading="nearest")
        else:
            im = ax.scatter(px[inside], py[inside], c=measured[inside], cmap=cmap, vmin=0, vmax=n, s=30, marker="s")
    ax.set_title(f"measured w*, each camera pixel where it sees the panel ({rows.size} pixels)")
    # fitted: the profile's w at every subpixel of the crop (3 columns per panel pixel)
    ax2 = fig.add_subplot(grid[0, 1])
    xs = np.arange(3 * x0, 3 * (x0 + cw)) + 0.5
    ys = np.arange(y0, y0 + ch) + 0.5
    wfit = (maps["fit"].psi(xs[None, :], ys[:, None]) * n + n / 2) % n
    im2 = ax2.imshow(wfit, cmap=cmap, vmin=0, vmax=n, interpolation="nearest", extent=(x0, x0 + cw, y0 + ch, y0),
                     aspect="auto")
    if rows.size:  # the measured camera pixels as dots: on a good fit they vanish into the stripes
        ax2.scatter(px[inside], py[inside], c=measured[inside], cmap=cmap, vmin=0, vmax=n, s=22,
                    edgecolors="black", linewidths=0.5)
    ax2.set_title(f"fitted w at every subpixel ({3 * cw}x{ch}); dots: measured w*")
    for a, mappable in ((ax, im if im is not None else im2), (ax2, im2)):
        a.set_xlim(x0, x0 + cw)
        a.set_ylim(y0 + ch, y0)
        a.set_aspect("equal")
        a.set_xlabel("panel x (pixels)")
        a.set_ylabel("panel y (pixels)")
        _colorbar(fig, a, mappable, f"view (cyclic, 0..{n})")

    # wrapped difference over the whole panel, circular mean in bins of b x b panel pixels
    diff = model.wrap((measured[valid] - fitted[valid]) / n)
    b = max(1, int(round(profile.width / 480)))
    nx, ny = -(-profile.width // b), -(-profile.height // b)
    bx = np.clip((px[valid] / b).astype(int), 0, nx - 1)
    by = np.clip((py[valid] / b).astype(int), 0, ny - 1)
    phasor = np.bincount(by * nx + bx, weights=np.cos(2 * math.pi * diff), minlength=nx * ny) + 1j * np.bincount(
        by * nx + bx, weights=np.sin(2 * math.pi * diff), minlength=nx * ny)
    count = np.bincount(by * nx + bx, minlength=nx * ny)
    binned = np.where(count > 0, np.angle(phasor) / (2 * math.pi) * n, np.nan).reshape(ny, nx)
    finite = binned[np.isfinite(binned)]
    lim = min(n / 2, max(0.25, float(np.percentile(np.abs(finite), 99)) if finite.size else 0.25))
    ax3 = fig.add_subplot(grid[1, 0:2])
    im3 = ax3.imshow(binned, cmap="coolwarm", vmin=-lim, vmax=lim, extent=(0, profile.width, profile.height, 0),
                     interpolation="nearest")
    ax3.add_patch(Rectangle((x0, y0), cw, ch, fill=False, edgecolor="black", linewidth=1.5))
    ax3.annotate("crop above", (x0 + cw, y0), xytext=(8, -4), textcoords="offset points", fontsize=11)
    ax3.set_title(f"measured - fitted over the whole panel (views, wrapped to [-{n / 2:g}, {n / 2:g}); circular "
                  f"mean in {b}x{b} pixel bins; RMS {math.sqrt(float(np.mean(diff ** 2))) * n:.3f} views)")
    ax3.set_xlabel("panel x (pixels)")
    ax3.set_ylabel("panel y (pixels)")
    _colorbar(fig, ax3, im3, f"measured - fitted (views; colours end at ±{lim:.2f})",
              "both" if lim < n / 2 else "neither")
    fig.suptitle(f"View map: measured and fitted view coordinate on a {cw}x{ch} pixel crop at the panel centre "
                 f"(x {x0}..{x0 + cw}, y {y0}..{y0 + ch}),\n{n} views, measured from fine group {group}; "
                 "below: their difference over the whole panel", fontsize=14)


def _residual_figure(fig, result) -> None:
    import cv2

    maps, profile = result.maps, result.profile
    n = profile.views
    valid = maps["valid"]
    measured, fitted, _ = _measured_and_fitted(result)
    resid = np.zeros(valid.shape)
    resid[valid] = model.wrap((measured[valid] - fitted[valid]) / n) * n
    wgt = valid.astype(np.float32)
    sigma = max(3.0, valid.shape[1] / 120)
    smooth = cv2.GaussianBlur(resid.astype(np.float32) * wgt, (0, 0), sigma) / np.maximum(
        cv2.GaussianBlur(wgt, (0, 0), sigma), 1e-6)
    smooth = np.where(valid, smooth, np.nan)
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
    im = ax.imshow(block, cmap="coolwarm", vmin=-lim, vmax=lim, extent=(0, profile.width, profile.height, 0))
    ax.set_title(f"per panel block ({block.shape[1]}x{block.shape[0]}), RMS "
                 f"{result.quality['block_residual_rms_views']:.3f} views")
    ax.set_xlabel("panel x (pixels)")
    ax.set_ylabel("panel y (pixels)")
    _colorbar(fig, ax, im, "mean measured - fitted (views)", "both")
    fig.suptitle("Residual of the fit: measured minus fitted view coordinate, wrapped, in views", fontsize=14)
