"""The calibration test patterns lenticalib draws, and what their manifest ``patterns.json`` says.

Every pattern is a phase-shifted sinusoid in *linear light* (sRGB-encoded into the PNG), a
function of one panel coordinate, evaluated at subpixel or row centres:

    axis "x":  L(x_s) = 0.5 + 0.45 cos(2 pi (x_s + 0.5) / T + theta)   T in subpixels
    axis "y":  L(y)   = 0.5 + 0.45 cos(2 pi (y + 0.5) / T + theta)     T in rows

with ``x_s = 3 x + position`` and ``position`` the subpixel slot (0, 1, 2) of the lit channel.

Why these patterns (the physics is in ``docs/optics.md``; the method in ``docs/calibration.md``):

* Through the lens sheet a camera sees, in every lens, one blurred point of the pixel plane.
  A sinusoid of long period ``T`` (much longer than a lens) is seen unchanged, only
  magnified, so the coarse groups ``x0 x1 x2`` and ``y0 y1`` measure, for every camera
  pixel, *which panel point it sees* (multi-frequency phase shifting, unwrapped coarse to
  fine; no camera model needed).
* The fine groups ``f16 f22`` (T = 16 and 22 subpixels, close to the lens period) are
  sampled by the lenses: what the camera sees is their alias, and the alias phase minus
  ``2 pi x / T`` is the view coordinate of the seen point (``psi`` in :mod:`.model`).
* The x- and y-patterns light only the green subpixel, which sits in the middle slot for
  both subpixel orders, so the coordinate they measure never depends on the order or on how
  the camera weighs red against blue; and every coordinate is measured in the same colour,
  so a camera's lateral chromatic aberration (red, green and blue imaged at slightly
  different magnifications) cannot put X and Y on different scales.
* ``order-r`` and ``order-b`` draw the fine sinusoid in red only and in blue only, at the
  slots red and blue have in RGB order; their phase against the fitted model tells
  whether red really is on the left.
* Every pattern has the same *registration frame*: the outer ``frame_width(height)`` pixels
  on all four sides are lit evenly (all subpixels at the mean level) in every pattern.  A
  tripod shakes by a fraction of a pixel between photos, and a tenth of a pixel between the
  coordinate and the fine photos moves the measured view coordinate by up to a view; the
  frame's outer edge looks the same in every photo, so each photo's shift is measured on it
  without bias (an edge lit by the photo's own fringe is weighted by that fringe) and undone
  (:mod:`.register`).  The fringes fill the panel inside the frame.

* With ``cells`` (``lenticalib patterns --cells``) 96 *cell patterns* follow: ``cell-<c><k>``
  draws the fine sinusoid of ``f16`` in channel ``c`` (r, g or b, at its RGB slot) only in the
  pixels of cell class ``k = 2 (y % 4) + x % 2``, ``celly-<c><k>`` a sinusoid of 16 rows
  along y the same way, and ``cellw-<c><k>`` and ``cellv-<c><k>`` the x sinusoid at 20 and 26
  subpixels (more periods, so that every lens period has one that neither is blind nor
  aliases too strongly: :data:`CELL_X_PERIODS`).  On a panel whose subpixels are not a stripe
  each channel of each cell sits elsewhere in the pixel; the phase of these photos against the
  fitted model measures where, along the row and along the column, and the lens routes by the
  combination across the lenses (:mod:`.layout_fit`).  Every cell pattern public calibrations
  use (1, 2 or 4 rows; 1 or 2 columns) is a function of the class.

23 photos in all (119 with the cell patterns).  Periods scale with the panel so any raster size
works; the fine periods cover lens periods Delta_r from 9.5 to 31 subpixels.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from ...core.colour import srgb_encode8
from ...core.files.documents import FORMATS, check_envelope
from ...core.errors import InputError
from ...core.pattern_sets import MANIFEST_NAME, manifest_matches, read_pattern_folder
from ...core.profile import MAX_VIEWS
from ...core.sizes import MAX_SIDE

DOCUMENT = FORMATS["lenticalib.patterns"]  # version 2: the registration frame
FORMAT_NAME, FORMAT_VERSION = DOCUMENT.name, DOCUMENT.version
MEAN_LEVEL = 0.5  # linear light
AMPLITUDE = 0.45  # linear light
FINE_PERIODS = (16.0, 22.0)  # subpixels
PERIOD_RANGE = (9.5, 31.0)  # lens periods Delta_r (subpixels) the fine groups measure (alias <= 0.42)
CHANNEL_SLOT_RGB = {"R": 0, "G": 1, "B": 2}
FRAME_FRACTION = 1.0 / 40.0  # registration frame width, of the panel height (pixels on every side)
FRAME_LEVEL = 0.3  # linear light, all three subpixels (their sum about the green fringe peak)
CELL_ROWS, CELL_COLUMNS = 4, 2  # cell classes: pixel (x, y) is of class 2 (y % 4) + x % 2
CELL_CLASSES = CELL_ROWS * CELL_COLUMNS
CELL_CLASS_RULE = "2 (y % 4) + x % 2"
# The cell patterns: "cell-<channel><class>", the fine sinusoid of period FINE_PERIODS[0] in one
# channel (at its RGB slot), lit only in the pixels of one class; one photo each.
CELL_GROUPS = tuple(f"cell-{c}{k}" for c in "rgb" for k in range(CELL_CLASSES))
# ... and "celly-<channel><class>": a sinusoid along y of CELL_Y_PERIOD rows, the same way: where
# each channel sits along the column (the x patterns see where it sits along the row; the lens
# routes by the combination across the lenses).
CELL_Y_GROUPS = tuple(f"celly-{c}{k}" for c in "rgb" for k in range(CELL_CLASSES))
CELL_Y_PERIOD = 16.0  # rows
# ... and "cellw-<channel><class>", "cellv-<channel><class>": the x patterns again at more
# periods.  A single-step photo carries a phase only where its alias fringe varies over the panel,
# and its errors grow with the alias |Delta_r / T - 1| (about 0.3 |alias| subpixel on a layout
# whose cells differ in dy), so the x photos at one period T are blind near Delta_r = T and off by
# 0.1-0.2 subpixel beyond an alias of about 0.35.  16 and 20 alone measured lens periods up to
# 22 subpixels; at 23.4 the 16-subpixel photos alias by 0.46 and the 20-subpixel ones are noisy
# (tools/bench_layouts.py).  26 measures there (alias -0.1) and is blind only beyond the lens
# periods random_scene draws (14 to 24); 16 and 26 alone were not enough at 23.4 (the two
# disagree by more than their floors, so the combined sigma reaches the limit), 16, 20 and 26 are
# (:func:`lenticalib.calib.routing.layout_fit.combine_periods`; measured range in docs/calibration.md).
CELL_X_PERIODS = (FINE_PERIODS[0], 20.0, 26.0)  # subpixels: CELL_GROUPS, CELL_WIDE_GROUPS, CELL_WIDER_GROUPS
CELL_WIDE_GROUPS = tuple(f"cellw-{c}{k}" for c in "rgb" for k in range(CELL_CLASSES))
CELL_WIDER_GROUPS = tuple(f"cellv-{c}{k}" for c in "rgb" for k in range(CELL_CLASSES))
CELL_X_GROUPS = dict(zip(CELL_X_PERIODS, (CELL_GROUPS, CELL_WIDE_GROUPS, CELL_WIDER_GROUPS)))
CELL_PERIOD_RANGE = (14.5, 23.5)  # lens periods Delta_r (subpixels) where the cell photos measured well


def frame_width(height: int) -> int:
    """Width in pixels of the evenly lit registration frame on every side of a panel ``height`` rows high."""
    return max(2, int(round(FRAME_FRACTION * height)))


@dataclasses.dataclass(frozen=True)
class Pattern:
    """One test image: a sinusoid along ``axis`` with ``period`` and phase step ``step`` of ``steps``.

    ``channels`` lists the lit channels ("G", "RGB", "R", "B"); for axis "x" each lit
    channel is evaluated at its RGB-order slot.  ``theta`` (radians) = 2 pi step / steps.
    ``cell_class``: the pattern lights only the pixels of that class (the cell patterns).
    """

    name: str
    group: str
    axis: str
    period: float
    step: int
    steps: int
    channels: str
    cell_class: int | None = None  # lit only in pixels of this class (:func:`cell_class_of`); None: all

    @property
    def file(self) -> str:
        return f"{self.name}.png"

    @property
    def theta(self) -> float:
        return 2.0 * math.pi * self.step / self.steps

    def to_dict(self) -> dict[str, Any]:
        data = dataclasses.asdict(self)
        if self.cell_class is None:  # the sets without cell patterns read (and hash) as before
            del data["cell_class"]
        data["file"] = self.file
        return data


@dataclasses.dataclass(frozen=True)
class PatternSet:
    """All patterns for one panel raster, with an id that changes when any of them changes."""

    width: int
    height: int
    views: int
    patterns: tuple[Pattern, ...]
    cells: bool = False  # with the cell patterns (:data:`CELL_GROUPS`)

    @property
    def set_id(self) -> str:
        body = json.dumps([self.width, self.height, self.views, FORMAT_VERSION,
                           [p.to_dict() for p in self.patterns]], sort_keys=True)
        return hashlib.sha256(body.encode()).hexdigest()[:16]

    def group(self, name: str) -> list[Pattern]:
        return [p for p in self.patterns if p.group == name]

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.patterns]

    def render(self, pattern: "Pattern") -> np.ndarray:
        """The pattern as the panel shows it (see :func:`render_pattern`)."""
        return render_pattern(pattern, self.width, self.height)

    def to_dict(self) -> dict[str, Any]:
        cells = {"cells": True, "cell_classes": CELL_CLASS_RULE} if self.cells else {}
        return {**DOCUMENT.envelope(), "set_id": self.set_id,
                "width": self.width, "height": self.height, "views": self.views, **cells,
                "period_range": list(PERIOD_RANGE), "mean_level": MEAN_LEVEL, "amplitude": AMPLITUDE,
                "frame_pixels": frame_width(self.height), "frame_level": FRAME_LEVEL,
                "encoding": "sRGB", "patterns": [p.to_dict() for p in self.patterns]}


def _group(name: str, axis: str, period: float, steps: int, channels: str) -> list[Pattern]:
    return [Pattern(f"{name}-{k}", name, axis, float(period), k, steps, channels) for k in range(steps)]


def cell_class_of(x, y):
    """The cell class of pixel ``(x, y)`` (ints or integer arrays, y from the top): ``2 (y % 4) + x % 2``,
    0..7.  Every cell pattern a layout can have (1, 2 or 4 rows; 1 or 2 columns) is a function of it."""
    return 2 * (y % CELL_ROWS) + x % CELL_COLUMNS


def design_patterns(width: int, height: int, views: int, cells: bool = False) -> PatternSet:
    """The pattern set for a ``width`` x ``height`` panel with ``views`` views.

    Coarse periods: 1.25 panel widths/heights (one unambiguous phase over the panel), then
    a twelfth of the width (a sixteenth of the height), then 96 subpixels (at most a third
    of a cycle per lens up to Delta_r = 32, so the lenses do not alias it).  ``cells``: also the
    96 cell patterns (:data:`CELL_GROUPS`, :data:`CELL_Y_GROUPS`, then the x patterns at the further
    periods of :data:`CELL_X_GROUPS`), for panels whose subpixels are not a stripe.
    """
    if not (isinstance(width, int) and isinstance(height, int) and width >= 64 and height >= 64):
        raise InputError(f"panel size {width}x{height} is too small", source="width/height",
                         hint="give the panel raster in pixels, at least 64x64")
    if not (isinstance(views, int) and 2 <= views <= 254):
        raise InputError(f"views must be an integer from 2 to 254, got {views}", source="views")
    sub = 3 * width
    t1 = sub / 12.0
    t2 = min(96.0, t1 / 2.0)
    patterns: list[Pattern] = []
    patterns += _group("x0", "x", 1.25 * sub, 3, "G")
    patterns += _group("x1", "x", t1, 3, "G")
    patterns += _group("x2", "x", t2, 3, "G")
    patterns += _group("y0", "y", 1.25 * height, 3, "G")
    patterns += _group("y1", "y", height / 16.0, 3, "G")
    for period in FINE_PERIODS:
        patterns += _group(f"f{period:g}", "x", period, 3, "G")
    patterns.append(Pattern("order-r", "order-r", "x", FINE_PERIODS[0], 0, 1, "R"))
    patterns.append(Pattern("order-b", "order-b", "x", FINE_PERIODS[0], 0, 1, "B"))
    if cells:
        for channel in "RGB":
            for k in range(CELL_CLASSES):
                name = f"cell-{channel.lower()}{k}"
                patterns.append(Pattern(name, name, "x", FINE_PERIODS[0], 0, 1, channel, k))
        for channel in "RGB":
            for k in range(CELL_CLASSES):
                name = f"celly-{channel.lower()}{k}"
                patterns.append(Pattern(name, name, "y", CELL_Y_PERIOD, 0, 1, channel, k))
        for period in CELL_X_PERIODS[1:]:
            for name in CELL_X_GROUPS[period]:
                patterns.append(Pattern(name, name, "x", period, 0, 1, name[-2].upper(), int(name[-1])))
    return PatternSet(width, height, views, tuple(patterns), cells=bool(cells))


def pattern_linear(pattern: Pattern, coordinate: np.ndarray) -> np.ndarray:
    """Linear light of ``pattern`` at panel coordinates (subpixel or row *indices*, any shape)."""
    phase = 2.0 * math.pi * (np.asarray(coordinate, dtype=np.float64) + 0.5) / pattern.period + pattern.theta
    return MEAN_LEVEL + AMPLITUDE * np.cos(phase)


def render_pattern(pattern: Pattern, width: int, height: int) -> np.ndarray:
    """The pattern as the panel shows it: uint8 RGB, shape (height, width, 3), registration frame included."""
    image = np.zeros((height, width, 3), dtype=np.uint8)
    for ci, channel in enumerate("RGB"):
        if channel not in pattern.channels:
            continue
        if pattern.axis == "x":
            coordinate = 3 * np.arange(width) + CHANNEL_SLOT_RGB[channel]
            values = srgb_encode8(pattern_linear(pattern, coordinate))
            image[:, :, ci] = values[None, :]
        else:
            values = srgb_encode8(pattern_linear(pattern, np.arange(height)))
            image[:, :, ci] = values[:, None]
        if pattern.cell_class is not None:
            lit = cell_class_of(np.arange(width)[None, :], np.arange(height)[:, None]) == pattern.cell_class
            image[:, :, ci] *= lit.astype(np.uint8)
    f = frame_width(height)
    frame = srgb_encode8(np.float64(FRAME_LEVEL))
    for part in (image[:f], image[-f:], image[:, :f], image[:, -f:]):
        part[...] = frame
    return image


def read_manifest(directory: str | os.PathLike) -> PatternSet:
    """The calibration pattern set described by ``DIR/patterns.json``; InputError naming the file if
    unusable (a crosstalk pattern folder included: see :func:`~lenticalib.core.pattern_sets.read_pattern_folder`)."""
    pattern_set = read_pattern_folder(directory)
    if not isinstance(pattern_set, PatternSet):
        raise InputError("holds crosstalk patterns, not calibration patterns", source=str(Path(directory) / MANIFEST_NAME),
                         hint="measure them with 'lenticalib crosstalk measure'; fit calibration patterns "
                              "written by 'lenticalib patterns'")
    return pattern_set


def pattern_set_from_manifest(data: dict[str, Any], source: str) -> PatternSet:
    """The calibration pattern set a parsed ``patterns.json`` of this format describes (the
    ``lenticalib.patterns`` kind of :mod:`lenticalib.core.pattern_sets`); InputError naming
    ``source`` when it is of another version or edited."""
    check_envelope(data, DOCUMENT, source)
    for key, low, high in (("width", 1, MAX_SIDE), ("height", 1, MAX_SIDE), ("views", 2, MAX_VIEWS)):
        value = data.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise InputError(f"field '{key}' is missing or not a whole number {low}..{high}", source=source,
                             hint="write the patterns again with 'lenticalib patterns'")
    cells = data.get("cells", False)
    if not isinstance(cells, bool):
        raise InputError("field 'cells' must be true or false", source=source,
                         hint="write the patterns again with 'lenticalib patterns'")
    try:
        expected = design_patterns(data["width"], data["height"], data["views"], cells=cells)
    except (TypeError, ValueError) as exc:
        raise InputError(f"describes no pattern set this lenticalib can draw ({exc})", source=source,
                         hint="write the patterns again with 'lenticalib patterns'") from None
    if not manifest_matches(data, expected):
        raise InputError("describes patterns this lenticalib did not draw (edited, or from another version)",
                         source=source, hint="write the patterns again with 'lenticalib patterns' and "
                                             "photograph them")
    return expected
