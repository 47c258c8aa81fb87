"""The crosstalk report: figures a display engineer reads, each with a title, axes with units, legends.

Written into one folder (``lenticalib crosstalk measure --report DIR``, staged as a whole):

    view-cone.png     the angular profile of a view: share of the light at the eye from one view vs.
                      the eye's offset from that view's zone centre (views), linear and logarithmic,
                      with the 1-sigma band and the matrix entries (integer offsets) marked
    matrix.png        the mixing matrix M (log colour scale, shares)
    uniformity.png    own-view share per region of the panel (as photographed), with 1-sigma
    photos.png        the white photo (working pixels) with the panel, the centre region and the
                      regions outlined, and the fitted sweep offset delta (views) across the panel
    compensation.png  per zone: RMS error of the view seen vs. the intended one, with and without
                      pre-compensation by the measured matrix (synthetic test views; the prediction
                      if the matrix is right)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

FIGURE_SIZES = {"view-cone.png": (1600, 1200), "matrix.png": (1200, 1050), "uniformity.png": (1400, 900),
                "photos.png": (1800, 800), "compensation.png": (1400, 800)}
REPORT_FILES = tuple(FIGURE_SIZES)


def write_crosstalk_report(measurement, directory: str | Path, compensation: dict | None = None) -> Path:
    """Write the figures of ``measurement`` (:class:`.measure.Measurement`) into ``directory``."""
    from ..report import write_figures

    directory = Path(directory)
    directory.mkdir(exist_ok=True)
    drawings = [("view-cone.png", _cone), ("matrix.png", _matrix), ("uniformity.png", _uniformity),
                ("photos.png", _photos)]
    if compensation is not None:
        drawings.append(("compensation.png", lambda fig, m: _compensation(fig, compensation)))
    write_figures(directory, drawings, FIGURE_SIZES, measurement)
    return directory


def _cone(fig, m) -> None:
    n = m.views
    grid, cone, sigma = m.cone_grid, m.cone, m.cone_sigma
    offsets = np.arange(n) - n * (np.arange(n) >= n / 2)
    order = np.argsort(offsets)
    for k, log in enumerate((False, True)):
        ax = fig.add_subplot(2, 1, k + 1)
        ax.fill_between(grid, np.maximum(cone - sigma, 1e-5), cone + sigma, color="tab:blue", alpha=0.25,
                        label="1-sigma")
        ax.plot(grid, np.maximum(cone, 1e-5), color="tab:blue", lw=1.5, label="measured view cone")
        ax.errorbar(offsets[order], np.maximum(m.row[order], 1e-5), yerr=m.row_sigma[order], fmt="o", ms=5,
                    color="tab:red", capsize=3, label="matrix entries M[i][i+m]")
        ax.set_xlim(-min(n / 2, 8), min(n / 2, 8))
        ax.set_xlabel("eye offset from the view's zone centre (views)")
        ax.set_ylabel("share of the light at the eye")
        ax.grid(alpha=0.3)
        if log:
            ax.set_yscale("log")
            ax.set_ylim(1e-4, 1.0)
            ax.set_title("the same, logarithmic: the non-adjacent floor")
        else:
            ax.set_title(f"View cone of one view ({n} views; centre region of the panel)")
            ax.legend(loc="upper right")
    fig.tight_layout()


def _matrix(fig, m) -> None:
    from matplotlib.colors import LogNorm

    ax = fig.add_subplot(1, 1, 1)
    image = ax.imshow(np.maximum(m.matrix, 1e-5), norm=LogNorm(vmin=1e-4, vmax=1.0), cmap="magma",
                      interpolation="nearest")
    ax.set_title("Mixing matrix M: share of the light at view i's zone centre from view j")
    ax.set_xlabel("view j shown (index)")
    ax.set_ylabel("eye at the centre of view i's zone (index)")
    bar = fig.colorbar(image, ax=ax, fraction=0.046, pad=0.04)
    bar.set_label("share of the light (log scale)")
    fig.tight_layout()


def _uniformity(fig, m) -> None:
    ax = fig.add_subplot(1, 1, 1)
    values = m.regions
    finite = values[np.isfinite(values)]
    vmin = float(finite.min()) if finite.size else 0.0
    vmax = float(finite.max()) if finite.size else 1.0
    image = ax.imshow(values, cmap="viridis", vmin=vmin - 0.01, vmax=vmax + 0.01, interpolation="nearest")
    for (j, i), v in np.ndenumerate(values):
        if np.isfinite(v):
            ax.text(i, j, f"{v:.3f}\n+-{m.regions_sigma[j, i]:.3f}", ha="center", va="center", color="white",
                    fontsize=11, bbox={"facecolor": "black", "alpha": 0.35, "pad": 1, "edgecolor": "none"})
    ax.set_xticks(range(values.shape[1]))
    ax.set_yticks(range(values.shape[0]))
    ax.set_title("Own-view share per region of the panel (as photographed)")
    ax.set_xlabel("region column (left to right)")
    ax.set_ylabel("region row (top to bottom)")
    bar = fig.colorbar(image, ax=ax, fraction=0.046, pad=0.04)
    bar.set_label("own-view share (fraction of the light)")
    fig.tight_layout()


def _photos(fig, m) -> None:
    import matplotlib.patches as patches

    white = m.images["white"]
    r0, r1, c0, c1 = m.images["region_box"]
    cr0, cr1, cc0, cc1 = m.images["centre_box"]
    ax = fig.add_subplot(1, 2, 1)
    ax.imshow(white, cmap="gray", vmin=0, vmax=float(np.percentile(white, 99.5)))
    ax.add_patch(patches.Rectangle((c0, r0), c1 - c0, r1 - r0, fill=False, color="tab:orange", lw=1.5,
                                   label="panel (lit area)"))
    ax.add_patch(patches.Rectangle((cc0, cr0), cc1 - cc0, cr1 - cr0, fill=False, color="tab:red", lw=2,
                                   label="centre region (matrix)"))
    ax.legend(loc="lower right")
    ax.set_title("White photo, glare removed (linear light)")
    ax.set_xlabel("x (working pixels)")
    ax.set_ylabel("y (working pixels)")
    ax = fig.add_subplot(1, 2, 2)
    image = ax.imshow(m.images["delta"], cmap="twilight", interpolation="nearest")
    ax.set_title("Fitted band offset delta across the photo")
    ax.set_xlabel("x (working pixels)")
    ax.set_ylabel("y (working pixels)")
    bar = fig.colorbar(image, ax=ax, fraction=0.046, pad=0.04)
    bar.set_label("offset of band-00 from the camera (views)")
    fig.tight_layout()


def _compensation(fig, study: dict) -> None:
    ax = fig.add_subplot(1, 1, 1)
    zones = np.arange(len(study["rms_without"]))
    ax.bar(zones - 0.2, study["rms_without"], width=0.4, label="without compensation", color="tab:gray")
    ax.bar(zones + 0.2, study["rms_with"], width=0.4, label="with pre-compensation", color="tab:green")
    ax.set_title(f"Seen vs. intended view at each zone centre, test views (black lift {study['black_lift']:g}): "
                 f"residual crosstalk {study['residual_crosstalk_without']:.2f} -> {study['residual_crosstalk_with']:.2f}",
                 fontsize=11)
    ax.set_xlabel("zone (view index)")
    ax.set_ylabel("RMS error (linear light, 0..1)")
    ax.legend(loc="center right")
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
