"""Subpixel layouts for the virtual panel: the stripes, named cell layouts and layout files.

A virtual panel is an RGB or BGR stripe (``PanelOptics.subpixel_order``) or carries a
:class:`~lenticalib.core.layout.SubpixelLayout` (``PanelOptics.subpixel_layout``): per cell, each
channel's centre ``(dx, dy)`` in pixels from the pixel centre (y down), and the cell pattern.

NAMED LAYOUTS (modelled on Looking Glass gen3 calibrations, ``subpixelCells`` with their y axis
turned down): R and G share one half of the pixel, one above the other, and B takes the other half.

    lkg-columns   two cells alternating by column (CellPatternMode 2):
                  cell 0  R (-0.25, +0.31)  G (-0.25, -0.28)  B (+0.25, 0)
                  cell 1  R (+0.25, +0.31)  G (+0.25, -0.28)  B (-0.25, 0)
    lkg-checker   the same two cells on a checkerboard (CellPatternMode 1)
    lkg-rows4     four cells by row (``y % 4``; no CellPatternMode of Looking Glass's draws it):
                  lkg-columns' two cells, each followed by a copy with R and G swapped vertically
"""

from __future__ import annotations

import os
from pathlib import Path

from ..core.files.documents import read_json_file
from ..core.errors import InputError, ProfileError
from ..core.layout import SubpixelLayout, layout_from_dict

STRIPES = ("RGB", "BGR")

_CELL0 = ((-0.25, 0.31), (-0.25, -0.28), (0.25, 0.0))
_CELL1 = ((0.25, 0.31), (0.25, -0.28), (-0.25, 0.0))
_CELL0_SWAPPED = ((-0.25, -0.28), (-0.25, 0.31), (0.25, 0.0))
_CELL1_SWAPPED = ((0.25, -0.28), (0.25, 0.31), (-0.25, 0.0))

NAMED_LAYOUTS: dict[str, SubpixelLayout] = {
    "lkg-columns": SubpixelLayout(cells=(_CELL0, _CELL1), pattern=((0, 1),)),
    "lkg-checker": SubpixelLayout(cells=(_CELL0, _CELL1), pattern=((0, 1), (1, 0))),
    "lkg-rows4": SubpixelLayout(cells=(_CELL0, _CELL0_SWAPPED, _CELL1, _CELL1_SWAPPED),
                                pattern=((0,), (1,), (2,), (3,))),
}
LAYOUT_CHOICES = STRIPES + tuple(NAMED_LAYOUTS)


def resolve_layout(text: str | os.PathLike, source: str = "layout") -> tuple[str, SubpixelLayout | None]:
    """``(order, layout)`` for a layout argument: ``"RGB"``/``"BGR"`` -> (that order, None); a name of
    :data:`NAMED_LAYOUTS` or a JSON layout file (``{"cells": [...], "pattern": [[...]]}``, or a
    profile holding ``subpixel_layout``) -> ("RGB", the layout).  InputError naming ``source``."""
    name = str(text)
    if name in STRIPES:
        return name, None
    if name in NAMED_LAYOUTS:
        return "RGB", NAMED_LAYOUTS[name]
    path = Path(name)
    if not path.suffix.lower() == ".json":
        raise InputError(f"unknown layout {name!r}", source=source,
                         hint=f"give one of {', '.join(LAYOUT_CHOICES)} or a JSON layout file")
    data = read_json_file(path, "layout", "give one of " + ", ".join(LAYOUT_CHOICES) + " or a JSON layout file")
    if isinstance(data, dict) and "subpixel_layout" in data and "cells" not in data:
        data = data["subpixel_layout"]
    try:
        return "RGB", layout_from_dict(data, str(path))
    except ProfileError as exc:
        raise InputError(exc.message, source=str(path), hint=exc.hint or "a layout is {\"cells\": [{\"R\": [dx, dy], "
                         "\"G\": [dx, dy], \"B\": [dx, dy]}, ...], \"pattern\": [[0, 1]]} (pixels, y down)") from None


def layout_label(order: str, layout: SubpixelLayout | None) -> str:
    """``"RGB"``, ``"BGR"``, the name of a named layout, or ``"custom"``."""
    if layout is None:
        return order
    for name, named in NAMED_LAYOUTS.items():
        if named == layout:
            return name
    return "custom"
