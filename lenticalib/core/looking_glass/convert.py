"""Looking Glass ``visual.json`` calibration files: import to and export from panel profiles.

THE FILE (docs/looking-glass.md).  A JSON object in which numeric fields are wrapped as
``{"value": x}``: ``pitch`` (lenticules per inch along the rows), ``slope`` (rows per lenticule
shift; its sign is the lens direction), ``center`` (phase, lenticules), ``viewCone`` (degrees),
``invView``, ``verticalAngle``, ``DPI``, ``screenW``/``screenH`` (pixels), ``flipImageX/Y``,
``flipSubp``, ``fringe``, ``serial`` and ``configVersion`` (strings), and in calibrations of
``configVersion`` 3.0 ``CellPatternMode`` and ``subpixelCells`` (per cell, ``ROffsetX``,
``ROffsetY``, ``GOffsetX``, ... in pixels from the pixel centre, **y up**).

THEIR RULE.  :mod:`lenticalib.core.looking_glass.vendor_rule` is our port of it (nearest view), the test oracle.
Per pixel ``(x, y_gl)`` (GL rows count from the bottom, ``y_gl = H - 1 - y``), with
``sigma = -1`` when ``flipImageX`` else ``+1``, ``C_r = sigma / slope`` and
``Delta = 3 W / P = 3 DPI / (pitch cos(atan(1 / slope)))`` subpixels, the phase of a colour is

    stripe:  phase = (3 x + c_pos + k0 + 3 (H - 0.5 - y) C_r) / Delta - center,
             c_pos = sigma * position (0, 1, 2; red reads position 2 when flipSubp), k0 = 1.5
    cells:   phase = (3 x + 3 dx + 3 C_r dy_up + 1.5 + 3 (H - 0.5 - y) C_r) / Delta - center

and the colour shows view ``floor((1 - frac(phase)) N)`` (``invView = 1``) or
``floor(frac(phase) N)`` (``invView = 0``).

THE MAPPING.  lenticalib's view is ``floor(w) mod N`` with
``w = i_ref + (3 C_r y + s_ref - x) N / Delta`` at the slot's continuous index ``x``, which equals
``-phase N`` (mod N) when

    C_r = sigma / slope,  Delta as above,  i_ref = 0,
    s_ref = Delta center - k0 - 3 (H - 0.5) C_r   reduced modulo Delta into [0, Delta)

with ``k0 = 1.5`` for a stripe and ``k0 = 0.5`` for cells (a layout slot's index is
``3 x + c + e`` with ``e = 1 + 3 dx - 3 C_r dy - c``, :mod:`lenticalib.core.layout`, one
subpixel more than their cell position).  A flipped stripe (``sigma = -1``) runs its positions
leftwards: position ``c`` sits at ``3 x - c``, which is a stripe of the opposite order shifted two
subpixels, so ``k0 = -0.5`` and the order is BGR (RGB with ``flipSubp``).  Cells map to a
:class:`~lenticalib.core.layout.SubpixelLayout` (``dy = -dy_up``; the pattern of
``CellPatternMode``, numbered as Looking Glass's own shaders number it -- 2 alternating columns,
4 alternating rows, not a third-party fork's ``y % 4`` and ``x % 2`` -- in lenticalib's top-down
rows).  ``invView = 0`` gives
``views_reversed``; ``flipImageX/Y`` also mirror the view images (``flip_image_x/y``).

WHICH WAY THE VIEWS RUN.  A lens focused on the pixel plane inverts, so on an unmirrored panel a
view index that falls to the right across the subpixels (``invView = 1``) grows as the viewer
moves right: ``view_direction = +1``, what Looking Glass content assumes (quilt view 0 is the
leftmost camera); ``invView = 0`` gives ``-1``.  Export writes ``invView`` from
``views_reversed`` and refuses a profile whose known direction disagrees with it.

LIMITS.  Refused, in one line naming the field: ``flipSubp`` together with ``subpixelCells``
(the cells already place each colour), a ``CellPatternMode`` outside 0..4, more than 16 cells,
vertical lenses (``C_r = 0``) on export, and a layout pattern no ``CellPatternMode`` draws.  When
``Delta > N`` the LentiAvatar rule leaves the subpixels with ``frac(w) >= N / Delta`` dark,
whereas their shader shows a view there too; on lit subpixels both agree.  A calibration without
``invView`` is read as ``invView = 1``, as Looking Glass Bridge's shader does (it has no such
input); the profile's provenance says so.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, Mapping

from ..files.atomic import write_text_atomic
from ..errors import ProfileError
from ..files.fields import is_finite_number
from ..layout import LKG_CELL_PATTERNS, SubpixelLayout, mode_for_pattern, pattern_for_mode
from .visual_file import (CELL_KEYS, DEFAULT_SOURCE, FLAG_FIELDS, NUMERIC_FIELDS, REQUIRED_FIELDS,
    ROUTING_FIELDS, normalize_visual, read_visual_json)
from ..profile import MAX_VIEWS, PanelProfile, make_provenance

__all__ = ["CELL_KEYS", "FLAG_FIELDS", "NUMERIC_FIELDS", "REQUIRED_FIELDS", "ROUTING_FIELDS", "read_visual_json",
           "normalize_visual",
           "routing_constants", "profile_from_visual", "import_visual_json", "visual_from_profile",
           "export_visual_json", "import_assumptions", "layout_of_visual", "has_cells"]

# Order in which export writes the fields (the order Looking Glass software writes them).
_EXPORT_ORDER = ("configVersion", "serial", "pitch", "slope", "center", "fringe", "viewCone", "invView",
                 "verticalAngle", "DPI", "screenW", "screenH", "flipImageX", "flipImageY",
                 "flipSubp", "CellPatternMode", "subpixelCells")
DEFAULT_VIEW_CONE = 40.0
CELLS_CONFIG_VERSION = "3.0"
STRIPE_K0, FLIPPED_STRIPE_K0, CELLS_K0 = 1.5, -0.5, 0.5


# --------------------------------------------------------------------------------------------
# visual.json <-> routing


def has_cells(visual: Mapping[str, Any]) -> bool:
    """True when a normalized visual.json routes by ``subpixelCells`` (their shader's test: any cells)."""
    return bool(visual.get("subpixelCells"))


def layout_of_visual(v: Mapping[str, Any]) -> SubpixelLayout:
    """The :class:`SubpixelLayout` of a normalized visual.json with cells (``dy`` turned to y down)."""
    cells = tuple(tuple((c[f"{ch}OffsetX"], -c[f"{ch}OffsetY"] + 0.0) for ch in "RGB") for c in v["subpixelCells"])
    mode = v.get("CellPatternMode", 0)
    return SubpixelLayout(cells=cells, pattern=pattern_for_mode(mode, len(cells), v["screenH"]))


def routing_constants(visual: Mapping[str, Any], source: str = DEFAULT_SOURCE) -> dict[str, Any]:
    """The routing fields of a visual.json under the module's mapping.

    RETURNED VALUE
    ``{"slant": C_r (pixels per row), "period": Delta (subpixels), "offset": s_ref (subpixels, in
    [0, Delta)), "reference_view": 0.0, "subpixel_order": "RGB" | "BGR", "subpixel_layout":
    SubpixelLayout | None, "views_reversed": bool, "flip_image_x": bool, "flip_image_y": bool}``.
    ``visual`` may be wrapped or plain.
    """
    v = normalize_visual(visual, source)
    slope, pitch, dpi, center, height = v["slope"], v["pitch"], v["DPI"], v["center"], v["screenH"]
    flip_x = v.get("flipImageX", 0.0) == 1.0
    sigma = -1.0 if flip_x else 1.0
    slant = sigma / slope
    period = 3.0 * dpi / (pitch * math.cos(math.atan(slant)))
    if not (math.isfinite(slant) and math.isfinite(period) and period > 0):
        raise ProfileError(f"pitch {pitch!r}, slope {slope!r}, DPI {dpi!r} give no usable lens "
                           f"period (slant {slant!r}, period {period!r} subpixels)", source=source)
    flip_subp = v.get("flipSubp", 0.0) == 1.0
    layout = None
    if has_cells(v):
        if flip_subp:
            raise ProfileError("field 'flipSubp': is 1 in a calibration with subpixelCells, whose offsets already "
                               "place each colour", source=source,
                               hint="lenticalib cannot tell which of the two the panel needs; set flipSubp to 0")
        try:
            layout = layout_of_visual(v)
        except ProfileError as exc:
            raise ProfileError(exc.message.replace("subpixel_layout.cells", "subpixelCells"), source=source,
                               hint=exc.hint) from None
        k0, order = CELLS_K0, "RGB"
    elif flip_x:
        k0, order = FLIPPED_STRIPE_K0, "RGB" if flip_subp else "BGR"
    else:
        k0, order = STRIPE_K0, "BGR" if flip_subp else "RGB"
    offset = period * center - k0 - 3.0 * (height - 0.5) * slant
    if not math.isfinite(offset):  # a centre near 1e308 overflows here; fmod would raise
        raise ProfileError(f"field 'center': gives a non-finite offset ({center!r})", source=source)
    offset = math.fmod(offset, period)  # exact
    if offset < 0.0:
        offset += period
        if offset >= period:  # a tiny negative remainder rounds up to period
            offset = 0.0
    return {"slant": slant, "period": period, "offset": offset, "reference_view": 0.0,
            "subpixel_order": order, "subpixel_layout": layout,
            "views_reversed": v.get("invView", 1.0) == 0.0, "flip_image_x": flip_x,
            "flip_image_y": v.get("flipImageY", 0.0) == 1.0}


def import_assumptions(visual: Mapping[str, Any]) -> list[str]:
    """What import had to assume about a normalized visual.json (shown to the user, kept in provenance)."""
    notes = []
    if "invView" not in visual:
        notes.append("the calibration has no invView: read as invView = 1, as Looking Glass Bridge's shader does")
    if has_cells(visual) and "CellPatternMode" not in visual:
        notes.append("the calibration has subpixelCells but no CellPatternMode: read as mode 0 (one cell)")
    return notes


def profile_from_visual(visual: Mapping[str, Any], views: int, source: str = DEFAULT_SOURCE, *,
                        path: str | os.PathLike | None = None) -> PanelProfile:
    """A :class:`PanelProfile` that routes exactly as the Looking Glass shader does.

    ARGUMENTS
    ``visual``: the fields of a visual.json (as :func:`read_visual_json` returns them; the
    wrapped ``{"value": x}`` form is accepted too).  ``views``: N, the number of quilt views
    (2..254).  ``source``: names the file in error messages.  ``path``: the file it came from,
    recorded (with its SHA-256) in the provenance.

    RETURNED VALUE
    The profile of :func:`routing_constants` with ``width``/``height`` = ``screenW``/``screenH``
    and ``view_direction`` +1 (``invView = 1``) or -1 (``invView = 0``); ``looking_glass`` keeps
    ``DPI``, ``viewCone``, ``serial``, ``configVersion``, ``fringe`` and every other field that
    is not routing, so that :func:`visual_from_profile` can write them back.  The provenance
    lists :func:`import_assumptions` under ``assumptions``.

    Raises ProfileError (naming ``source`` and the field) for invalid or unrepresentable fields
    (module docstring, LIMITS) or an invalid ``views``.
    """
    if not isinstance(views, int) or isinstance(views, bool) or not 2 <= views <= MAX_VIEWS:
        raise ProfileError(f"views: must be a whole number between 2 and {MAX_VIEWS}, got {views!r}",
                           source=source, hint="give the number of views of the quilts (45 or 48 on a Portrait)")
    v = normalize_visual(visual, source)
    routing = routing_constants(v, source)
    direction = -1 if routing["views_reversed"] else 1
    extras = {k: val for k, val in v.items() if k not in ROUTING_FIELDS}
    provenance = make_provenance("import-lkg", inputs=[path] if path is not None else [],
                                 views=views, assumptions=import_assumptions(v),
                                 convention="i_ref = 0, s_ref reduced modulo Delta into [0, Delta)",
                                 view_direction={"value": direction, "method": "import-lkg",
                                                 "evidence": f"invView = {1 if direction == 1 else 0}: the view index "
                                                             f"{'grows' if direction == 1 else 'falls'} as the viewer "
                                                             "moves right (module docstring of lenticalib.core.looking_glass.convert)"})
    try:
        return PanelProfile(views=views, width=v["screenW"], height=v["screenH"], view_direction=direction,
                            looking_glass=extras, provenance=provenance, **routing)
    except ProfileError as exc:  # re-attribute to the visual.json
        raise ProfileError(exc.message, source=source, hint=exc.hint) from None


def import_visual_json(path: str | os.PathLike, views: int) -> PanelProfile:
    """Read ``path`` (a visual.json) and return its profile for ``views`` views.

    See :func:`read_visual_json` and :func:`profile_from_visual`.
    """
    return profile_from_visual(read_visual_json(path), views, source=str(path), path=path)


def _wrap(value):
    """Numbers (and booleans) are written as ``{"value": x}``; everything else as is."""
    if isinstance(value, (int, float)):
        return {"value": value}
    return value


def _cells_of_layout(layout: SubpixelLayout) -> list[dict[str, float]]:
    return [{f"{ch}Offset{axis}": (dx if axis == "X" else -dy + 0.0)
             for ch, (dx, dy) in zip("RGB", cell) for axis in "XY"} for cell in layout.cells]


def visual_from_profile(profile: PanelProfile, dpi: float | None = None) -> dict[str, Any]:
    """The visual.json of ``profile``, in the wrapped form, ready for ``json.dumps``.

    ARGUMENTS
    ``profile``: any valid profile with ``slant != 0``.  ``dpi``: panel pixels per inch; when
    ``None`` it is taken from ``profile.looking_glass["DPI"]``.

    RETURNED VALUE
    dict with ``pitch`` (lenticules per inch) ``= 3 DPI / (Delta cos(atan(C_r)))``,
    ``slope = sigma / C_r``, ``center`` in [0, 1) (module docstring), ``DPI``, ``screenW``,
    ``screenH``, ``flipSubp``, ``invView`` (0 for ``views_reversed``), ``flipImageX/Y`` (the
    profile's image flips), ``CellPatternMode`` and ``subpixelCells`` (a layout; also written,
    empty, when the stored ``configVersion`` is 3 or later), ``viewCone`` (stored value, else 40
    degrees), ``serial`` (stored value, else ``""``) and every other field stored in
    ``profile.looking_glass``.  Numeric fields are wrapped ``{"value": x}``.  Re-importing it
    with the profile's ``views`` gives the same routing.

    Raises ProfileError naming the field when the profile cannot be written: slant 0, no DPI,
    a known ``view_direction`` that disagrees with ``views_reversed`` (module docstring), a
    layout pattern no ``CellPatternMode`` draws.
    """
    name = profile.name or "profile"
    extras = dict(profile.looking_glass or {})
    want = -1 if profile.views_reversed else 1
    if profile.view_direction is not None and profile.view_direction != want:
        raise ProfileError(f"view_direction is {profile.view_direction:+d} but a visual.json with "
                           f"invView = {0 if profile.views_reversed else 1} runs its views the other way",
                           source=name,
                           hint="Looking Glass content needs the view index to grow as the viewer moves right; "
                                "check the direction with 'lenticalib patterns --direction'")
    if profile.slant == 0:
        raise ProfileError("slant is 0 (vertical lenses), which a visual.json cannot express",
                           source=name, hint="Looking Glass panels always have slanted lenses")
    if dpi is None:
        if "DPI" not in extras:
            raise ProfileError("no DPI known for the visual.json", source=name,
                               hint="give the panel's pixels per inch with `dpi`")
        dpi, dpi_source = extras["DPI"], "looking_glass.DPI"
    else:
        dpi_source = "`dpi`"
    if not is_finite_number(dpi) or not dpi > 0:
        raise ProfileError(f"{dpi_source}: must be a finite number > 0 pixels per inch, got {dpi!r}",
                           source=name)
    dpi = float(dpi)
    sigma = -1.0 if profile.flip_image_x else 1.0
    layout = profile.subpixel_layout
    config_version = extras.get("configVersion")
    cell_fields: dict[str, Any] = {}
    if layout is not None:
        mode = mode_for_pattern(layout.pattern, len(layout.cells), profile.height)
        if mode is None:
            raise ProfileError(f"field 'subpixel_layout.pattern': {layout.pattern!r} is not drawn by any Looking "
                               f"Glass CellPatternMode on a {profile.height}-row panel", source=name,
                               hint="Looking Glass software knows modes " + ", ".join(map(str, sorted(LKG_CELL_PATTERNS))))
        k0, flip_subp = CELLS_K0, 0.0
        cell_fields = {"CellPatternMode": mode, "subpixelCells": _cells_of_layout(layout)}
        if not isinstance(config_version, str) or _major(config_version) < 3:
            config_version = CELLS_CONFIG_VERSION
    else:
        k0 = FLIPPED_STRIPE_K0 if profile.flip_image_x else STRIPE_K0
        bgr = profile.subpixel_order == "BGR"
        flip_subp = 1.0 if bgr != profile.flip_image_x else 0.0
        if isinstance(config_version, str) and _major(config_version) >= 3:
            cell_fields = {"CellPatternMode": 0, "subpixelCells": []}
    slant, period, n = profile.slant, profile.period, profile.views
    slope = sigma / slant
    pitch = 3.0 * dpi / (period * math.cos(math.atan(slant)))
    center = profile.reference_view / n + (profile.offset + k0 + 3.0 * (profile.height - 0.5) * slant) / period
    center = center - math.floor(center)
    if center >= 1.0:  # a tiny negative value rounds up to 1
        center = 0.0
    for key, value in (("slope", slope), ("pitch", pitch), ("center", center)):
        if not math.isfinite(value):
            raise ProfileError(f"cannot express the profile: {key} would be {value!r}", source=name)
    fields: dict[str, Any] = {
        "serial": extras.get("serial", ""),
        "pitch": pitch,
        "slope": slope,
        "center": center,
        "viewCone": extras.get("viewCone", DEFAULT_VIEW_CONE),
        "invView": 0.0 if profile.views_reversed else 1.0,
        "DPI": dpi,
        "screenW": float(profile.width),
        "screenH": float(profile.height),
        "flipImageX": 1.0 if profile.flip_image_x else 0.0,
        "flipImageY": 1.0 if profile.flip_image_y else 0.0,
        "flipSubp": flip_subp,
        **cell_fields,
    }
    if config_version is not None:
        fields["configVersion"] = config_version
    for key, value in extras.items():
        if key not in fields and key not in ROUTING_FIELDS:
            fields[key] = value
    ordered = {k: fields[k] for k in _EXPORT_ORDER if k in fields}
    ordered.update((k, val) for k, val in fields.items() if k not in ordered)
    return {k: _wrap(val) for k, val in ordered.items()}


def _major(version: str) -> int:
    """The major number of a ``configVersion`` string (``"3.0"`` -> 3; unreadable -> 0)."""
    head = version.strip().split(".")[0]
    return int(head) if head.isdigit() else 0


def export_visual_json(profile: PanelProfile, path: str | os.PathLike,
                       dpi: float | None = None) -> Path:
    """Write :func:`visual_from_profile` of ``profile`` to ``path`` atomically; returns the path."""
    text = json.dumps(visual_from_profile(profile, dpi=dpi), indent=4) + "\n"
    return write_text_atomic(path, text)
