"""Reading a Looking Glass ``visual.json``: unwrap ``{"value": x}`` and validate every field.

The fields and what lenticalib makes of them: :mod:`lenticalib.core.looking_glass.convert` and docs/looking-glass.md.
"""

from __future__ import annotations

import math
import os
from typing import Any, Mapping

from ..files.documents import MAX_VISUAL_JSON_BYTES, read_json_file
from ..errors import ProfileError
from ..files.fields import is_finite_number, is_number, short_repr
from ..layout import LKG_CELL_PATTERNS, MAX_CELLS
from ..sizes import MAX_SIDE

REQUIRED_FIELDS = ("pitch", "slope", "center", "DPI", "screenW", "screenH")
FLAG_FIELDS = ("invView", "flipImageX", "flipImageY", "flipSubp")
NUMERIC_FIELDS = REQUIRED_FIELDS + ("viewCone", "verticalAngle", "fringe", "CellPatternMode") + FLAG_FIELDS
CELL_KEYS = ("ROffsetX", "ROffsetY", "GOffsetX", "GOffsetY", "BOffsetX", "BOffsetY")
# Fields that become the profile's routing (never stored as extras; recomputed on export).
ROUTING_FIELDS = ("pitch", "slope", "center", "screenW", "screenH", "CellPatternMode", "subpixelCells") + FLAG_FIELDS
DEFAULT_SOURCE = "visual.json"


# --------------------------------------------------------------------------------------------
# reading and validation


def _unwrap(value):
    """``{"value": x}`` -> ``x``; anything else unchanged."""
    if isinstance(value, dict) and len(value) == 1 and "value" in value:
        return value["value"]
    return value


def normalize_visual(raw: Any, source: str) -> dict[str, Any]:
    """Unwrap and validate a visual.json object (wrapped or already plain).

    Returns a new dict: required fields as float (``screenW``/``screenH`` as int), optional
    numeric fields as float, ``serial`` and ``configVersion`` as str, every other field unwrapped
    but otherwise as given.  ProfileError naming ``source`` (the file or the unit's URL) and the
    field for each problem; a value quoted in it is cut to a few dozen characters.
    """
    if not isinstance(raw, Mapping):
        raise ProfileError("must be a JSON object of calibration fields", source=source,
                           hint="a Looking Glass visual.json looks like {\"pitch\": {\"value\": 52.5}, ...}")
    out: dict[str, Any] = {}
    for key, value in raw.items():
        if not isinstance(key, str):
            raise ProfileError(f"field name {key!r} is not a string", source=source)
        out[key] = _unwrap(value)
    missing = [k for k in REQUIRED_FIELDS if k not in out]
    if missing:
        raise ProfileError(f"missing field(s): {', '.join(missing)}", source=source,
                           hint="a visual.json needs " + ", ".join(REQUIRED_FIELDS))
    for key in NUMERIC_FIELDS:
        if key not in out:
            continue
        value = out[key]
        if not is_number(value):
            raise ProfileError(f"field '{key}': must be a number (or {{\"value\": number}}), "
                               f"got {short_repr(raw[key], 48)}", source=source)
        if not is_finite_number(value):
            raise ProfileError(f"field '{key}': must be finite, got {short_repr(value)}", source=source)
        out[key] = float(value)
    if not out["DPI"] > 0:
        raise ProfileError(f"field 'DPI': must be > 0 pixels per inch, got {out['DPI']!r}",
                           source=source)
    if not out["pitch"] > 0:
        raise ProfileError(f"field 'pitch': must be > 0 lenticules per inch, got {out['pitch']!r}",
                           source=source)
    if out["slope"] == 0:
        raise ProfileError("field 'slope': must not be 0", source=source,
                           hint="slope is rows per lenticule shift; 0 is not a lens sheet")
    for key in ("screenW", "screenH"):
        value = out[key]
        if value != math.floor(value) or not 1 <= value <= MAX_SIDE:
            raise ProfileError(f"field '{key}': must be a whole number of pixels between 1 and "
                               f"{MAX_SIDE}, got {value!r}", source=source)
        out[key] = int(value)
    for key in ("serial", "configVersion"):
        if key in out and not isinstance(out[key], str):
            raise ProfileError(f"field '{key}': must be a string, got {short_repr(out[key])}", source=source)
    for key in FLAG_FIELDS:
        if key in out and out[key] not in (0.0, 1.0):
            raise ProfileError(f"field '{key}': must be 0 or 1, got {out[key]!r}", source=source)
    if "CellPatternMode" in out:
        mode = out["CellPatternMode"]
        if mode != math.floor(mode) or int(mode) not in LKG_CELL_PATTERNS:
            raise ProfileError(f"field 'CellPatternMode': {mode!r} is not a cell pattern lenticalib knows "
                               f"({', '.join(map(str, sorted(LKG_CELL_PATTERNS)))})", source=source,
                               hint="0 one cell, 1 checkerboard, 2 row % 4, 3 (row + 2 (column % 2)) % 4, "
                                    "4 column % 2")
        out["CellPatternMode"] = int(mode)
    if "subpixelCells" in out:
        out["subpixelCells"] = _cells(out["subpixelCells"], source)
    return out


def _cells(raw: Any, source: str) -> list[dict[str, float]]:
    """Validate ``subpixelCells``: a list of objects with the six offsets, in pixels."""
    if not isinstance(raw, list):
        raise ProfileError("field 'subpixelCells': must be a list of cells", source=source)
    if len(raw) > MAX_CELLS:
        raise ProfileError(f"field 'subpixelCells': {len(raw)} cells, at most {MAX_CELLS} are used by "
                           "Looking Glass software", source=source)
    cells = []
    for i, cell in enumerate(raw):
        if not isinstance(cell, Mapping):
            raise ProfileError(f"field 'subpixelCells[{i}]': must be an object with {', '.join(CELL_KEYS)}",
                               source=source)
        missing = [k for k in CELL_KEYS if k not in cell]
        if missing:
            raise ProfileError(f"field 'subpixelCells[{i}]': missing {', '.join(missing)}", source=source)
        entry = {}
        for key in CELL_KEYS:
            value = _unwrap(cell[key])
            if not is_finite_number(value):
                raise ProfileError(f"field 'subpixelCells[{i}].{key}': must be a finite number of pixels, "
                                   f"got {short_repr(value)}", source=source)
            entry[key] = float(value)
        cells.append(entry)
    return cells


def read_visual_json(path: str | os.PathLike) -> dict[str, Any]:
    """Read a Looking Glass ``visual.json`` and return its fields with the wrappers removed.

    ARGUMENTS
    ``path``: the file.

    RETURNED VALUE
    dict of plain values: ``pitch`` (lenticules per inch), ``slope``, ``center`` (lenticules),
    ``DPI`` (pixels per inch) as float; ``screenW``, ``screenH`` (pixels) as int; the optional
    numeric fields (``viewCone`` degrees, ``invView``, ``verticalAngle``, ``flipImageX/Y``,
    ``flipSubp``) as float when present; strings (``serial``, ``configVersion``) and unknown
    fields as found (unknown ``{"value": x}`` wrappers removed).

    Raises ProfileError naming the file (and the field) for a missing or unreadable file,
    invalid JSON, a missing required field, a non-numeric or non-finite number, DPI <= 0,
    pitch <= 0, slope == 0 or a screen size that is not a positive whole number.
    """
    src = str(path)
    raw = read_json_file(path, "visual.json", "give the path of the Looking Glass visual.json", ProfileError,
                         MAX_VISUAL_JSON_BYTES)
    return normalize_visual(raw, src)
