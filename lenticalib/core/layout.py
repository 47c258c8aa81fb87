"""Subpixel layouts: where each colour channel sits inside a pixel, per cell of a cell pattern.

A stripe panel (``subpixel_order`` ``"RGB"`` or ``"BGR"``) puts three vertical stripes side by
side; the profile needs no layout for it.  Other panels (Looking Glass units whose calibration has
``subpixelCells``) place each channel at its own position inside the pixel, and the position
depends on the pixel's *cell*: a small pattern of cells repeats over the raster.

THE LAYOUT (docs/profile-format.md, "Subpixel layouts")

    cells     one entry per cell: for R, G and B the channel's centre relative to the pixel
              centre, ``(dx, dy)`` in pixels, x to the right, **y down** (lenticalib's rows);
              the stripe RGB layout is R (-1/3, 0), G (0, 0), B (+1/3, 0).
    pattern   the cell of pixel ``(x, y)`` is ``pattern[y % rows][x % columns]``, ``y`` counted
              from the top row (1, 2 or 4 rows; 1 or 2 columns).

ROUTING (docs/optics.md).  The lenses see only the component of a position across the lens:
moving a subpixel down by ``dy`` rows changes ``w`` exactly as moving it ``-C_r dy`` pixels along
the row.  Channel ``c`` of pixel ``x`` therefore routes like a stripe subpixel at the continuous
index ``x_s = 3 x + c + e`` (left-edge convention, as the LentiAvatar rule evaluates ``x_s``)
with the *slot shift*

    e(cell, c) = 1 + 3 dx_c - 3 C_r dy_c - c         subpixels,

zero for every channel of the stripe RGB layout.  With a layout the profile's slots are the
channels (slot ``c`` of pixel ``x`` is channel ``c``: ``rho = (0, 1, 2)``), so every table indexed
``[y, 3 x + slot]`` keeps its shape; only the routing of a slot moves by ``e``.
"""

from __future__ import annotations

import dataclasses
from fractions import Fraction
from typing import Any, Mapping, Sequence

import numpy as np

from .errors import ProfileError
from .files.fields import is_finite_number, short_repr

CHANNELS = ("R", "G", "B")
MAX_CELLS = 16
MAX_OFFSET = 1.5  # pixels: a subpixel centre more than 1.5 pixels from its pixel's centre is no layout
PATTERN_ROWS = (1, 2, 4)
PATTERN_COLUMNS = (1, 2)

# The cell patterns Looking Glass calibrations name by ``CellPatternMode``, as Looking Glass's own
# shaders number them (``GetCellForPixel``, docs/looking-glass.md); their GL rows count from the
# bottom and these tables are in their row order, see :func:`pattern_for_mode`.
LKG_CELL_PATTERNS: dict[int, tuple[tuple[int, ...], ...]] = {
    0: ((0,),),                          # one cell everywhere
    1: ((0, 1), (1, 0)),                 # checkerboard
    2: ((0, 1),),                        # cell = column % 2 (alternating columns)
    3: ((0, 2), (1, 3), (2, 0), (3, 1)),  # cell = (row + 2 (column % 2)) % 4
    4: ((0,), (1,)),                     # cell = row % 2 (alternating rows)
}


