"""The camera calibration report: three figures a person reads, and ``summary.json``.

    residuals.png     left: histogram of the residual lengths (px) of the corners kept and of the
                      outliers; right: every residual as an arrow at its corner over the image
                      frame, lengthened by a stated factor, coloured by length (px)
    coverage.png      every observed corner over the image frame (colour: the photo it is in),
                      outliers marked, cells with no corner shaded and the image corners the
                      advice names outlined: where the data constrain the lens
    uncertainty.png   the worst-direction projection uncertainty (px, 1 sigma) over the image, at
                      the working distance and at infinity, with labelled contours and the
                      observed corners
    summary.json      :func:`calibration_summary`: what ``lenticalib camera calibrate --json`` prints

Figures follow :mod:`lenticalib.calib.routing.report`: title, axes with units, colour bars with units,
:data:`FIGURE_SIZES` pixels, fonts of at least 10 pt (drawn by its ``write_figures``).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from ...core.files.documents import FORMATS, write_document
from ...core.profile import make_provenance
from ...core.figures import write_figures
from ..camera.model_file import note_line
from .solve import COVERAGE_GRID, covered_cells
from .quality import IMAGE_CORNERS, weak_corner_keys, weak_corners

FIGURE_SIZES = {"residuals.png": (1800, 1200), "coverage.png": (1800, 1200), "uncertainty.png": (1800, 860)}
REPORT_FILES = tuple(FIGURE_SIZES) + ("summary.json",)
DOCUMENT = FORMATS["lenticalib.camera-calibration"]
_OPENCV_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4")


def _nice(x: float) -> float:
    """The largest of 1, 2, 5 x 10^k not above ``x`` (x > 0)."""
    k = math.floor(math.log10(x))
    for m in (5, 2, 1):
        if m * 10 ** k <= x:
            return float(m * 10 ** k)
    return float(10 ** k)


def intrinsics_named(lensmodel: str, values: np.ndarray) -> dict:
    """``{name: value}`` of the core and, for OpenCV models, each distortion coefficient; a splined
    model's spline values are counted, not listed."""
    out = {k: round(float(v), 6) for k, v in zip(("fx", "fy", "cx", "cy"), values[:4])}
    if "OPENCV" in lensmodel:
        out.update({k: float(v) for k, v in zip(_OPENCV_NAMES, values[4:])})
    elif len(values) > 4:
        out["spline_parameters"] = int(len(values) - 4)
    return out


def field_of_view(model) -> list[float]:
    """Horizontal and vertical field of view (degrees) between the centres of opposite edge pixels."""
    import mrcal

    w, h = model.imagersize()
    lens, data = model.intrinsics()
    cx, cy = data[2], data[3]
    v = mrcal.unproject(np.array([[0.0, cy], [w - 1.0, cy], [cx, 0.0], [cx, h - 1.0]]), lens, data, normalize=True)
    return [round(math.degrees(math.acos(float(np.clip(a @ b, -1, 1)))), 3) for a, b in ((v[0], v[1]), (v[2], v[3]))]


def calibration_summary(cal, qual: dict, board, found: list, photos: list, *, output, report=None,
                        manifest=None, seconds: float = 0.0, rectified: dict | None = None) -> dict:
    """The summary of a calibration (``summary.json`` and ``--json``), JSON-ready.

    Keys: format, format_version, output, report, lensmodel, lensmodel_choice, candidates, imagersize,
    intrinsics (named), field_of_view_deg, board (+ manifest path), photos {given, used,
    rejected [{photo, reason}], frames (photo of each frame, in order)}, residuals, coverage,
    working_distance_mm, uncertainty, provenance (inputs with SHA-256), seconds, note (the
    text written at the top of the .cameramodel), rectified_pass (the inlier RMS, px, with the first
    corners and with those located again in rectified views, the first corners' outward pull
    against the second (``rectified.bend_pull``), and whether the second were kept).
    """
    model = cal.cameramodel()
    lens, values = model.intrinsics()
    used = [f for f in found if f.corners is not None]
    rejected = [{"photo": f.path, "reason": f.reason} for f in found if f.corners is None]
    for entry in qual["residuals"]["per_frame"]:
        corners = board.cols * board.rows
        if entry["outliers"] > corners / 2:
            rejected.append({"photo": entry["photo"], "reason": f"{entry['outliers']} of {corners} corners "
                             "rejected as outliers by the solve (kept in the solve, barely used)"})
    board_doc = board.to_dict()
    if manifest is not None:
        board_doc["manifest"] = str(manifest)
    inputs = [str(p) for p in photos] + ([str(manifest)] if manifest is not None else [])
    res = qual["residuals"]
    unc = qual["uncertainty"]
    scale = (qual.get("cross_validation") or {}).get("scale", 1.0)
    summary = {**DOCUMENT.envelope(), "output": str(output),
               "report": None if report is None else str(report), "lensmodel": lens,
               "lensmodel_choice": cal.choice, "rectified_pass": rectified, "candidates": cal.candidates,
               "imagersize": list(model.imagersize()),
               "intrinsics": intrinsics_named(lens, values), "field_of_view_deg": field_of_view(model),
               "board": board_doc,
               "photos": {"given": len(photos), "used": len(used), "rejected": rejected,
                          "frames": [f.path for f in used]},
               "residuals": res, "coverage": qual["coverage"], "working_distance_mm": qual["working_distance_mm"],
               "uncertainty": unc, "cross_validation": qual.get("cross_validation"),
               "provenance": make_provenance("camera calibrate (mrcal)", inputs),
               "advice": weak_corners(unc, distance_mm=qual["working_distance_mm"]), "seconds": round(float(seconds), 2)}
    summary["note"] = (f"lenticalib camera calibrate: {summary['provenance']['command'] or 'library call'}\n"
                       f"{len(used)} of {len(photos)} photos of a {board.describe()}; {lens} ({cal.choice})\n"
                       f"RMS {res['rms_px']:.4f} px, {res['outliers']} outliers of {res['corners']} corners; "
                       f"uncertainty {unc['at_working_distance']['centre']:.3f} px at the centre, "
                       f"{unc['at_working_distance']['worst']:.3f} px worst at {qual['working_distance_mm']:.0f} mm"
                       + (f" (mrcal's, x{scale:.3f} from cross-validation and the corner locator)" if scale > 1.0 else "")
                       + f"\n{note_line(scale)}")
    return json.loads(json.dumps(summary, default=lambda v: v.item() if isinstance(v, np.generic) else str(v)))


