"""The fit report: figures a person reads to see why a fit is good or bad, plus a summary.

Written into one folder (each file atomically):

    panel.png       the panel as found in the photos: mask outline, measured iso-X/iso-Y lines
    view-map.png    the measured view coordinate w* per camera pixel (cyclic colours) and the
                    fitted model's, side by side
    residual.png    measured minus model, per camera pixel (smoothed) and per panel block
    summary.json    constants, uncertainties, quality numbers, problems, camera estimate
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


def _figure_bytes(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    return buf.getvalue()


def write_report(result, directory: str | os.PathLike, capture_dir: str | os.PathLike) -> Path:
    """Write the report of ``result`` (a :class:`~lenticalib.calib.fit.FitResult`) into ``directory``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    maps, profile = result.maps, result.profile
    n = profile.views
    fit: model.PlaneFit = maps["fit"]
    mask, valid, x, y = maps["mask"], maps["valid"], maps["x"], maps["y"]

    # 1. the panel as found
    fig, ax = plt.subplots(figsize=(10, 6.5))
    dc = maps["dc"]
    ax.imshow(np.clip(dc / max(np.percentile(dc, 99.5), 1e-6), 0, 1) ** (1 / 2.2), cmap="gray")
    ax.contour(mask.astype(float), levels=[0.5], colors=["lime"], linewidths=1.0)
    xv = np.where(valid, x, np.nan)
    yv = np.where(valid, y, np.nan)
    ax.contour(xv, levels=np.linspace(0, 3 * profile.width, 9)[1:-1], colors=["orange"], linewidths=0.6)
    ax.contour(yv, levels=np.linspace(0, profile.height, 9)[1:-1], colors=["deepskyblue"], linewidths=0.6)
    ax.set_title(f"panel found in the photos ({100 * mask.mean():.0f}% of the frame); "
                 "orange/blue: measured panel columns/rows at eighths")
    ax.axis("off")
    write_bytes_atomic(directory / "panel.png", _figure_bytes(fig))
    plt.close(fig)

    # 2. view maps: measured (per pixel, from the fine group used first) and model
    fine = next(iter(maps["fine_z"].items()))
    period = float(fine[0][1:])
    measured = np.full(mask.shape, np.nan)
    cycles = np.angle(fine[1][valid]) / (2 * math.pi)
    measured[valid] = (model.wrap(cycles - x[valid] / period) * n + n / 2) % n
    modelled = np.full(mask.shape, np.nan)
    modelled[valid] = (fit.psi(x[valid], y[valid]) * n + n / 2) % n
    fig, axes = plt.subplots(1, 2, figsize=(14, 5))
    for ax, data, title in ((axes[0], measured, f"measured w* (fine group {fine[0]})"),
                            (axes[1], modelled, "fitted profile w")):
        im = ax.imshow(data, cmap="hsv", vmin=0, vmax=n, interpolation="nearest")
        ax.set_title(title)
        ax.axis("off")
    fig.colorbar(im, ax=axes, label="view", shrink=0.8)
    write_bytes_atomic(directory / "view-map.png", _figure_bytes(fig))
    plt.close(fig)

    # 3. residuals
    import cv2

    resid = np.zeros(mask.shape)
    resid[valid] = model.wrap(measured[valid] / n - modelled[valid] / n) * n
    wgt = valid.astype(np.float32)
    sigma = max(3.0, mask.shape[1] / 120)
    smooth = cv2.GaussianBlur(resid.astype(np.float32) * wgt, (0, 0), sigma) / np.maximum(
        cv2.GaussianBlur(wgt, (0, 0), sigma), 1e-6)
    smooth = np.where(valid, smooth, np.nan)
    fig, axes = plt.subplots(1, 2, figsize=(14, 5))
    lim = max(0.15, float(np.nanpercentile(np.abs(smooth), 99)))
    im = axes[0].imshow(smooth, cmap="coolwarm", vmin=-lim, vmax=lim)
    axes[0].set_title("residual per camera pixel, smoothed (views)")
    axes[0].axis("off")
    fig.colorbar(im, ax=axes[0], shrink=0.8)
    block = maps["block_residual_map"]
    im = axes[1].imshow(block, cmap="coolwarm", vmin=-lim, vmax=lim,
                        extent=(0, profile.width, profile.height, 0))
    axes[1].set_title(f"residual per panel block (views), RMS {result.quality['block_residual_rms_views']:.3f}")
    axes[1].set_xlabel("panel x (pixels)")
    axes[1].set_ylabel("panel y (pixels)")
    fig.colorbar(im, ax=axes[1], shrink=0.8)
    write_bytes_atomic(directory / "residual.png", _figure_bytes(fig))
    plt.close(fig)

    summary = {"capture_set": str(capture_dir), "trusted": result.trusted, "problems": result.problems,
               "profile": profile.to_dict(), "quality": result.quality, "seconds": result.seconds}
    write_text_atomic(directory / "summary.json", json.dumps(summary, indent=2, default=float) + "\n")
    return directory
