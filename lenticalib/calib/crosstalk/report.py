"""The crosstalk report: figures a display engineer reads, each with a title, axes with units, legends.

Written into one folder (``lenticalib crosstalk measure --report DIR``, staged as a whole):

    view-cone.png     the angular profile of a view: share of the light at the eye from one view vs.
                      the eye's offset from that view's zone centre (views), linear and logarithmic,
                      with the 1-sigma band and the matrix entries (integer offsets) marked; the
                      derived figures of ``crosstalk.json`` with their definitions
    matrix.png        the mixing matrix M (log colour scale, shares)
    uniformity.png    own-view share per region of the panel, on panel coordinates, with 1-sigma
    photos.png        the white photo (working pixels) with the panel, the centre region and the
                      regions outlined, and where the band sweep lies across the photo, with a
                      caption saying what to look for
    compensation.png  what pre-compensation by the measured matrix would do (synthetic test views; the
                      prediction if the matrix is right): the light each other view leaks into a
                      view, without and with, and one test pixel across the zones
    tone-curve.png    camera JPEGs only: the camera's tone curve measured from the photos (light of
                      each 8-bit code, and its ratio to plain sRGB decoding) with its 1-sigma, the
                      codes the black and white photos hold, and the model blended in, if any

The numbers a figure states are those of ``crosstalk.json`` (the document), recorded in the PNG
(:func:`lenticalib.calib.routing.report.read_figure_record`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.colour import srgb_decode_lut
from ...core.figures import write_figures
from .ratios import TOE_END
from .result import HEADLINE, describe_figure

FIGURE_SIZES = {"view-cone.png": (1600, 1300), "matrix.png": (1200, 1050), "uniformity.png": (1400, 900),
                "photos.png": (1800, 900), "compensation.png": (1800, 800), "tone-curve.png": (1700, 850)}
REPORT_FILES = tuple(FIGURE_SIZES)


def write_crosstalk_report(measurement, directory: str | Path, document: dict,
                           compensation: dict | None = None) -> Path:
    """Write the figures of ``measurement`` (:class:`.measure.Measurement`) into ``directory``; the
    numbers they state come from ``document`` (:func:`.result.crosstalk_document`) and the
    ``compensation`` study (:func:`lenticalib.render.compose.compensation.compensation_study`)."""
    directory = Path(directory)
    directory.mkdir(exist_ok=True)
    drawings = [("view-cone.png", lambda fig, m: _cone(fig, m, document)), ("matrix.png", _matrix),
                ("uniformity.png", lambda fig, m: _uniformity(fig, m, document)), ("photos.png", _photos)]
    if compensation is not None:
        drawings.append(("compensation.png", lambda fig, m: _compensation(fig, compensation)))
    if measurement.photometry.get("tone_curve"):
        drawings.append(("tone-curve.png", lambda fig, m: _tone_curve(fig, m.photometry["tone_curve"])))
    write_figures(directory, drawings, FIGURE_SIZES, measurement)
    return directory


def _cone(fig, m, document: dict) -> dict:
    n = m.views
    grid, cone, sigma = m.cone_grid, m.cone, m.cone_sigma
    offsets = np.arange(n) - n * (np.arange(n) >= n / 2)
    order = np.argsort(offsets)
    figures = document["figures"]
    reach = min(n / 2, 8)
    positive = m.row[m.row > 0]
    floor = max(1e-6, min(1e-4, 0.5 * float(positive.min()))) if positive.size else 1e-4
    gs = fig.add_gridspec(3, 1, height_ratios=(1.0, 1.0, 0.34), left=0.08, right=0.97, top=0.93, bottom=0.02,
                          hspace=0.32)
    for k, log in enumerate((False, True)):
        ax = fig.add_subplot(gs[k])
        low = floor if log else -np.inf
        ax.fill_between(grid, np.maximum(cone - sigma, low), np.maximum(cone + sigma, low), color="tab:blue",
                        alpha=0.25, label="1-sigma")
        ax.plot(grid, np.maximum(cone, low), color="tab:blue", lw=1.5, label="measured view cone")
        shown = m.row[order] > floor if log else np.ones(n, bool)
        ax.errorbar(offsets[order][shown], m.row[order][shown], yerr=m.row_sigma[order][shown], fmt="o", ms=5,
                    color="tab:red", capsize=3, label="matrix entries M[i][i+m]")
        if log and not shown.all():
            ax.plot(offsets[order][~shown], np.full(int((~shown).sum()), floor * 1.15), "v", ms=8, color="tab:red",
                    label=f"entry at or below {floor:.0e} (0 or negative: within its sigma)")
            ax.legend(loc="upper right")
        ax.set_xlim(-reach - 0.4, reach + 0.4)
        ax.set_xlabel("eye offset from the view's zone centre (views"
                      + (f"; up to ±{reach:g} shown, all {n} in crosstalk.json)" if reach < n / 2 else ")"))
        ax.set_ylabel("share of the light at the eye (0..1)")
        ax.grid(alpha=0.3)
        if log:
            ax.set_yscale("log")
            ax.set_ylim(floor, 1.0)
            ax.set_title("the same, logarithmic: the non-adjacent floor")
        else:
            ax.set_title(f"View cone of one view ({n} views; centre region of the panel)")
            ax.legend(loc="upper right")
    # the derived figures of crosstalk.json, each with what it is
    ax = fig.add_subplot(gs[2])
    ax.axis("off")
    lines = [describe_figure(k, figures[k]["value"], figures[k]["sigma"], plus_minus="±") for k in HEADLINE
             if k in figures]
    ax.text(0.0, 1.0, "Derived figures (crosstalk.json; every crosstalk is leakage over signal, black-corrected):\n"
            + "\n".join(lines), va="top", ha="left", fontsize=12, transform=ax.transAxes)
    return {k: figures[k]["value"] for k in HEADLINE if k in figures}


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


def _uniformity(fig, m, document: dict) -> dict:
    uniformity = document["uniformity"]
    values = np.array(uniformity["own_view_share"], dtype=float)  # None (not measured) -> NaN
    sigma = np.array(uniformity["sigma"], dtype=float)
    xe, ye = uniformity["columns_panel_x"], uniformity["rows_panel_y"]
    ax = fig.add_subplot(1, 1, 1)
    finite = values[np.isfinite(values)]
    vmin = float(finite.min()) if finite.size else 0.0
    vmax = float(finite.max()) if finite.size else 1.0
    image = ax.pcolormesh(xe, ye, values, cmap="viridis", vmin=vmin - 0.01, vmax=vmax + 0.01)
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[-1], ye[0])
    ax.set_aspect("equal")
    for (j, i), v in np.ndenumerate(values):
        if np.isfinite(v):
            ax.text((xe[i] + xe[i + 1]) / 2, (ye[j] + ye[j + 1]) / 2, f"{v:.3f}\n±{sigma[j, i]:.3f}", ha="center",
                    va="center", color="white", fontsize=11,
                    bbox={"facecolor": "black", "alpha": 0.35, "pad": 1, "edgecolor": "none"})
    ax.set_xticks(xe)
    ax.set_yticks(ye)
    ax.set_xticklabels([f"{v:g}" for v in xe])
    ax.set_yticklabels([f"{v:g}" for v in ye])
    own = document["figures"]["own_view_share"]["value"]
    ax.set_title(f"Own-view share per region of the panel ({values.shape[1]}x{values.shape[0]} regions, ± 1-sigma);"
                 f"\nthe matrix is measured in the centre region: {own:.3f}")
    ax.set_xlabel("panel x (pixels; regions divide the panel as photographed evenly)")
    ax.set_ylabel("panel y (pixels)")
    bar = fig.colorbar(image, ax=ax, fraction=0.046, pad=0.04)
    bar.set_label("own-view share (share of the light, 0..1)")
    fig.tight_layout()
    return {"own_view_share": values.tolist(), "sigma": sigma.tolist(), "columns_panel_x": list(xe),
            "rows_panel_y": list(ye), "centre_own_view_share": own}


def _photos(fig, m) -> dict:
    import matplotlib.patches as patches

    white = m.images["white"]
    n = m.views
    r0, r1, c0, c1 = m.images["region_box"]
    cr0, cr1, cc0, cc1 = m.images["centre_box"]
    gs = fig.add_gridspec(2, 2, height_ratios=(1.0, 0.2), left=0.05, right=0.95, top=0.92, bottom=0.03,
                          wspace=0.25, hspace=0.25)
    ax = fig.add_subplot(gs[0, 0])
    ax.imshow(white, cmap="gray", vmin=0, vmax=float(np.percentile(white, 99.5)))
    ax.add_patch(patches.Rectangle((c0, r0), c1 - c0, r1 - r0, fill=False, color="tab:orange", lw=1.5,
                                   label="panel (lit area)"))
    ax.add_patch(patches.Rectangle((cc0, cr0), cc1 - cc0, cr1 - cr0, fill=False, color="tab:red", lw=2,
                                   label="centre region (matrix)"))
    ax.legend(loc="lower right")
    ax.set_title("White photo, glare removed (linear light)")
    ax.set_xlabel("x (working pixels)")
    ax.set_ylabel("y (working pixels)")
    ax = fig.add_subplot(gs[0, 1])
    image = ax.imshow(m.images["delta"] % n, cmap="twilight", vmin=0, vmax=n, interpolation="nearest")
    ax.set_title("How far the first band photo's band is from the camera's view\n(fitted from all band photos)")
    ax.set_xlabel("x (working pixels)")
    ax.set_ylabel("y (working pixels)")
    bar = fig.colorbar(image, ax=ax, fraction=0.046, pad=0.04)
    bar.set_label(f"band-00's view minus the camera's view (views, cyclic 0..{n})")
    _caption(fig, gs[1, :], "Right: each band photo lights a one-view band that moves steadily across the panel from "
             "left to right; the measurement finds where it is at every camera pixel.\n"
             "Good: the colour changes smoothly and evenly from left to right and hardly at all from top to "
             "bottom (upright stripes, leaning at most as the panel does in the photo).\n"
             "Bad: stripes that tilt against the panel's edges, bend, or bunch up: the profile (slant, period) "
             "is not this panel's, or the camera moved between photos; the matrix then comes out too broad.")
    return {}


def _caption(fig, cell, text: str) -> None:
    """A caption (what a figure shows, what good and bad look like) in grid cell ``cell``, no axes."""
    caption = fig.add_subplot(cell)
    caption.axis("off")
    caption.text(0.0, 1.0, text, va="top", ha="left", fontsize=12, transform=caption.transAxes)


def _compensation(fig, study: dict) -> dict:
    n = len(study["rms_without"])
    offsets = np.asarray(study["leak_offsets"])
    without, with_ = 100 * np.asarray(study["leak_without"]), 100 * np.asarray(study["leak_with"])
    other = offsets != 0
    sys_without, sys_with = study["residual_crosstalk_without"], study["residual_crosstalk_with"]
    rms_without, rms_with = study["mean_rms_without"], study["mean_rms_with"]
    ax = fig.add_subplot(1, 2, 1)
    ax.bar(offsets[other] - 0.2, without[other], width=0.4, color="tab:gray", label="without compensation")
    ax.bar(offsets[other] + 0.2, with_[other], width=0.4, color="tab:green", label="with pre-compensation")
    ax.axhline(0, color="black", lw=0.8)
    # offsets run -N/2..N/2-1: the axis ends at the last bar on each side (no empty tick), at most 8 away
    low, high = max(int(offsets.min()), -8), min(int(offsets.max()), 8)
    ax.set_xlim(low - 0.5, high + 0.5)
    ax.set_title(f"Light each other view leaks into a view (signed; own view = 100 %):\nsystem crosstalk, the sum "
                 f"of the magnitudes over all {n - 1} other views, {100 * sys_without:.1f}% → {100 * sys_with:.1f}%",
                 fontsize=12)
    cut = low > offsets.min() or high < offsets.max()
    ax.set_xlabel("offset of the leaking view (views" + (f"; {low:+d} to {high:+d} shown)" if cut else ")"))
    ax.set_ylabel("light over the view's own light (%)")
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3, axis="y")
    ax = fig.add_subplot(1, 2, 2)
    zones = np.arange(n)
    ax.plot(zones, study["example_intended"], color="black", lw=2, label="intended")
    ax.plot(zones, study["example_seen_without"], color="tab:gray", lw=2, marker="o", ms=4,
            label="seen without compensation")
    ax.plot(zones, study["example_seen_with"], color="tab:green", lw=2, marker="o", ms=4,
            label="seen with pre-compensation")
    ax.plot(zones, study["example_target"], color="tab:purple", lw=1.5, ls="--", zorder=5,
            label=f"intended, black lifted by {study['black_lift']:g} (what compensation aims at)")
    ax.set_title(f"One test pixel as the eye at each zone centre sees it; over all test pixels\nRMS seen - intended "
                 f"{rms_without:.4f} → {rms_with:.4f} (linear light, 0..1)", fontsize=12)
    ax.set_xlabel("zone (view index)")
    ax.set_ylabel("light (linear, 0..1)")
    values = np.concatenate([np.asarray(study[k], float) for k in ("example_intended", "example_target",
                                                                   "example_seen_without", "example_seen_with")])
    low, high = float(values.min()), float(values.max())
    ax.set_ylim(low - 0.05 * (high - low), high + 0.55 * (high - low))  # head room for the legend
    ax.legend(loc="upper center", ncol=2, fontsize=10)
    ax.grid(alpha=0.3)
    fig.suptitle("Pre-compensation with the measured matrix, as predicted if the matrix is right (synthetic test "
                 f"views, black lift {study['black_lift']:g})", fontsize=14)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return {"residual_crosstalk_without": sys_without, "residual_crosstalk_with": sys_with,
            "mean_rms_without": rms_without, "mean_rms_with": rms_with}


def _tone_light(curve: dict) -> np.ndarray:
    """float64 (256,): the linear light of each 8-bit code under a ``crosstalk.json`` tone curve entry."""
    if "light_of_code" in curve:
        return np.asarray(curve["light_of_code"], dtype=np.float64)
    return srgb_decode_lut().astype(np.float64) ** float(curve["power"])


def _tone_curve(fig, curve: dict) -> dict:
    """The camera's tone curve (``photometry.tone_curve`` of ``crosstalk.json``), normalised to 1 at
    the white photo's median code: light against code (log), and its ratio to plain sRGB."""
    black, white = (int(v) for v in curve["code_range"])
    sigma, toe = float(curve["power_sigma"]), float(curve.get("toe_sigma", 0.0))
    codes = np.arange(256)
    srgb = srgb_decode_lut().astype(np.float64)
    srgb_n = np.maximum(srgb / srgb[white], 1e-12)

    def normalised(light):
        return np.maximum(light, 1e-12) / max(float(light[white]), 1e-12)

    main = normalised(_tone_light(curve))
    # the band the measurement propagates: the power's and the toe's (whole at black, none from
    # TOE_END of white's light up: ratios.relinearised), in quadrature on the log light
    spread = np.hypot(sigma * np.log(main), toe * np.clip(1.0 - main / TOE_END, 0.0, 1.0))
    band_label = f"1-sigma: a power 1 ± {sigma:.3f} on the light" + (f", the toe ± {100 * toe:.0f} %" if toe else "")
    label = (f"measured: sRGB decoding ** {curve['power']:.3f}" if "power" in curve
             else "measured: sRGB decoding x a bent factor")
    other = curve.get("blended_with")
    gs = fig.add_gridspec(2, 2, height_ratios=(1.0, 0.2), left=0.07, right=0.97, top=0.88, bottom=0.03,
                          wspace=0.22, hspace=0.3)
    shown = codes >= 1
    for k, ratio in enumerate((False, True)):
        ax = fig.add_subplot(gs[0, k])
        ref = srgb_n if ratio else 1.0
        lo, hi = main * np.exp(-spread) / ref, main * np.exp(spread) / ref
        ax.fill_between(codes[shown], lo[shown], hi[shown], color="tab:blue", alpha=0.25, label=band_label)
        ax.plot(codes[shown], (main / ref)[shown], color="tab:blue", lw=2, label=label)
        if other:
            alt = normalised(_tone_light(other))
            ax.plot(codes[shown], (alt / ref)[shown], color="tab:orange", lw=1.5, ls="--",
                    label=f"blended in at weight {other['weight']:.2f}: "
                          + (f"sRGB ** {other['power']:.3f}" if "power" in other else "the bent curve"))
        ax.plot(codes[shown], (srgb_n / ref)[shown], color="0.4", lw=1.2, ls=":", label="plain sRGB decoding")
        for span in ((0, black), (white, 255)):
            ax.axvspan(*span, color="0.85", alpha=0.5, lw=0,
                       label="codes the measurement does not read" if span[0] == 0 else None)
        for code, what in ((black, "black photo"), (white, "white photo")):
            ax.axvline(code, color="k", lw=0.8, ls="-.")
            ax.text(code + 2, 0.97, f"{what}\n(median code {code})", fontsize=10, va="top",
                    transform=ax.get_xaxis_transform())
        ax.set_xlim(0, 255)
        ax.set_xlabel("8-bit code in the JPEG (all three channels)")
        if ratio:
            inside = slice(max(black, 1), white + 1)
            values = np.concatenate([(main / srgb_n)[inside], lo[inside], hi[inside]])
            ax.set_ylim(max(0.0, float(values.min()) - 0.05), float(values.max()) + 0.05)
            ax.axhline(1.0, color="0.4", lw=0.8)
            ax.set_ylabel("measured light / sRGB's (both 1 at the white photo's code)")
            ax.set_title("How far the camera is from sRGB (what plain decoding would get wrong)")
        else:
            ax.set_yscale("log")
            ax.set_ylim(1e-4, 2.0)
            ax.set_ylabel("linear light (1 = the white photo's median code)")
            ax.set_title("Light of each code")
            ax.legend(loc="lower right")
    photos = "black, white, half and level photos" if "level" in curve.get("relations", "") else "black, white and half photos"
    fig.suptitle(f"Camera tone curve measured from the {photos}", fontsize=14)
    _caption(fig, gs[1, :], "The measurement reads the codes between the black and the white photo's (unshaded).  An "
             "ordinary camera stays within a few per cent of sRGB there,\na phone's S-curve bends it by tens of "
             "per cent.  The 1-sigma (the power's, and the toe's: the light a few codes above black) enters every "
             "uncertainty of crosstalk.json.\nA wide band, or a bent curve blended in, means the JPEGs limit the "
             "accuracy: shoot RAW and convert it to 16-bit linear (--photos linear) where the camera can\n"
             "(docs/crosstalk.md, \"Phone-like cameras\" and \"The toe\").")
    return {"model": "power" if "power" in curve else "curve", "power_sigma": sigma, "toe_sigma": toe,
            "code_range": [black, white],
            "blended_weight": float(other["weight"]) if other else 0.0}
