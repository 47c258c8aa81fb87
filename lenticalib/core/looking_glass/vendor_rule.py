"""Our port of the Looking Glass lenticular rule (nearest view): the oracle for :mod:`lenticalib.core.looking_glass.convert`.

Written from Looking Glass's own public shader sources (Bridge's ``Lenticular_RGBA_With_Aspect``
as their Unity plugin and Looking-Glass/looking-glass-webxr carry it, and the older HoloPlay shader
for ``invView`` and ``flipSubp``; files and lines in docs/looking-glass.md), in float64, pixel by
pixel and independently of lenticalib's routing, so that import + encode can be checked against it.
tests/test_lkg_vendor_rule.py holds a second transcription, written apart from this one.

Per pixel: ``uv = ((x + 0.5) / W, (y_gl + 0.5) / H)`` with ``y_gl = H - 1 - y`` (GL rows from
the bottom), ``P = pitch W / DPI cos(atan(1 / slope))`` lenticules across the width,
``tilt = H / (W slope)`` and ``subp = 1 / (3 W)``, both negated when ``flipImageX``.

* no ``subpixelCells``: position ``c`` (0, 1, 2) has ``p_c = uv.x + c subp + uv.y tilt``; red
  reads position ``ri`` (2 when ``flipSubp`` else 0), green 1, blue ``bi`` (0 when ``flipSubp``
  else 2);
* cells: ``cell = pattern(x, y_gl) % cells`` (``CellPatternMode``: 0 one cell, 1 checkerboard,
  2 ``x % 2`` (alternating columns), 3 ``(y_gl + 2 (x % 2)) % 4``, 4 ``y_gl % 2`` (alternating
  rows); a third-party fork numbers 2 as ``y_gl % 4`` and 4 as ``x % 2``, Looking Glass does not)
  and colour ``k`` has
  ``p_k = uv.x + kOffsetX / W + (uv.y + kOffsetY / H) tilt``.

Then ``phase = p P - center`` and the colour shows view ``floor(z N)`` with
``z = 1 - frac(phase)`` (``invView = 1``, also when absent) or ``z = frac(phase)``
(``invView = 0``).  The shader clamps ``z`` into (0, 1); this port keeps the value N that an exact
tie ``frac(phase) = 0`` gives with ``invView = 1`` (it is view 0 modulo N) so ties stay visible.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from .visual_file import DEFAULT_SOURCE, normalize_visual


def _cell_index(mode: int, x: np.ndarray, y_gl: np.ndarray) -> np.ndarray:
    """Their ``GetCellForPixel`` before the modulo by the number of cells (``xPos = x``, ``yPos = y_gl``)."""
    if mode == 1:
        return np.where((y_gl % 2) == (x % 2), 0, 1)
    if mode == 2:
        return x % 2 + 0 * y_gl
    if mode == 3:
        return (y_gl + (x % 2) * 2) % 4
    if mode == 4:
        return y_gl % 2 + 0 * x
    return 0 * x + 0 * y_gl


def lkg_phase(visual: Mapping[str, Any]) -> np.ndarray:
    """Their ``phase`` of every colour, float64 ``(screenH, screenW, 3)`` indexed ``[y, x, channel]``.

    ``y`` counts from the top (lenticalib's row), channel 0, 1, 2 = R, G, B.  In lenticules, not
    reduced.
    """
    v = normalize_visual(visual, DEFAULT_SOURCE)
    w, h = v["screenW"], v["screenH"]
    pitch, slope, center, dpi = v["pitch"], v["slope"], v["center"], v["DPI"]
    sign = -1.0 if v.get("flipImageX", 0.0) == 1.0 else 1.0
    p = pitch * w / dpi * math.cos(math.atan(1.0 / slope))
    tilt = h / (w * slope) * sign
    subp = 1.0 / (3.0 * w) * sign
    x = np.arange(w)
    y_gl = (h - 1) - np.arange(h)
    uv_x = ((x + 0.5) / w)[None, :]
    uv_y = ((y_gl + 0.5) / h)[:, None]
    out = np.empty((h, w, 3))
    cells = v.get("subpixelCells") or []
    if not cells:
        flip = v.get("flipSubp", 0.0) == 1.0
        positions = (2, 1, 0) if flip else (0, 1, 2)  # position read by R, G, B
        for channel, c in enumerate(positions):
            out[:, :, channel] = (uv_x + c * subp + uv_y * tilt) * p - center
        return out
    cell = _cell_index(int(v.get("CellPatternMode", 0)), x[None, :], y_gl[:, None]) % len(cells)
    for channel, name in enumerate("RGB"):
        off_x = np.array([c[f"{name}OffsetX"] for c in cells])[cell]
        off_y = np.array([c[f"{name}OffsetY"] for c in cells])[cell]
        out[:, :, channel] = (uv_x + off_x / w + (uv_y + off_y / h) * tilt) * p - center
    return out


def lkg_view_map(visual: Mapping[str, Any], views: int) -> np.ndarray:
    """View of every colour by their rule: int32 ``(screenH, screenW, 3)`` ``[y, x, channel]``, values 0..N.

    ``floor(z N)`` with ``z = 1 - frac(phase)`` (``invView = 1`` or absent) or ``frac(phase)``
    (``invView = 0``), in float64; N occurs only on exact ties with ``invView = 1``.
    """
    v = normalize_visual(visual, DEFAULT_SOURCE)
    phase = lkg_phase(v)
    frac = phase - np.floor(phase)
    z = frac if v.get("invView", 1.0) == 0.0 else 1.0 - frac
    return np.floor(z * views).astype(np.int32)


def lkg_ties(visual: Mapping[str, Any], views: int, tolerance: float = 1e-6) -> np.ndarray:
    """Colours whose ``phase * N`` lies within ``tolerance`` of an integer: bool ``(H, W, 3)``.

    There float evaluations of the rule may legitimately pick either neighbouring view."""
    pn = lkg_phase(visual) * views
    return np.abs(pn - np.round(pn)) < tolerance