@dataclasses.dataclass(frozen=True)
class SubpixelLayout:
    """Channel positions per cell and the cell pattern (module docstring).

    ``cells``: tuple of cells, each a tuple of three ``(dx, dy)`` pairs (R, G, B; pixels from the
    pixel centre, y down).  ``pattern``: tuple of rows of cell indices, ``pattern[y % rows][x %
    columns]``, y from the top.  Frozen and hashable: part of the profile's routing key.
    """

    cells: tuple[tuple[tuple[float, float], ...], ...]
    pattern: tuple[tuple[int, ...], ...] = ((0,),)

    def __post_init__(self):
        problem = layout_problem(self)
        if problem is not None:
            raise ProfileError(f"field 'subpixel_layout.{problem[0]}': {problem[1]}", source="profile")

    @property
    def pattern_rows(self) -> int:
        return len(self.pattern)

    @property
    def pattern_columns(self) -> int:
        return len(self.pattern[0])

    def cell_of(self, x, y):
        """Cell index of pixel ``(x, y)`` (ints or integer arrays; y from the top)."""
        table = np.asarray(self.pattern, dtype=np.int64)
        return table[np.asarray(y) % self.pattern_rows, np.asarray(x) % self.pattern_columns]

    def slot_shifts(self, slant: float) -> tuple[tuple[Fraction, Fraction, Fraction], ...]:
        """Exact slot shifts ``e(cell, c)`` in subpixels for a panel of slant ``C_r`` (pixels per row).

        One triple (R, G, B) per cell, as :class:`fractions.Fraction` of the float inputs, so that
        the fixed-point routing can round them once.
        """
        c_r = Fraction(slant)
        return tuple(tuple(1 + 3 * Fraction(dx) - 3 * c_r * Fraction(dy) - c for c, (dx, dy) in enumerate(cell))
                     for cell in self.cells)

    def per_slot(self, per_cell: Sequence[Sequence[Any]]) -> list[list[Any]]:
        """A per-cell triple (R, G, B) laid out over the pattern: rows ``[y % rows][3 (x % columns) + c]``."""
        return [[per_cell[cell][c] for cell in row for c in range(3)] for row in self.pattern]

    def slot_shift_table(self, slant: float) -> np.ndarray:
        """Slot shifts ``e`` in subpixels, float64 ``(rows, 3 * columns)`` indexed
        ``[y % rows, 3 (x % columns) + c]`` (:meth:`slot_shifts` laid out by :meth:`per_slot`)."""
        return np.array(self.per_slot([[float(e) for e in cell] for cell in self.slot_shifts(slant)]))

    def to_dict(self) -> dict[str, Any]:
        """The JSON form: ``{"cells": [{"R": [dx, dy], "G": [...], "B": [...]}, ...], "pattern": [[...]]}``."""
        return {"cells": [{name: [float(dx), float(dy)] for name, (dx, dy) in zip(CHANNELS, cell)}
                          for cell in self.cells],
                "pattern": [list(row) for row in self.pattern]}


def layout_problem(layout: SubpixelLayout) -> tuple[str, str] | None:
    """The first problem of ``layout`` as ``(field, message)`` (field relative to the layout), else None."""
    cells, pattern = layout.cells, layout.pattern
    if not isinstance(cells, tuple) or not 1 <= len(cells) <= MAX_CELLS:
        return "cells", f"must hold 1 to {MAX_CELLS} cells, got {short_repr(cells)}"
    for i, cell in enumerate(cells):
        if not isinstance(cell, tuple) or len(cell) != 3:
            return f"cells[{i}]", "must give R, G and B"
        for name, pair in zip(CHANNELS, cell):
            if not isinstance(pair, tuple) or len(pair) != 2:
                return f"cells[{i}].{name}", f"must be [dx, dy] in pixels, got {short_repr(pair)}"
            for axis, value in zip("xy", pair):
                if not is_finite_number(value):
                    return f"cells[{i}].{name}", f"d{axis} must be a finite number of pixels, got {short_repr(value)}"
                if abs(value) > MAX_OFFSET:
                    return f"cells[{i}].{name}", (f"d{axis} = {short_repr(value)} pixels is more than "
                                                  f"{MAX_OFFSET:g} pixels from the pixel centre")
    if not isinstance(pattern, tuple) or len(pattern) not in PATTERN_ROWS:
        return "pattern", f"must have {', '.join(map(str, PATTERN_ROWS))} rows, got {short_repr(pattern)}"
    widths = {len(row) if isinstance(row, tuple) else -1 for row in pattern}
    if len(widths) != 1 or widths.pop() not in PATTERN_COLUMNS:
        return "pattern", f"rows must all have 1 or 2 cell indices, got {short_repr(pattern)}"
    for row in pattern:
        for cell in row:
            if isinstance(cell, bool) or not isinstance(cell, int) or not 0 <= cell < len(cells):
                return "pattern", (f"cell index {short_repr(cell)} is not one of the {len(cells)} "
                                   f"cell{'' if len(cells) == 1 else 's'} (0 to {len(cells) - 1})")
    return None