def summary_lines(summary: dict) -> list[str]:
    """The short human summary ``lenticalib camera calibrate`` prints."""
    i, res, unc = summary["intrinsics"], summary["residuals"], summary["uncertainty"]
    near, far = unc["at_working_distance"], unc["at_infinity"]
    corners = [near[k] for k in IMAGE_CORNERS]
    far_corners = [far[k] for k in IMAGE_CORNERS]
    lines = [f"wrote {summary['output']} ({summary['lensmodel']})",
             f"lens model: {summary['lensmodel_choice']}",
             f"photos: {summary['photos']['used']} of {summary['photos']['given']} with the board"
             + (f"; not used: {', '.join(Path(r['photo']).name for r in summary['photos']['rejected'])}"
                if summary["photos"]["rejected"] else ""),
             f"fit: RMS {res['rms_px']:.4f} px, worst {res['worst_px']:.3f} px, {res['outliers']} outliers of "
             f"{res['corners']} corners, pixel noise {res['noise_px']:.4f} px; corners cover "
             f"{100 * summary['coverage']:.0f}% of the image",
             f"focal {i['fx']:.2f} x {i['fy']:.2f} px, principal point ({i['cx']:.2f}, {i['cy']:.2f}) px, field of "
             f"view {summary['field_of_view_deg'][0]:.1f} x {summary['field_of_view_deg'][1]:.1f} deg",
             f"uncertainty (1 sigma, worst direction) at {summary['working_distance_mm']:.0f} mm: "
             f"{near['centre']:.3f} px "
             f"at the centre, {min(corners):.3f}-{max(corners):.3f} px at the image corners; at infinity "
             f"{far['centre']:.3f} px at the centre, {min(far_corners):.3f}-{max(far_corners):.3f} px at the image "
             f"corners, {far['worst']:.3f} px worst"]
    lines[3:3] = [f"  not used: {Path(r['photo']).name}: {r['reason']}" for r in summary["photos"]["rejected"]]
    cv = summary.get("cross_validation") or {}
    loc = cv.get("corner_locator") or {}
    if cv.get("skipped"):
        lines.append(f"cross-validation skipped: {cv['skipped']}")
    elif cv:
        lines.append(f"cross-validation: the two halves of the photos differ by {cv['median_difference_px']:.3f} px "
                     f"(median); mean squared Mahalanobis distance {cv['mean_squared_mahalanobis']:.2f} against 2 "
                     f"expected" + (f"; the model from the corners located the other way differs by "
                                    f"{loc['median_difference_px']:.3f} px (median), {loc['worst_difference_px']:.3f} px "
                                    f"worst, {loc['mean_squared_mahalanobis']:.2f} in squared sigmas"
                                    if "mean_squared_mahalanobis" in loc else "")
                     + f"; so uncertainties are x{cv['scale']:.2f}")
    lines += [f"advice: {line}" for line in summary.get("advice", [])]
    if summary["report"] is not None:
        lines.append(f"report: {summary['report']} (residuals.png, coverage.png, uncertainty.png, summary.json)")
    return lines


