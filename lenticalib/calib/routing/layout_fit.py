"""The subpixel layout from the cell photos: each channel's shift across the lenses, per cell class.

Frames and units: working-image pixels (see :mod:`.phase`); panel coordinates ``X`` (subpixels)
and ``Y`` (rows); shifts in subpixels along a row.

THE MEASUREMENT.  A cell photo (``cell-<c><k>``, :data:`.patterns.CELL_GROUPS`; ``cellw-<c><k>`` and
``cellv-<c><k>`` at further periods, :data:`.patterns.CELL_X_GROUPS`) shows the fine sinusoid of period ``T``
in channel ``c`` only, evaluated at the channel's stripe-RGB slot
``x_s = 3 x + c``, and only in the pixels of cell class ``k`` (``2 (y % 4) + x % 2``); a
``celly-<c><k>`` photo (:data:`.patterns.CELL_Y_GROUPS`) a sinusoid of ``CELL_Y_PERIOD`` rows
along y.  The camera sees the light of a subpixel where it is: if channel ``c`` sits ``a``
subpixels along the row from its stripe slot (``a = 1 + 3 dx - c``) and ``dy`` rows down, the
x photo's fringe is moved by ``-a / T`` cycles against the fitted plane and the y photo's by
``-dy / T_y`` against the measured row coordinate.  The lenses route by the position across
them only, ``e = a - 3 C_r dy`` (``docs/optics.md``): :func:`route_shifts`.  The coordinate
maps and the fitted plane come from patterns lit in green in every pixel, so they sit at the
green light's mean position: what the photos measure is ``r = e - mean over classes of e(G)``.
A shift common to every slot is a change of the offset and cannot be told from it, so that is
the layout's gauge (the fitted offset carries the rest).

Per photo the phase offset against the plane's prediction is fitted block by block
(``A + Re(m exp(2 pi i predicted))`` in blocks of ``BLOCK`` pixels); its 1-sigma comes from a
delete-one-tile jackknife over ``TILES`` tiles of the panel, so spatially correlated errors count
(moire of the sparse lit pixels, glare, JPEG); a cell's sigma has a systematic floor
(:func:`shift_floor`).  The periods of x photos are combined per class and channel by
their sigmas and floors (:func:`combine_periods`).  The offsets of the eight green photos give the
reference (their mean is the plane's own green), which also cancels what all single photos share
(the tone curve's harmonics, the camera's colour mixing into the luminance).

THE DECISION.  The stripe ``RGB`` (``r = 0, 0, 0`` in every class) or ``BGR`` (``r = 2, 0, -2``)
when every shift agrees with it within ``AGREE_SIGMAS`` sigma (or ``AGREE_FLOOR`` subpixels);
else a :class:`~lenticalib.core.layout.SubpixelLayout`: classes whose shifts agree are merged
into cells, which gives the cell pattern, and each cell's channel offsets are
``dx = (r + g - 1 + c) / 3`` pixels with ``dy = 0``, the common ``g`` chosen so that the channel
centres average to the pixel centre over the panel (the offset moves by ``g`` too).  The fit cannot tell (one-line refusal) when a
shift's 1-sigma exceeds ``MAX_SHIFT_SIGMA_VIEWS`` views or a class agrees with no cell.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...core.errors import CalibrationError
from ...core.layout import CHANNELS, SubpixelLayout, stripe_layout
from ..patterns.calibration_patterns import CELL_CLASSES, CELL_COLUMNS, CELL_ROWS

BLOCK = 32  # working pixels per side of a block of the phase fit
TILES = (6, 4)  # jackknife tiles of the panel (across, down)
AGREE_SIGMAS = 3.0  # shifts agree when within this many combined sigma ...
AGREE_FLOOR = 0.06  # ... or this many subpixels (a systematic floor of the method)
MAX_SHIFT_SIGMA_VIEWS = 0.08  # a shift known worse than this (1 sigma, in views) is not resolved
# Systematic floor of a cell's shift (1 sigma, subpixels), added to the statistical sigma of the
# merged classes (which shrinks with their number, while the errors are common to the classes):
# SHIFT_FLOOR + ALIAS_FLOOR (Delta_r / T - 1)^2 (:func:`shift_floor`).  Simulated sets
# (tools/bench_layouts.py) show per-channel errors, the same in every class (stripe panels too:
# R and B opposite), that grow with the photos' alias: up to 0.016 subpixel at
# |Delta_r / T - 1| < 0.1, 0.025 at 0.19 and 0.073 at 0.46.  A colour plane of the camera
# displaced by a fraction of a pixel (lateral chromatic aberration, demosaicing) moves a fringe's
# phase in proportion to its frequency, the alias; the fit cannot tell that from a shift.
SHIFT_FLOOR = 0.015
ALIAS_FLOOR = 0.25


def shift_floor(lens_period: float, period: float) -> float:
    """The systematic 1-sigma floor (subpixels) of a cell's shift measured with photos of ``period``
    on a panel of ``lens_period`` (both subpixels)."""
    return SHIFT_FLOOR + ALIAS_FLOOR * (lens_period / period - 1.0) ** 2
STRIPE_SHIFTS = {"RGB": (0.0, 0.0, 0.0), "BGR": (2.0, 0.0, -2.0)}


@dataclasses.dataclass
class CellShifts:
    """Measured shifts ``r`` (subpixels) per cell class and channel, with 1-sigma.

    ``shift``, ``sigma``: float64 ``(CELL_CLASSES, 3)``, ``[class, channel]`` (R, G, B);
    ``amplitude``: the fringe contrast of each photo relative to the fine green group.
    """

    shift: np.ndarray
    sigma: np.ndarray
    amplitude: np.ndarray
    period: float
    parts: dict | None = None  # the measurements it was made of (:func:`route_shifts`)

    def to_dict(self) -> dict:
        out = {"definition": "r = slot shift across the lenses minus the mean green shift, subpixels; "
                             "rows: cell classes 2 (y % 4) + x % 2, columns R, G, B",
               "shift_subpixels": np.round(self.shift, 4).tolist(),
               "sigma_subpixels": np.round(self.sigma, 4).tolist(),
               "amplitude": np.round(self.amplitude, 3).tolist()}
        for name, part in (self.parts or {}).items():
            out[name] = part.to_dict()
        return out


def combine_periods(parts: list[CellShifts], floors: list[float]) -> tuple[CellShifts, np.ndarray]:
    """The shifts along the row from x photos at several periods, and their systematic floor.

    ``parts``: one :class:`CellShifts` per period (its ``sigma`` statistical, ``inf`` where a
    photo showed no usable fringe); ``floors``: each period's systematic 1-sigma (subpixels,
    :func:`shift_floor`).  Per class and channel the measurements are averaged with weights
    ``1 / (sigma^2 + floor^2)``, so the period that measures better dominates (near its blind
    spot a period's jackknife sigma is large; where it aliases strongly, its floor is).  Returns
    the combined shifts (statistical sigma ``sqrt(sum w^2 sigma^2) / sum w``) and the combined
    floor, float64 ``(CELL_CLASSES, 3)`` (``sum w floor / sum w``: the floors of one channel are
    alike in every class, so they add linearly).  Where two periods disagree by more than their
    combined uncertainty, the statistical sigma grows by that ratio (the Birge ratio), so a
    sigma stays honest when one period is off by more than it claims.
    """
    shift = np.stack([p.shift for p in parts])
    stat = np.stack([p.sigma for p in parts])
    floor = np.broadcast_to(np.asarray(floors, dtype=np.float64)[:, None, None], shift.shape)
    total = np.hypot(stat, floor)
    w = np.where(np.isfinite(total), 1.0 / np.maximum(total, 1e-9) ** 2, 0.0)
    wsum = w.sum(axis=0)
    if np.any(wsum <= 0.0):  # no period measured this class and channel
        out_sigma = np.where(wsum > 0, 0.0, np.inf)
        wsum = np.where(wsum > 0, wsum, 1.0)
    else:
        out_sigma = np.zeros(wsum.shape)
    finite = np.isfinite(total)
    mean = np.where(finite, w * shift, 0.0).sum(axis=0) / wsum
    sigma = np.sqrt(np.where(finite, (w * stat) ** 2, 0.0).sum(axis=0)) / wsum
    comb_floor = np.where(finite, w * floor, 0.0).sum(axis=0) / wsum
    if len(parts) > 1:  # Birge ratio over the periods that measured
        chi2 = np.where(finite, w * (shift - mean) ** 2, 0.0).sum(axis=0)
        dof = np.maximum(finite.sum(axis=0) - 1, 1)
        sigma = sigma * np.sqrt(np.maximum(1.0, chi2 / dof))
    sigma = sigma + out_sigma
    amplitude = np.max(np.stack([p.amplitude for p in parts]), axis=0)
    named = {f"along_row_period_{p.period:g}": p for p in parts}
    return CellShifts(mean, sigma, amplitude, parts[0].period, named), comb_floor


def route_shifts(along_row: CellShifts, along_column: CellShifts, slant: float) -> CellShifts:
    """The shifts across the lenses (what routing needs, subpixels) from the shifts along the row
    (subpixels, the ``cell`` photos) and along the column (rows, the ``celly`` photos):
    ``r = r_x - 3 C_r dy`` (a point ``dy`` rows lower lies on the lens line ``3 C_r dy``
    subpixels further right), with the two sigmas combined."""
    shift = along_row.shift - 3.0 * slant * along_column.shift
    sigma = np.hypot(along_row.sigma, 3.0 * abs(slant) * along_column.sigma)
    parts = {"along_row": along_row, "along_column_rows": along_column}  # along_row holds each period
    return CellShifts(shift, sigma, np.minimum(along_row.amplitude, along_column.amplitude), along_row.period, parts)


@dataclasses.dataclass
class LayoutDecision:
    """What the cell photos say: ``order`` ("RGB" or "BGR") and ``layout`` (None for a stripe), the
    measured ``shifts``, each cell's shift (in the layout's gauge) and 1-sigma
    (``cell_shift``/``cell_sigma``, ``(cells, 3)`` subpixels), the 4 x 2 ``class_cells`` table and
    ``problem`` (a sentence) when it cannot tell."""

    order: str
    layout: SubpixelLayout | None
    shifts: CellShifts
    cell_shift: np.ndarray
    cell_sigma: np.ndarray
    class_cells: list
    problem: str | None = None

    views_per_subpixel: float = 0.0
    gauge: float = 0.0  # subpixels added to every measured shift (and to the offset) for the layout written

    def to_dict(self) -> dict:
        out = {"result": "stripe " + self.order if self.layout is None else "cells",
               "sigma_views_worst": round(float(np.max(self.cell_sigma)) * self.views_per_subpixel, 4),
               "measured": self.shifts.to_dict(),
               "cell_of_class": self.class_cells,
               "cell_shift_subpixels": np.round(self.cell_shift, 4).tolist(),
               "gauge_subpixels": round(self.gauge, 4),
               "cell_sigma_subpixels": np.round(self.cell_sigma, 4).tolist(),
               "note": "only the component across the lenses is measurable: dy = 0, dx carries it"}
        if self.layout is not None:
            out["layout"] = self.layout.to_dict()
            out["dx_sigma_pixels"] = np.round(self.cell_sigma / 3.0, 4).tolist()
        if self.problem:
            out["problem"] = self.problem
        return out


def block_phases(luma: np.ndarray, predicted_cycles: np.ndarray, valid: np.ndarray,
                 block: int = BLOCK) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per block, the complex fringe amplitude ``m / A`` of ``luma ~ A + Re(m exp(2 pi i predicted))``.

    RETURNED VALUE
    ``(q, row, col)``: complex (blocks,), and each block's centre (working pixels), for the blocks
    at least half covered by ``valid`` with ``A > 0``.
    """
    h, w = luma.shape
    rows, cols = np.nonzero(valid)
    nbx = (w + block - 1) // block
    index = (rows // block) * nbx + cols // block
    nb = ((h + block - 1) // block) * nbx
    ph = 2 * math.pi * predicted_cycles[rows, cols]
    basis = (np.ones_like(ph), np.cos(ph), np.sin(ph))
    val = luma[rows, cols].astype(np.float64)
    gram = np.empty((nb, 3, 3))
    rhs = np.empty((nb, 3))
    for i in range(3):
        rhs[:, i] = np.bincount(index, weights=basis[i] * val, minlength=nb)
        for j in range(i, 3):
            gram[:, i, j] = gram[:, j, i] = np.bincount(index, weights=basis[i] * basis[j], minlength=nb)
    full = np.nonzero(gram[:, 0, 0] >= block * block // 2)[0]
    coef = np.linalg.solve(gram[full] + 1e-9 * np.eye(3), rhs[full][:, :, None])[:, :, 0]
    good = coef[:, 0] > 0
    coef, full = coef[good], full[good]
    q = (coef[:, 1] - 1j * coef[:, 2]) / coef[:, 0]
    return q, (full // nbx + 0.5) * block, (full % nbx + 0.5) * block


def phase_offset(q: np.ndarray, row: np.ndarray, col: np.ndarray, shape: tuple[int, int],
                 tiles: tuple[int, int] = TILES) -> tuple[float, float, float]:
    """``(offset, sigma, amplitude)``: the phase (cycles) of the summed block amplitudes, its 1-sigma
    by a delete-one-tile jackknife over ``tiles`` tiles of the image, and the mean ``|m / A|``."""
    total = q.sum()
    offset = math.atan2(total.imag, total.real) / (2 * math.pi)
    tile = (np.clip((row / shape[0] * tiles[1]).astype(int), 0, tiles[1] - 1) * tiles[0]
            + np.clip((col / shape[1] * tiles[0]).astype(int), 0, tiles[0] - 1))
    sums = np.bincount(tile, weights=q.real, minlength=tiles[0] * tiles[1]) \
        + 1j * np.bincount(tile, weights=q.imag, minlength=tiles[0] * tiles[1])
    used = np.bincount(tile, minlength=tiles[0] * tiles[1]) > 0
    leave = [total - s for s, u in zip(sums, used) if u]
    m = len(leave)
    if m < 3:
        return offset, math.inf, float(np.abs(total) / max(q.size, 1))
    est = np.array([math.atan2(v.imag, v.real) / (2 * math.pi) for v in leave])
    d = (est - offset + 0.5) % 1.0 - 0.5
    sigma = math.sqrt((m - 1) / m * float(np.sum((d - d.mean()) ** 2)))
    return offset, sigma, float(np.abs(total) / q.size)


def shifts_from_offsets(offset: np.ndarray, sigma: np.ndarray, amplitude: np.ndarray, period: float) -> CellShifts:
    """:class:`CellShifts` from the phase offsets (cycles, ``(classes, 3)``) of the cell photos:
    ``r = -T (offset - reference)``, the reference the circular mean of the green offsets."""
    usable = np.isfinite(sigma[:, 1])  # a green photo without fringes (sigma inf) is no reference
    green = offset[usable, 1]
    if green.size == 0:
        return CellShifts(np.zeros(offset.shape), np.full(offset.shape, np.inf), amplitude, period)
    ref = math.atan2(np.sin(2 * np.pi * green).mean(), np.cos(2 * np.pi * green).mean()) / (2 * math.pi)
    d = (offset - ref + 0.5) % 1.0 - 0.5
    shift = -period * d
    # the reference's own error: the mean of the green sigmas over the classes, in every shift
    ref_var = float(np.sum(sigma[usable, 1] ** 2)) / green.size ** 2
    return CellShifts(shift, period * np.sqrt(sigma ** 2 + ref_var), amplitude, period)


def _agree(a, sa, b, sb) -> bool:
    return bool(np.all(np.abs(a - b) <= np.maximum(AGREE_SIGMAS * np.sqrt(sa ** 2 + sb ** 2), AGREE_FLOOR)))


def _compress(table: list[list[int]]) -> tuple[tuple[int, ...], ...]:
    """The smallest periodic table (1, 2 or 4 rows; 1 or 2 columns) equal to the 4 x 2 ``table``."""
    rows = next(r for r in (1, 2, 4) if all(table[y] == table[y % r] for y in range(CELL_ROWS)))
    cols = 1 if all(row[0] == row[1] for row in table) else CELL_COLUMNS
    return tuple(tuple(table[y][x] for x in range(cols)) for y in range(rows))


def decide_layout(shifts: CellShifts, views_per_subpixel: float, floor=SHIFT_FLOOR) -> LayoutDecision:
    """The stripe or the cell layout the shifts show (module docstring).

    ``views_per_subpixel``: ``N / Delta_r``, to judge the shifts' uncertainty in views;
    ``floor``: the systematic 1-sigma of a cell's shift (:func:`shift_floor`), subpixels: one
    number, or per class and channel ``(CELL_CLASSES, 3)`` (:func:`combine_periods`).
    """
    r, s = shifts.shift, shifts.sigma
    floor = np.broadcast_to(np.asarray(floor, dtype=np.float64), r.shape)
    worst = float(np.max(s)) * views_per_subpixel
    sa = np.hypot(s, floor)  # agreement is judged with the systematic floor too

    def merged(members):
        """(mean, 1-sigma with the floor) of some classes' shifts, (3,) each."""
        mean, sig = _weighted_mean(r[members], s[members])
        return mean, np.hypot(sig, floor[members].mean(axis=0))

    for order, stripe in STRIPE_SHIFTS.items():
        if _agree(r, sa, np.array(stripe)[None, :], 0.0):
            mean, sig = merged(list(range(CELL_CLASSES)))
            table = [[0] * CELL_COLUMNS for _ in range(CELL_ROWS)]
            decision = LayoutDecision(order, None, shifts, mean[None, :], sig[None, :], table,
                                      views_per_subpixel=views_per_subpixel)
            if worst > MAX_SHIFT_SIGMA_VIEWS:
                decision.problem = (f"the cell photos' shifts are known only to {worst:.2f} views (limit "
                                    f"{MAX_SHIFT_SIGMA_VIEWS})")
            return decision
    cells: list[list[int]] = []  # classes per cell
    for k in range(CELL_CLASSES):
        for members in cells:
            m, _ = _weighted_mean(r[members], s[members])
            if _agree(r[k], sa[k], m, 0.0):
                members.append(k)
                break
        else:
            cells.append([k])
    problem = None
    if worst > MAX_SHIFT_SIGMA_VIEWS:
        problem = (f"the subpixel layout is not resolved: a channel's shift is known only to {worst:.2f} views "
                   f"(limit {MAX_SHIFT_SIGMA_VIEWS})")
    else:
        for members in cells:
            m, _ = _weighted_mean(r[members], s[members])
            if not all(_agree(r[k], sa[k], m, 0.0) for k in members):
                problem = "the cell classes' shifts are inconsistent (a class agrees with no cell)"
    class_cell = {k: i for i, members in enumerate(cells) for k in members}
    table = [[class_cell[2 * y + x] for x in range(CELL_COLUMNS)] for y in range(CELL_ROWS)]
    means = [merged(members) for members in cells]
    cell_shift = np.array([m for m, _ in means])
    cell_sigma = np.array([ms for _, ms in means])
    # The gauge of the layout written: every slot's shift moved by the same ``gauge`` so that the
    # channel centres average to the pixel centre over the panel (mean dx 0, as in a stripe), and
    # the offset moved by as much (:func:`regauged_offset`), which routes every slot as before.
    gauge = -float(np.mean([cell_shift[class_cell[k]] for k in range(CELL_CLASSES)]))
    cell_shift = cell_shift + gauge
    pairs = tuple(tuple((float((cell_shift[i, c] - 1 + c) / 3.0), 0.0) for c in range(3)) for i in range(len(cells)))
    layout = SubpixelLayout(cells=pairs, pattern=_compress(table))
    return LayoutDecision("RGB", layout, shifts, cell_shift, cell_sigma, table, problem, views_per_subpixel, gauge)


def regauged_offset(offset: float, period: float, decision: LayoutDecision) -> float:
    """The profile offset (subpixels) that goes with the decision's layout: ``offset + gauge``
    reduced into ``[0, period)`` (a common shift ``e -> e + g`` of every slot routes like
    ``s_ref -> s_ref - g``, so the two together leave every slot's ``w`` unchanged)."""
    value = math.fmod(offset + decision.gauge, period)
    return value + period if value < 0 else value


def _weighted_mean(r: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse-variance mean over the first axis of ``(n, 3)`` shifts and its 1-sigma ``(3,)``."""
    r, s = np.atleast_2d(r), np.atleast_2d(s)
    w = 1.0 / np.maximum(s, 1e-6) ** 2
    return (w * r).sum(axis=0) / w.sum(axis=0), 1.0 / np.sqrt(w.sum(axis=0))


def describe(decision: LayoutDecision) -> str:
    """One line for the fit's output: the layout found and its uncertainty."""
    if decision.layout is None:
        return f"stripe {decision.order} (every cell class agrees with it)"
    parts = []
    for i, cell in enumerate(decision.layout.cells):
        chans = ", ".join(f"{name} {dx:+.3f}+-{decision.cell_sigma[i, c] / 3:.3f}"
                          for c, (name, (dx, _)) in enumerate(zip(CHANNELS, cell)))
        parts.append(f"cell {i}: {chans}")
    rows = "/".join("".join(str(c) for c in row) for row in decision.layout.pattern)
    return f"cells, pattern {rows} (rows from the top): " + "; ".join(parts) + " (dx pixels, dy 0)"


def refuse_if_unresolved(decision: LayoutDecision, source: str) -> None:
    """CalibrationError (one line) when the decision has a problem."""
    if decision.problem:
        raise CalibrationError(decision.problem, source=source,
                               hint="retake the cell photos in focus with the camera still, closer to the panel")


def class_shifts(profile) -> np.ndarray:
    """The slot shifts ``e`` (subpixels) a profile gives each cell class and channel, float64
    ``(CELL_CLASSES, 3)`` (R, G, B): zeros for RGB, ``(2, 0, -2)`` for BGR (the channels' slots
    relative to RGB's), the layout's :meth:`~lenticalib.core.layout.SubpixelLayout.slot_shifts`."""
    out = np.zeros((CELL_CLASSES, 3))
    layout = profile.subpixel_layout or stripe_layout(profile.subpixel_order)
    per_cell = [[float(e) for e in cell] for cell in layout.slot_shifts(profile.slant)]
    for k in range(CELL_CLASSES):
        out[k] = per_cell[int(layout.cell_of(k % CELL_COLUMNS, k // CELL_COLUMNS))]
    return out


def same_cells(a, b) -> bool:
    """Whether two profiles group the cell classes into cells alike (up to the cells' numbering; a
    stripe is one cell)."""
    def partition(profile):
        layout = profile.subpixel_layout
        if layout is None:
            return {frozenset(range(CELL_CLASSES))}
        cell = [int(layout.cell_of(k % CELL_COLUMNS, k // CELL_COLUMNS)) for k in range(CELL_CLASSES)]
        return {frozenset(k for k in range(CELL_CLASSES) if cell[k] == c) for c in set(cell)}

    return partition(a) == partition(b)


def shift_error(fitted, truth) -> float:
    """Largest error (subpixels) of ``fitted``'s slot shifts against ``truth``'s over every class and
    channel, in the layout's gauge (the mean green shift taken out of both: :mod:`.layout_fit`)."""
    d = class_shifts(fitted) - class_shifts(truth)
    return float(np.max(np.abs(d - d[:, 1].mean())))