def layout_from_dict(data: Any, source: str) -> SubpixelLayout:
    """Parse the JSON form (see :meth:`SubpixelLayout.to_dict`); ProfileError names ``source`` and field."""
    def fail(field, message, hint=None):
        raise ProfileError(f"field 'subpixel_layout{field}': {message}", source=source, hint=hint)

    if not isinstance(data, Mapping):
        fail("", "must be an object with 'cells' and 'pattern'")
    unknown = set(data) - {"cells", "pattern"}
    if unknown:
        fail("", f"unknown field(s) {', '.join(sorted(map(str, unknown)))}", "a layout has 'cells' and 'pattern'")
    raw_cells = data.get("cells")
    if not isinstance(raw_cells, list):
        fail(".cells", "must be a list of cells, each {\"R\": [dx, dy], \"G\": [dx, dy], \"B\": [dx, dy]}")
    cells = []
    for i, cell in enumerate(raw_cells):
        if not isinstance(cell, Mapping) or set(cell) != set(CHANNELS):
            fail(f".cells[{i}]", "must be {\"R\": [dx, dy], \"G\": [dx, dy], \"B\": [dx, dy]} (pixels, y down)")
        pairs = []
        for name in CHANNELS:
            pair = cell[name]
            if not isinstance(pair, list) or len(pair) != 2 or not all(is_finite_number(v) for v in pair):
                fail(f".cells[{i}].{name}", f"must be [dx, dy], two finite numbers of pixels, got {short_repr(pair)}")
            pairs.append((float(pair[0]), float(pair[1])))
        cells.append(tuple(pairs))
    raw_pattern = data.get("pattern", [[0]])
    if not isinstance(raw_pattern, list) or not all(isinstance(row, list) for row in raw_pattern):
        fail(".pattern", "must be a list of rows of cell indices, e.g. [[0, 1]]")
    try:
        return SubpixelLayout(cells=tuple(cells), pattern=tuple(tuple(row) for row in raw_pattern))
    except ProfileError as exc:  # the same message, naming the file
        raise ProfileError(exc.message, source=source, hint=exc.hint) from None


def pattern_for_mode(mode: int, cell_count: int, height: int) -> tuple[tuple[int, ...], ...]:
    """The top-down pattern table of Looking Glass ``CellPatternMode`` ``mode`` on a panel ``height`` rows tall.

    Their cell uses GL rows (``y_gl = H - 1 - y``) and is taken modulo the number of cells; the
    table returned is indexed by lenticalib's row ``y % rows``.  KeyError for an unknown mode.
    """
    gl = LKG_CELL_PATTERNS[mode]
    rows = len(gl)
    return tuple(tuple(cell % cell_count for cell in gl[(height - 1 - r) % rows]) for r in range(rows))


def mode_for_pattern(pattern: Sequence[Sequence[int]], cell_count: int, height: int) -> int | None:
    """The ``CellPatternMode`` whose table equals ``pattern`` on this panel, or None."""
    want = tuple(tuple(row) for row in pattern)
    for mode in sorted(LKG_CELL_PATTERNS):
        candidate = pattern_for_mode(mode, cell_count, height)
        if _same_pattern(candidate, want):
            return mode
    return None


def _same_pattern(a, b) -> bool:
    """Equal as periodic tables (a 1-row table equals a 2-row table with equal rows, and so on)."""
    rows = max(len(a), len(b))
    cols = max(len(a[0]), len(b[0]))
    return all(a[r % len(a)][c % len(a[0])] == b[r % len(b)][c % len(b[0])]
               for r in range(rows) for c in range(cols))


def stripe_layout(order: str) -> SubpixelLayout:
    """The stripe ``"RGB"`` or ``"BGR"`` layout written as one cell (for display and comparison)."""
    third = 1.0 / 3.0
    xs = (-third, 0.0, third) if order == "RGB" else (third, 0.0, -third)
    return SubpixelLayout(cells=(tuple((x, 0.0) for x in xs),))
