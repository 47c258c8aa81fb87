"""The subpixel order and the cell layout, read from the order and cell photos against the fitted plane.

Step 5 of :func:`.fit.fit_capture_set`: the red-only and blue-only photos (``ORDER_CHANNELS``)
give RGB or BGR (:func:`subpixel_order`); with the cell photos each channel's shift per cell class
gives the stripe order or the cell layout instead (:func:`cell_layout`, :mod:`.layout_fit`).
Phases are in fringe cycles per working pixel; shifts in pattern units (subpixels, rows).
"""

from __future__ import annotations

import math

import numpy as np

from ...core.errors import CaptureError
from . import layout_fit, model
from .groups import group_photos
from ..patterns.calibration_patterns import CELL_X_GROUPS, CELL_Y_GROUPS, CELL_Y_PERIOD, FINE_PERIODS

ORDER_CHANNELS = {"order-r": 0, "order-b": 2}  # the order photos, and the channel each lights
MIN_CELL_CONTRAST = 0.1  # a cell photo's fringe contrast, of the fine green group's


def predicted_fine_cycles(fit, x_sm, y_sm, valid, period):
    """float64 (h, w) working grid: the fine fringe's phase (cycles) the fitted plane ``fit`` predicts at
    each valid pixel for a pattern of ``period`` subpixels (0 elsewhere)."""
    out = np.zeros(x_sm.shape)
    out[valid] = x_sm[valid] / period + fit.psi(x_sm[valid], y_sm[valid])
    return out


def subpixel_order(capture, fit, x_sm, y_sm, valid, shape, groups, progress, registration) -> model.OrderDecision:
    """RGB or BGR from the red-only and blue-only photos against the fitted plane (:func:`.model.decide_order`);
    CaptureError naming a photo of the wrong colour or without fringes."""
    period = capture.patterns.group("order-r")[0].period
    pred = predicted_fine_cycles(fit, x_sm, y_sm, valid, period)
    f_ref = groups[f"f{period:g}"]
    # the median: a dark, noisy pixel (or the resampling's ringing next to one) has dc near 0
    # and would dominate a mean of the ratio
    ref_amp = float(np.median(np.abs(f_ref.z[valid]) / np.maximum(f_ref.dc[valid], 1e-6)))
    offsets, amps = {}, {}
    for name, channel in ORDER_CHANNELS.items():
        photo = group_photos(capture, name, shape, progress, keep_rgb=True)[0]
        registration.undo_shake([photo], capture)
        rgb_mean = photo.rgb[valid].mean(axis=0)
        other = 2 - channel
        if rgb_mean[channel] <= rgb_mean[other]:
            colour = "red" if channel == 0 else "blue"
            raise CaptureError(f"should show a {colour} pattern but its panel is not {colour}",
                               source=str(photo.path),
                               hint=f"photograph {name}.png (swapped with the other order photo?)")
        amplitudes, _, _ = layout_fit.block_phases(photo.luma, pred, valid, block=48)
        q, blocks = complex(amplitudes.sum()), int(amplitudes.size)
        blocks = max(1, blocks)
        amps[name] = abs(q) / blocks / max(ref_amp, 1e-9)
        offsets[name] = math.atan2(q.imag, q.real) / (2 * math.pi)
        if amps[name] < 0.15:
            raise CaptureError(f"shows almost no fringes of pattern {name} (contrast {amps[name]:.2f} of the fine "
                               "green group)", source=str(photo.path),
                               hint=f"show {name}.png full screen, keep the camera still and in focus, and retake")
    return model.decide_order(offsets["order-r"], offsets["order-b"], period, amps["order-r"], amps["order-b"])


def cell_layout(capture, fit, x_sm, y_sm, valid, shape, groups, progress, registration,
                 views: int) -> layout_fit.LayoutDecision:
    """The stripe order or the cell layout from the cell photos (:mod:`.layout_fit`); CaptureError
    naming a photo that does not show its channel's fringes (at every period of the x photos),
    CalibrationError (one line) when the shifts cannot tell the layout."""
    lens_period = -1.0 / fit.a
    slant = fit.b * lens_period / 3.0
    parts, floors, weak = [], [], []
    for period, names in CELL_X_GROUPS.items():
        reference = groups[f"f{min(FINE_PERIODS, key=lambda p: abs(p - period)):g}"]
        part, faint = _cell_shifts(capture, names, period, predicted_fine_cycles(fit, x_sm, y_sm, valid, period),
                                   reference, valid, shape, progress, registration)
        parts.append(part)
        floors.append(layout_fit.shift_floor(lens_period, period))
        weak.append(faint)
    for key, error in weak[0].items():  # a photo without fringes is an error only when no period has them
        if all(key in faint for faint in weak[1:]):
            raise error
    along_row, floor = layout_fit.combine_periods(parts, floors)
    along_column, faint = _cell_shifts(capture, CELL_Y_GROUPS, CELL_Y_PERIOD,
                                       np.where(valid, y_sm / CELL_Y_PERIOD, 0.0), groups["y1"], valid, shape,
                                       progress, registration)
    for error in faint.values():
        raise error
    shifts = layout_fit.route_shifts(along_row, along_column, slant)
    decision = layout_fit.decide_layout(shifts, views / lens_period, floor)
    layout_fit.refuse_if_unresolved(decision, str(capture.directory / "captures"))
    return decision


def _cell_shifts(capture, names, period, pred, reference, valid, shape, progress,
                 registration) -> tuple[layout_fit.CellShifts, dict]:
    """The shifts (in units of the pattern coordinate) one kind of cell photo measures, against the
    phase ``pred`` (cycles, per working pixel); contrast judged against the green group ``reference``.

    Returns the shifts (sigma ``inf`` for a photo whose fringes are too faint) and, per
    ``(class, channel)`` of such a photo, the CaptureError that names it; a photo of the wrong
    colour raises at once."""
    ref_amp = float(np.median(np.abs(reference.z[valid]) / np.maximum(reference.dc[valid], 1e-6)))
    classes = len(names) // 3
    offset, sigma, amplitude = (np.zeros((classes, 3)) for _ in range(3))
    faint = {}
    for name in names:
        channel, k = "rgb".index(name[-2]), int(name[-1])
        photo = group_photos(capture, name, shape, progress, keep_rgb=True)[0]
        registration.undo_shake([photo], capture)
        rgb_mean = photo.rgb[valid].mean(axis=0)
        if int(np.argmax(rgb_mean)) != channel:
            colour = ("red", "green", "blue")[channel]
            raise CaptureError(f"should show a {colour} pattern but its panel is not {colour}",
                               source=str(photo.path), hint=f"photograph {name}.png (swapped with another cell photo?)")
        q, rows, cols = layout_fit.block_phases(photo.luma, pred, valid)
        offset[k, channel], sigma[k, channel], amp = layout_fit.phase_offset(q, rows, cols, photo.luma.shape)
        amplitude[k, channel] = amp / max(ref_amp, 1e-9)
        if amplitude[k, channel] < MIN_CELL_CONTRAST:
            faint[(k, channel)] = CaptureError(
                f"shows almost no fringes of pattern {name} (contrast {amplitude[k, channel]:.2f} of the green "
                "group's)", source=str(photo.path),
                hint=f"show {name}.png full screen, keep the camera still and in focus, and retake")
            sigma[k, channel] = math.inf
    shifts = layout_fit.shifts_from_offsets(offset, sigma, amplitude, period)
    return shifts, faint