def _outline(ax, w, h, **kw):
    from matplotlib.patches import Rectangle

    ax.add_patch(Rectangle((-0.5, -0.5), w, h, fill=False, edgecolor=kw.get("color", "black"), lw=1.5,
                           label=kw.get("label", "image frame")))
    ax.set_xlim(-0.03 * w, 1.03 * w)
    ax.set_ylim(1.03 * h, -0.03 * h)
    ax.set_aspect("equal")
    ax.set_xlabel("image x (px)")
    ax.set_ylabel("image y (px)")


def _colorbar(fig, ax, mappable, label, extend="neither"):
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    cax = make_axes_locatable(ax).append_axes("right", size="3%", pad=0.12)
    return fig.colorbar(mappable, cax=cax, label=label, extend=extend)


def _residuals_figure(fig, subject) -> None:
    cal, qual = subject["cal"], subject["qual"]
    s = cal.solve
    obs = s.optimization_inputs["observations_board"][..., :2]
    w, h = s.optimization_inputs["imagersizes"][0]
    lengths = np.linalg.norm(s.residuals, axis=-1)
    ax = fig.add_axes((0.06, 0.1, 0.26, 0.78))
    top = max(float(np.percentile(lengths[s.inlier], 99.5)) * 1.5, 1e-6)
    bins = np.linspace(0.0, top, 40)
    ax.hist(np.clip(lengths[s.inlier], 0, top), bins=bins, color="tab:blue", label="corners kept")
    rejected = s.observed & ~s.inlier
    if rejected.any():
        ax.hist(np.clip(lengths[rejected], 0, top), bins=bins, color="tab:red", label="outliers (clipped at right)")
    rms = qual["residuals"]["rms_px"]
    ax.axvline(rms * math.sqrt(2), color="black", ls="--", label=f"RMS length {rms * math.sqrt(2):.3f} px")
    ax.set_xlabel("residual length (px)")
    ax.set_ylabel("corners")
    ax.set_title("Residual lengths")
    ax.legend(loc="upper right")
    ax2 = fig.add_axes((0.40, 0.1, 0.52, 0.78))
    p95 = max(float(np.percentile(lengths[s.inlier], 95)), 1e-6)
    gain = _nice(0.04 * w / p95)
    keep = s.inlier
    q = ax2.quiver(obs[keep][:, 0], obs[keep][:, 1], gain * s.residuals[keep][:, 0], gain * s.residuals[keep][:, 1],
                   lengths[keep], cmap="viridis", angles="xy", scale_units="xy", scale=1.0, width=0.0018)
    if rejected.any():  # not the corners a photo did not show (x, y = -1)
        ax2.plot(obs[rejected][:, 0], obs[rejected][:, 1], "x", color="tab:red", ms=6, label="outliers")
    _outline(ax2, w, h)
    ax2.legend(loc="lower right", framealpha=0.85)
    ax2.set_title(f"Residuals (projected - observed) at each corner, arrows lengthened x{gain:g}")
    _colorbar(fig, ax2, q, "residual length (px)")
    fig.suptitle(f"{cal.lensmodel}: RMS {rms:.4f} px per coordinate, {qual['residuals']['outliers']} outliers of "
                 f"{qual['residuals']['corners']} corners", fontsize=14)


def _coverage_figure(fig, subject) -> None:
    import matplotlib.patches as patches

    cal, qual = subject["cal"], subject["qual"]
    s = cal.solve
    obs = s.optimization_inputs["observations_board"][..., :2]
    w, h = s.optimization_inputs["imagersizes"][0]
    n = obs.shape[0]
    ax = fig.add_axes((0.07, 0.08, 0.82, 0.82))
    # the cells of the coverage grid (the cells the quality's coverage counts): empty ones shaded
    nx, ny = COVERAGE_GRID
    occupied = covered_cells(obs[s.observed], (w, h))
    empty = [(i, j) for i in range(nx) for j in range(ny) if (i, j) not in occupied]
    for k, (i, j) in enumerate(empty):
        ax.add_patch(patches.Rectangle((i * w / nx, j * h / ny), w / nx, h / ny, facecolor="tab:red", alpha=0.15,
                                       hatch="//", edgecolor="tab:red", lw=0,
                                       label="cell with no corner" if k == 0 else None))
    # the image corners the advice asks photos for (summary "advice"): their corner cells outlined
    weak = weak_corner_keys(qual["uncertainty"])
    for k, key in enumerate(weak):
        i, j = (0 if "left" in key else nx - 1), (0 if key.startswith("top") else ny - 1)
        ax.add_patch(patches.Rectangle((i * w / nx, j * h / ny), w / nx, h / ny, fill=False, edgecolor="tab:orange",
                                       lw=3, label="image corner the advice asks photos for" if k == 0 else None))
    for i in range(1, nx):
        ax.axvline(i * w / nx, color="0.75", lw=0.8, zorder=0)
    for j in range(1, ny):
        ax.axhline(j * h / ny, color="0.75", lw=0.8, zorder=0)
    frame = np.broadcast_to(np.arange(n)[:, None, None], obs.shape[:3])
    # one colour per photo: a qualitative map while its colours can be told apart
    cmap = "tab20" if n <= 20 else "turbo"
    sc = ax.scatter(obs[..., 0][s.inlier], obs[..., 1][s.inlier], c=frame[s.inlier] + 1, s=8, cmap=cmap,
                    vmin=0.5, vmax=(20 if n <= 20 else n) + 0.5, label="corners kept")
    rejected = s.observed & ~s.inlier
    if rejected.any():
        ax.plot(obs[..., 0][rejected], obs[..., 1][rejected], "x", color="black", ms=6, label="outliers")
    _outline(ax, w, h)
    ax.legend(loc="lower center", framealpha=0.85, markerscale=2)  # clear of the image corners
    ax.set_title(f"Observed corners of {n} photos over the {w}x{h} image: {100 * qual['coverage']:.0f}% of the "
                 f"{nx}x{ny} grid of cells covered\n(the lens is known only where corners are: fill the shaded cells"
                 + ("; reach the outlined image corners, as the advice says" if weak else "") + ")")
    bar = _colorbar(fig, ax, sc, "photo (frame number)")
    if n <= 20:
        bar.set_ticks(range(1, n + 1))
        bar.ax.set_ylim(0.5, n + 0.5)


