"""``fit_capture_set``: photos of the test patterns -> a calibrated panel profile.

Steps (each checks its photos and fails with a message naming them):

1. open the capture set and load every photo as linear luminance (``captures``);
2. demodulate every phase-shift group; find the panel from the coarse fringes;
3. seen panel coordinates X (subpixels) and Y (rows) for every camera pixel, unwrapped
   coarse to fine and smoothed (``phase``) -- no camera model is needed for this;
4. the lens alias of the fine groups gives psi = (w* - N/2)/N per pixel; one plane fits
   them all (``model``), with block-jackknife uncertainties;
5. red-only and blue-only photos against that plane give the subpixel order; with the cell
   photos (``lenticalib patterns --cells``) each channel's shift per cell class gives the stripe
   order or the cell layout instead (``layout_fit``);
6. quality gates: coherence, residual, uncertainty; then the profile and its provenance.

The fit reads only the photos and ``patterns.json``: nothing the simulator knows.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from typing import Callable

import cv2
import numpy as np

from ...core.errors import CalibrationError, CaptureError, InputError
from ...core.identity import virtual_panel_record
from ...core.profile import PanelProfile, make_provenance
from . import layout_fit, model, photometric
from ..patterns import phase
from ..camera.from_panel import CameraModel, describe_pose, estimate_camera, load_camera_model
from ..patterns.capture_sets import CaptureSet, Photo, open_capture_set
from .checks import check_clipping, check_photo_steps, mask_checks
from .groups import Group, Registration, demodulate_group
from .order_photos import ORDER_CHANNELS, cell_layout, predicted_fine_cycles, subpixel_order
from ..patterns.calibration_patterns import (CELL_PERIOD_RANGE, CELL_X_GROUPS, CELL_Y_GROUPS, FINE_PERIODS,
    PERIOD_RANGE)
from ..camera.pose import PanelPose, camera_pose
from .uncertainty import constants_with_uncertainty, quality_and_covariance, registration_variance

ProgressFn = Callable[[str], None]

# What fit_capture_set does, in order: every photo of these groups is read (one progress call
# each), and each stage is one progress call; progress_steps counts from the same lists.
DEMODULATED_GROUPS = ("x1", "y1", "x0", "y0", "x2") + tuple(f"f{t:g}" for t in FINE_PERIODS)
STAGE_PANEL, STAGE_COORDINATES, STAGE_PLANE, STAGE_ORDER = STAGES = (
    "finding the panel", "measuring seen panel coordinates", "fitting the view-coordinate plane", "subpixel order")
STAGE_LAYOUT = "subpixel layout"  # only for a set with the cell photos


def progress_steps(pattern_set) -> int:
    """How many times :func:`fit_capture_set` calls ``progress`` for a capture set of ``pattern_set``
    (a :class:`~.patterns.PatternSet`): once per photo it reads, once per stage."""
    cells = getattr(pattern_set, "cells", False)
    names = DEMODULATED_GROUPS + tuple(ORDER_CHANNELS) + (CELL_Y_GROUPS + sum(CELL_X_GROUPS.values(), ()) if cells else ())
    photos = sum(len(pattern_set.group(name)) for name in names)
    return photos + len(STAGES) + (1 if cells else 0)

# Quality gates (views unless stated).  A fit failing one is reported as untrustworthy.
MAX_BLOCK_RESIDUAL_RMS = 0.12  # systematic misfit of the plane, RMS over panel blocks
MAX_PREDICTED_ERROR = 0.15  # 1-sigma of w at the worst panel corner relative to the centre (non-uniformity)
# 1-sigma of the mean of w: a rotation of the whole view cone, which viewers do not see as
# banding or ghosting; refused only when it may reach half a view
MAX_PREDICTED_CENTRING = 0.5
MIN_COHERENCE = 0.15  # |mean exp(2 pi i residual)| of the fine samples
MIN_ORDER_MARGIN = 0.35  # fraction of the RGB/BGR separation
MAX_ALIAS = 0.42  # |T/Delta_r - 1| ... a fine group aliasing beyond this is not used
MAX_LAYOUT_SIGMA = 0.08  # views: 1-sigma of a cell layout's shifts (a stripe found is exact)


@dataclasses.dataclass
class FitResult:
    """A fitted profile, whether it passed the quality gates, and everything the report shows."""

    profile: PanelProfile
    trusted: bool
    problems: list[str]
    quality: dict
    maps: dict
    seconds: float
    warnings: list[str] = dataclasses.field(default_factory=list)
    direction: dict | None = None  # evidence of --moved-right (calib/routing/direction.py), when given
    pose: PanelPose | None = None  # the camera's pose in mm (a camera model and the pixel pitch given)
    layout: layout_fit.LayoutDecision | None = None  # from the cell photos, when the set has them


def _correct_photometry(groups: dict[str, "Group"], mask: np.ndarray) -> dict[str, bool]:
    """Cancel the tone-curve phase error of the coordinate groups (see :mod:`.photometric`)."""
    done = {}
    for fine, coarse, along in (("x1", "x0", "x"), ("x2", None, "x"), ("y1", "y0", "y")):
        g = groups[fine]
        measured = phase.phase_cycles(g.z)
        table = photometric.phase_error_table(measured, _modulation_weight(g, mask), along)
        done[fine] = table is not None
        g.cycles = photometric.correct_phase(measured, table)
        if coarse:
            groups[coarse].cycles = photometric.correct_phase(phase.phase_cycles(groups[coarse].z), table)
    return done


def _coordinate_maps(capture: CaptureSet, groups: dict[str, Group], mask: np.ndarray):
    ps = capture.patterns
    h, w = mask.shape
    sub, rows = 3 * ps.width, ps.height
    x0 = phase.coordinate_from_single_period(groups["x0"].phase(), groups["x0"].period, sub)
    y0 = phase.coordinate_from_single_period(groups["y0"].phase(), groups["y0"].period, rows)
    cols, rws = np.meshgrid(np.arange(w), np.arange(h))
    for name, coord, along, extent in (("x0", x0, cols, sub), ("y0", y0, rws, rows)):
        c = coord[mask]
        span = np.percentile(c, 99) - np.percentile(c, 1)
        corr = np.corrcoef(c[::97], along[mask][::97])[0, 1] if c.size > 200 else 0.0
        if not (0.45 * extent < span < 1.15 * extent) or abs(corr) < 0.8:
            names = ", ".join(p.name for p in ps.group(name))
            raise CaptureError(f"photos {names} do not show a fringe across the panel as expected",
                               source=str(capture.directory / "captures"),
                               hint="retake them with the patterns shown full screen, in order, and the camera "
                                    "upright (less than 45 degrees of roll)")
        if corr < 0:
            raise CaptureError(f"photos of group {name} are mirrored or in the wrong order",
                               source=str(capture.directory / "captures"),
                               hint="do not mirror the photos (selfie camera) and name each photo like its pattern")
    check_photo_steps(groups["x0"], x0 / groups["x0"].period, mask, capture, "")
    check_photo_steps(groups["y0"], y0 / groups["y0"].period, mask, capture, "")
    coords = {}
    # The single-fringe coordinates are smooth functions of the pixel (one fringe over the panel):
    # smoothed, their noise no longer picks wrong fringes of the next group in noisy photos.
    frame_sigma = max(3.0, mask.shape[1] / 150.0)
    weight = mask.astype(np.float32)
    x0s = np.where(mask, phase.smooth_coordinate(x0, weight, frame_sigma), x0)
    y0s = np.where(mask, phase.smooth_coordinate(y0, weight, frame_sigma), y0)
    for chain, start in ((("x1", "x2"), x0s), (("y1",), y0s)):
        coarse, coarse_name = start, chain[0][0] + "0"
        for name in chain:
            g = groups[name]
            check_photo_steps(g, coarse / g.period, mask, capture, f"(checked against group {coarse_name})")
            fine, residual = phase.unwrap(coarse, g.phase(), g.period)
            bad = float(np.mean(np.abs(residual[mask]) > 0.3))
            if bad > 0.2:
                raise CaptureError(f"group {name} disagrees with group {coarse_name} on {100 * bad:.0f}% of the "
                                   "panel", source=str(capture.directory / "captures"),
                                   hint="the camera moved between photos, or photos are swapped; use a tripod "
                                        "and retake the set")
            coarse, coarse_name = fine, name
        coords[chain[0][0]] = (coarse, groups[chain[-1]])
    return coords


def _modulation_weight(group: Group, mask: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.abs(group.z) / np.maximum(group.dc, 1e-6)
    return np.where(mask, np.clip(ratio, 0.0, 1.5), 0.0).astype(np.float32)


def fit_capture_set(directory: str | os.PathLike, *, views: int | None = None,
                    camera_model: CameraModel | str | os.PathLike | None = None,
                    pixel_pitch_mm: float | None = None,
                    progress: ProgressFn | None = None) -> FitResult:
    """Fit the panel profile from the capture set in ``directory``; see the module docstring.

    Raises CaptureError for unusable photos and CalibrationError when no plane fits.  A fit
    that converges but fails a quality gate is returned with ``trusted=False`` and the
    reasons in ``problems``.  With ``camera_model`` and ``pixel_pitch_mm`` the result carries the
    camera's pose in mm (``pose``, distances to the pixel plane: :mod:`.pose`).
    """
    start = time.perf_counter()
    given_camera = None if not camera_model else \
        camera_model if isinstance(camera_model, CameraModel) else load_camera_model(camera_model)
    capture = open_capture_set(directory)
    ps = capture.patterns
    if given_camera is not None:
        _check_camera_size(given_camera, capture)
    n_views = views or ps.views
    groups: dict[str, Group] = {}
    shape = None
    registration = Registration()
    for name in DEMODULATED_GROUPS:
        groups[name] = demodulate_group(capture, name, shape, progress, registration)
        shape = groups[name].photos[0].shape
    if progress:
        progress(STAGE_PANEL)
    mask = phase.panel_mask([np.abs(groups["x1"].z), np.abs(groups["y1"].z)])
    mask_checks(mask, capture)
    warnings = registration.warnings
    check_clipping(list(groups.values()), mask)
    photometry = _correct_photometry(groups, mask)

    if progress:
        progress(STAGE_COORDINATES)
    coords = _coordinate_maps(capture, groups, mask)
    h, w = mask.shape
    sigma = max(3.0, w / 300.0)
    x_raw, xg = coords["x"]
    y_raw, yg = coords["y"]
    # The finest x/y groups were Gaussian-averaged in _demodulate_group (y1: sigma = frame/300,
    # ~16 rows).  Near the panel border that average is one-sided (the bezel has no fringe) and
    # pulls the seen coordinate toward the panel centre: +-0.4..4 rows in the first rows inside
    # the mask, which shrinks the Y map by ~5e-5 and makes |C_r| too large.  Use only pixels
    # whose averaging window lies on the panel.
    r = int(math.ceil(2.5 * max(xg.sigma, yg.sigma)))
    inner = cv2.erode(mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
                      ).astype(bool) if r > 0 else mask
    x_sm = phase.smooth_coordinate(x_raw, _modulation_weight(xg, inner), sigma)
    y_sm = phase.smooth_coordinate(y_raw, _modulation_weight(yg, inner), sigma)
    valid = inner & np.isfinite(x_sm) & np.isfinite(y_sm)
    valid &= (x_sm >= 0) & (x_sm < 3 * ps.width) & (y_sm >= 0) & (y_sm < ps.height)

    if progress:
        progress(STAGE_PLANE)
    stride = max(1, int(round(math.sqrt(valid.sum() / 800_000))))
    sub = np.zeros_like(valid)
    sub[::stride, ::stride] = True
    take = valid & sub
    xs, ys = x_sm[take], y_sm[take]
    parts = []
    for gi, period in enumerate(FINE_PERIODS):
        g = groups[f"f{period:g}"]
        psi = model.wrap(g.phase()[take] - xs / period)
        weight = _modulation_weight(g, mask)[take]
        parts.append(model.PlaneSamples(xs, ys, psi, weight, np.full(xs.shape, gi)))
    all_samples = model.PlaneSamples(*(np.concatenate([getattr(p, f) for p in parts])
                                       for f in ("x", "y", "psi", "weight", "group")))
    a0, b0 = model.fft_search(all_samples, ps.width, ps.height, PERIOD_RANGE)
    xc, yc = 1.5 * ps.width, 0.5 * ps.height
    first, _ = model.fit_plane(all_samples, a0, b0, xc, yc)
    period0 = -1.0 / first.a
    group_fits, used = [], []
    for gi, period in enumerate(FINE_PERIODS):
        alias = period0 / period - 1.0 if period0 / period < 1.5 else 9.0
        gfit, _ = model.fit_plane(parts[gi], first.a, first.b, xc, yc)
        group_fits.append((period, alias, gfit))
        if abs(alias) <= MAX_ALIAS and gfit.coherence >= MIN_COHERENCE:
            used.append(gi)
    if not used:
        best = max(group_fits, key=lambda t: t[2].coherence)
        raise CalibrationError(f"no fine group gives a usable phase (best coherence {best[2].coherence:.2f}, "
                               f"lens period near {period0:.2f} subpixels)", source=str(capture.directory),
                               hint=f"the fine patterns resolve lens periods of {PERIOD_RANGE[0]:g} to "
                                    f"{PERIOD_RANGE[1]:g} subpixels; check focus (the fine fringes must be sharp)")
    keep = np.isin(all_samples.group, used)
    samples = model.PlaneSamples(*(getattr(all_samples, f)[keep] for f in ("x", "y", "psi", "weight", "group")))
    fit, final_weights = model.fit_plane(samples, first.a, first.b, xc, yc)
    cov = model.block_jackknife(samples, fit, final_weights, ps.width, ps.height)
    if len(used) > 1:
        diffs = np.array([[g.a - fit.a, g.b - fit.b, float(model.wrap(g.c0 - fit.c0))]
                          for _, _, g in (group_fits[i] for i in used)])
        cov = cov + np.diag(np.mean(diffs ** 2, axis=0))

    if progress:
        progress(STAGE_ORDER)
    order = subpixel_order(capture, fit, x_sm, y_sm, valid, shape, groups, progress, registration)
    _check_fine_photos(capture, groups, fit, x_sm, y_sm, valid, used)
    layout = None
    if ps.cells:
        if progress:
            progress(STAGE_LAYOUT)
        layout = cell_layout(capture, fit, x_sm, y_sm, valid, shape, groups, progress, registration, n_views)

    camera, pose = _camera(groups["x1"].photos[0], x_sm, y_sm, valid, ps, given_camera, pixel_pitch_mm)
    reg_var = registration_variance(groups, registration.shifts, x_sm, y_sm, valid, fit, used)
    quality, cov = quality_and_covariance(fit, samples, final_weights, cov, ps, n_views, reg_var)
    constants, sigmas = constants_with_uncertainty(fit, cov)
    if layout is not None and layout.layout is not None:  # the offset in the gauge of the layout written
        constants["offset"] = layout_fit.regauged_offset(constants["offset"], constants["period"], layout)
    quality.update({
        "fine_groups": [{"period": p, "alias": round(al, 4), "coherence": round(g.coherence, 4),
                         "used": i in used, "period_estimate": -1.0 / g.a} for i, (p, al, g) in enumerate(group_fits)],
        "subpixel_order": dataclasses.asdict(order),
        **({"subpixel_layout": layout.to_dict()} if layout is not None else {}),
        "panel_fraction_of_frame": float(mask.mean()),
        "working_resolution": [w, h],
        "photo_resolution": [shape[1], shape[0]],
        "camera": camera,
        "photo_shifts_pixels": registration.shifts,
        "tone_correction": photometry,
    })
    block_map = quality.pop("block_residual_map")
    problems = []
    if quality["block_residual_rms_views"] > MAX_BLOCK_RESIDUAL_RMS:
        problems.append(f"the plane misfits the measurement by {quality['block_residual_rms_views']:.3f} views RMS "
                        f"(limit {MAX_BLOCK_RESIDUAL_RMS})")
    if quality["predicted_error_worst_views"] > MAX_PREDICTED_ERROR:
        problems.append(f"1-sigma uncertainty of the view coordinate reaches "
                        f"{quality['predicted_error_worst_views']:.3f} views at a corner, relative to the "
                        f"centre (limit {MAX_PREDICTED_ERROR})")
    if quality["predicted_error_centre_views"] > MAX_PREDICTED_CENTRING:
        problems.append(f"1-sigma uncertainty of the centring reaches {quality['predicted_error_centre_views']:.3f} "
                        f"views (limit {MAX_PREDICTED_CENTRING})")
    if quality["coherence"] < MIN_COHERENCE:
        problems.append(f"fine fringes are weak (coherence {quality['coherence']:.2f}, limit {MIN_COHERENCE})")
    if layout is not None and layout.layout is not None:
        layout_sigma = float(np.max(layout.cell_sigma)) * n_views / constants["period"]
        if layout_sigma > MAX_LAYOUT_SIGMA:
            problems.append(f"1-sigma uncertainty of the subpixel layout reaches {layout_sigma:.3f} views (limit "
                            f"{MAX_LAYOUT_SIGMA}; the cell photos measure well at lens periods of about "
                            f"{CELL_PERIOD_RANGE[0]:g} to {CELL_PERIOD_RANGE[1]:g} "
                            f"subpixels, this panel's is {constants['period']:.2f})")
    if layout is None and order.margin < MIN_ORDER_MARGIN:
        problems.append(f"subpixel order is ambiguous (margin {order.margin:.2f}, limit {MIN_ORDER_MARGIN}; a panel "
                        "whose subpixels are not a stripe? photograph the cell patterns too: 'lenticalib patterns "
                        "--cells')")

    seconds = time.perf_counter() - start
    virtual_panel = virtual_panel_record(capture.directory)  # photos of the virtual panel: which one (docs/identity.md)
    provenance = make_provenance(
        "lenticalib fit: phase-shifted sinusoids seen through the lens sheet; plane fit of the lens alias",
        capture.inputs, pattern_set=ps.set_id, quality=quality, seconds=round(seconds, 2),
        convention="w(x_s, y) = w*(x_s + 0.5, y + 0.5); calibration camera at w* = N/2",
        **({} if virtual_panel is None else {"virtual_panel": virtual_panel}))
    profile = PanelProfile(views=n_views, slant=constants["slant"], period=constants["period"],
                           offset=constants["offset"], reference_view=n_views / 2.0,
                           width=ps.width, height=ps.height,
                           subpixel_order=order.order if layout is None else layout.order,
                           subpixel_layout=None if layout is None else layout.layout,
                           uncertainty=sigmas, provenance=provenance)
    maps = {"block_residual_map": block_map, "mask": mask, "x": x_sm, "y": y_sm, "valid": valid, "fit": fit,
            "dc": groups["y1"].dc, "samples": samples, "weights": final_weights, "sample_pixels": take}
    return FitResult(profile, not problems, problems, quality, maps, seconds, warnings, pose=pose, layout=layout)


def _check_fine_photos(capture, groups, fit, x_sm, y_sm, valid, used) -> None:
    """Each fine photo must show its phase step of the fringe the fitted plane predicts."""
    for gi, period in enumerate(FINE_PERIODS):
        if gi not in used:
            continue
        g = groups[f"f{period:g}"]
        pred = predicted_fine_cycles(fit, x_sm, y_sm, valid, period)
        check_photo_steps(g, pred, valid, capture, "(checked against the fitted panel model)")


def _check_camera_size(model, capture) -> None:
    """InputError before the fit when the camera model was calibrated at another image size."""
    if model.image_size is None:
        return
    w, h = capture.photo_size
    if (w, h) != tuple(model.image_size):
        raise InputError(f"the camera model is for {model.image_size[0]}x{model.image_size[1]} images, the photos are "
                         f"{w}x{h}", source=str(model.source),
                         hint="use the model of the camera (and resolution) that took these photos; do not resize "
                              "the photos")


def _camera(photo: Photo, x_sm, y_sm, valid, ps, given, pixel_pitch_mm) -> tuple[dict, PanelPose | None]:
    """Camera estimate from ~2500 correspondences on a grid over the measured panel; with a
    camera model, the pose from ~20000 (and in mm with the pixel pitch)."""
    rows, cols = np.nonzero(valid)
    step = max(1, rows.size // (20000 if given is not None else 2500))
    rows, cols = rows[::step], cols[::step]
    pixels = np.column_stack([(cols + 0.5) / photo.scale - 0.5, (rows + 0.5) / photo.scale - 0.5])
    panel = np.column_stack([x_sm[rows, cols] / 3.0 - ps.width / 2.0, y_sm[rows, cols] - ps.height / 2.0])
    if given is not None:  # the user asked for a metric pose: a failure is an error, not a note
        pose = camera_pose(pixels, panel, given, pixel_pitch_mm or 1.0)
        return describe_pose(pose, given, pixel_pitch_mm), pose if pixel_pitch_mm else None
    try:
        return estimate_camera(pixels, panel, (photo.shape[1], photo.shape[0])), None
    except (cv2.error, np.linalg.LinAlgError, ValueError) as exc:  # informative only: never fail the fit
        return {"source": "not estimated", "reason": str(exc).strip().splitlines()[-1][:200]}, None