def _uncertainty_figure(fig, subject) -> None:
    import matplotlib.patheffects as effects
    from matplotlib.colors import LogNorm

    cal, qual = subject["cal"], subject["qual"]
    maps = qual["_maps"]
    grid = maps["grid"]
    obs = cal.solve.optimization_inputs["observations_board"][..., :2]
    w, h = cal.solve.optimization_inputs["imagersizes"][0]
    pairs = ((maps["near"], f"at the working distance, {maps['distance']:.0f} mm"), (maps["far"], "at infinity"))
    top = float(max(np.max(maps["near"]), np.max(maps["far"])))
    bottom = max(float(min(np.min(maps["near"]), np.min(maps["far"]))), 1e-4, top / 1000)
    handles = []
    for k, (stdev, where) in enumerate(pairs):
        ax = fig.add_axes((0.05 + 0.49 * k, 0.13, 0.39, 0.72))
        im = ax.imshow(np.maximum(stdev, bottom), extent=(grid[0, 0, 0], grid[0, -1, 0], grid[-1, 0, 1], grid[0, 0, 1]),
                       origin="upper", cmap="magma", norm=LogNorm(vmin=bottom, vmax=max(top, bottom * 1.01)),
                       interpolation="bilinear")
        candidates = (0.005, 0.01, 0.02, 0.03, 0.05, 0.08, 0.1, 0.15, 0.2, 0.3, 0.5, 1, 2, 5)
        levels = [v for v in candidates if stdev.min() < v < stdev.max()]
        levels = levels[::max(1, int(np.ceil(len(levels) / 6)))]  # at most six contours
        if levels:
            cs = ax.contour(grid[0, :, 0], grid[:, 0, 1], stdev, levels=levels, colors="white", linewidths=1.0)
            for label in ax.clabel(cs, fmt="%g px", fontsize=10):
                label.set_path_effects([effects.withStroke(linewidth=2.5, foreground="black")])
        (dots,) = ax.plot(obs[..., 0][cal.solve.observed], obs[..., 1][cal.solve.observed], ".", color="cyan",
                          ms=1.5, alpha=0.6, label="observed corners")
        handles = [dots]
        _outline(ax, w, h, color="grey")
        ax.set_title(f"Projection uncertainty {where}")
        _colorbar(fig, ax, im, "worst-direction stdev (px, 1 sigma, log scale)")
    fig.legend(handles=handles, loc="lower center", markerscale=8, framealpha=0.85)
    scale = qual.get("cross_validation", {}).get("scale", 1.0)
    scaled = f", x{scale:.2f} from cross-validation and the corner locator" if scale > 1.0 else ""
    fig.suptitle(f"{cal.lensmodel}: how far a projection may be off (1 sigma, from the observed pixel noise "
                 f"{qual['residuals']['noise_px']:.4f} px{scaled})", fontsize=14)


def write_report(directory: str | os.PathLike, cal, qual: dict, summary: dict) -> Path:
    """Write the three figures and ``summary.json`` into ``directory`` (which must exist)."""
    directory = Path(directory)
    write_figures(directory, [("residuals.png", _residuals_figure), ("coverage.png", _coverage_figure),
                              ("uncertainty.png", _uncertainty_figure)], FIGURE_SIZES, {"cal": cal, "qual": qual})
    write_document(directory / "summary.json", DOCUMENT, summary)
    return directory
