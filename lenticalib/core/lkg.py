"""Looking Glass ``visual.json`` calibration files: import to and export from panel profiles.

THE FILE
A JSON object in which every numeric field is wrapped as ``{"value": x}``:

    pitch        lenticules per inch, measured along the rows          (> 0)
    slope        rows per lenticule column shift; its sign is the lens direction   (!= 0)
    center       phase offset, in lenticules (only its value modulo 1 matters)
    viewCone     view cone in degrees (metadata for renderers)
    invView      1 on every shipping device (see below)
    DPI          panel pixels per inch                                  (> 0)
    screenW/H    panel raster in pixels
    flipImageX/Y 0 on every shipping device
    flipSubp     1 when the panel's subpixels are B, G, R from left to right
    serial, configVersion   plain strings

plus occasionally ``verticalAngle`` and other fields; those are kept, not interpreted.

THEIR RULE (the open-source shader ports), in GL frames: row ``y_gl`` counts from the bottom
(``y_gl = H - 1 - y`` for lenticalib's top-down row ``y``), the centre of pixel ``(x, y_gl)`` is
``uv = ((x + 0.5) / W, (y_gl + 0.5) / H)``, and for the subpixel at physical position ``c`` in
0..2 of that pixel

    P     = pitch * W / DPI * cos(atan(1 / slope))        lenticules across the panel width
    tilt  = H / (W * slope)
    subp  = 1 / (3 W)
    phase = (uv.x + c * subp + uv.y * tilt) * P - center
    view  = floor((1 - frac(phase)) * N)                  (invView = 1)

Quilt view 0 is the bottom-left tile, and their view index equals lenticalib's view index.
``flipSubp`` only decides which colour sits at position ``c`` (red is read from position 2 on
a BGR panel); the view of a *position* does not depend on it.

THE MAPPING TO THE ROUTING CONSTANTS (docs/profile-format.md)
With ``x_s = 3 x + c``:  ``phase = (x_s + 1.5 + 3 (H - 0.5 - y) / slope) / Delta - center`` where

    Delta = 3 W / P = 3 DPI / (pitch * cos(atan(1 / slope)))      subpixels.

Their view is ``floor(frac(-phase) N) = floor(-phase N) mod N`` (``1 - frac`` equals
``frac(-phase)`` except when ``frac(phase) == 0``, where they get view N, i.e. 0 mod N), and
lenticalib's is ``floor(w) mod N`` with ``w = i_ref + (3 C_r y + s_ref - x_s) N / Delta``.
Equating the two for every ``(x_s, y)``:

    C_r   = 1 / slope                                         pixels per row
    Delta = 3 DPI / (pitch * cos(atan(C_r)))                  subpixels
    i_ref + s_ref N / Delta = N center - (N / Delta)(1.5 + 3 (H - 0.5) C_r)

CONVENTION.  On import lenticalib sets ``i_ref = 0`` and

    s_ref = (Delta * center - 1.5 - 3 (H - 0.5) C_r)  reduced modulo Delta into [0, Delta)

(reducing by ``k Delta`` shifts ``w`` by ``k N``, so it shows the same views; the reduced value
is independent of which of the equivalent centres ``center + k`` the file holds).  On export
``center = i_ref / N + (s_ref + 1.5 + 3 (H - 0.5) C_r) / Delta``, reduced modulo 1 into [0, 1).

WHICH WAY THE VIEWS RUN (``view_direction``).  Along a row, ``phase`` grows with ``x_s``
(``P > 0``), so with ``invView = 1`` their view ``floor(frac(-phase) N)`` *falls* by ``N / Delta``
per subpixel to the right inside every lenticule -- exactly lenticalib's ``w``, which falls by
``N / Delta_r`` per subpixel (``Delta_r > 0``).  A lenticule focused on the pixel plane inverts:
an eye at ``u_E`` sees ``u_P = u_c + (u_c - u_E) g / D`` (docs/optics.md), so an eye moving right
(``u_E`` up) sees a point further left (``x_s`` down) under every lens, i.e. a *higher* view.
Hence ``invView = 1`` on an unmirrored panel means the view index grows as the viewer moves
right: ``view_direction = +1``, which is also what Looking Glass content assumes (quilt view 0
is the leftmost camera, so it must reach the leftmost eye for the depth to be right).  With
``invView = 0`` their view ``floor(frac(phase) N)`` would grow to the right across the
subpixels, equal to ``N - 1 - `` lenticalib's view (but for ties): the opposite direction,
which lenticalib's rule (``Delta_r > 0``, view index falling to the right) cannot express with
their view numbering.  So import sets ``view_direction = +1``; export writes ``invView = 1``
for ``+1`` (and for an unknown direction, the value every shipping device has; the CLI warns)
and refuses a profile with ``view_direction = -1``.

LIMITS.  lenticalib models only ``invView = 1`` with unflipped images (every shipping device);
other files are refused.  Vertical lenses (``C_r = 0``) have no ``slope`` and cannot be exported.
When ``Delta > N`` the LentiAvatar routing rule leaves the subpixels with ``frac(w) >= N / Delta`` dark, whereas
the Looking Glass shader shows ``floor(w) mod N`` there as well; on lit subpixels both agree.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .atomic import write_text_atomic
from .documents import read_json_file
from .errors import ProfileError
from .fields import is_finite_number, is_number, short_repr
from .profile import MAX_VIEWS, PanelProfile, make_provenance
from .sizes import MAX_SIDE

REQUIRED_FIELDS = ("pitch", "slope", "center", "DPI", "screenW", "screenH")
NUMERIC_FIELDS = REQUIRED_FIELDS + ("viewCone", "invView", "verticalAngle", "flipImageX",
                                    "flipImageY", "flipSubp")
# Fields that become the profile's routing constants (never stored as extras; recomputed on export).
ROUTING_FIELDS = ("pitch", "slope", "center", "screenW", "screenH", "flipSubp", "invView",
                  "flipImageX", "flipImageY")
# Order in which export writes the fields (the order Looking Glass software writes them).
_EXPORT_ORDER = ("configVersion", "serial", "pitch", "slope", "center", "viewCone", "invView",
                 "verticalAngle", "DPI", "screenW", "screenH", "flipImageX", "flipImageY",
                 "flipSubp")
DEFAULT_VIEW_CONE = 40.0
DEFAULT_SOURCE = "visual.json"


# --------------------------------------------------------------------------------------------
# reading and validation


def _unwrap(value):
    """``{"value": x}`` -> ``x``; anything else unchanged."""
    if isinstance(value, dict) and len(value) == 1 and "value" in value:
        return value["value"]
    return value


def _normalize(raw: Any, source: str) -> dict[str, Any]:
    """Unwrap and validate a visual.json object (wrapped or already plain).

    Returns a new dict: required fields as float (``screenW``/``screenH`` as int), optional
    numeric fields as float, every other field unwrapped but otherwise as given.
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
                               f"got {raw[key]!r}", source=source)
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
            raise ProfileError(f"field '{key}': must be a string, got {out[key]!r}", source=source)
    return out


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
    raw = read_json_file(path, "visual.json", "give the path of the Looking Glass visual.json", ProfileError)
    return _normalize(raw, src)


# --------------------------------------------------------------------------------------------
# visual.json -> profile


def routing_constants(visual: Mapping[str, Any], source: str = DEFAULT_SOURCE) -> dict[str, float]:
    """The routing constants of a visual.json under the module's convention.

    RETURNED VALUE
    ``{"slant": C_r (pixels per row), "period": Delta (subpixels), "offset": s_ref (subpixels,
    in [0, Delta)), "reference_view": i_ref (= 0.0)}``.  ``visual`` may be wrapped or plain.
    """
    v = _normalize(visual, source)
    slope, pitch, dpi, center, height = v["slope"], v["pitch"], v["DPI"], v["center"], v["screenH"]
    slant = 1.0 / slope
    period = 3.0 * dpi / (pitch * math.cos(math.atan(slant)))
    if not (math.isfinite(slant) and math.isfinite(period) and period > 0):
        raise ProfileError(f"pitch {pitch!r}, slope {slope!r}, DPI {dpi!r} give no usable lens "
                           f"period (slant {slant!r}, period {period!r} subpixels)", source=source)
    offset = period * center - 1.5 - 3.0 * (height - 0.5) * slant
    if not math.isfinite(offset):  # a centre near 1e308 overflows here; fmod would raise
        raise ProfileError(f"field 'center': gives a non-finite offset ({center!r})", source=source)
    offset = math.fmod(offset, period)  # exact
    if offset < 0.0:
        offset += period
        if offset >= period:  # a tiny negative remainder rounds up to period
            offset = 0.0
    return {"slant": slant, "period": period, "offset": offset, "reference_view": 0.0}


def profile_from_visual(visual: Mapping[str, Any], views: int, source: str = DEFAULT_SOURCE, *,
                        path: str | os.PathLike | None = None) -> PanelProfile:
    """A :class:`PanelProfile` that routes exactly as the Looking Glass shader does.

    ARGUMENTS
    ``visual``: the fields of a visual.json (as :func:`read_visual_json` returns them; the
    wrapped ``{"value": x}`` form is accepted too).  ``views``: N, the number of quilt views
    (2..254).  ``source``: names the file in error messages.  ``path``: the file it came from,
    recorded (with its SHA-256) in the provenance.

    RETURNED VALUE
    The profile: ``slant = 1 / slope`` (pixels per row), ``period = Delta`` (subpixels),
    ``reference_view = 0``, ``offset = s_ref`` in [0, Delta) (subpixels; see the module
    docstring), ``width``/``height`` = ``screenW``/``screenH``, ``subpixel_order`` ``"BGR"`` when
    ``flipSubp`` else ``"RGB"``, ``view_direction = +1`` (``invView = 1``: module docstring).
    ``looking_glass`` keeps ``DPI``, ``viewCone``, ``serial``,
    ``configVersion`` and every other field that is not a routing constant, so that
    :func:`visual_from_profile` can write them back.

    Raises ProfileError (naming ``source``) for invalid fields, ``invView != 1``, flipped images
    or an invalid ``views``.
    """
    if not isinstance(views, int) or isinstance(views, bool) or not 2 <= views <= MAX_VIEWS:
        raise ProfileError(f"views: must be a whole number between 2 and {MAX_VIEWS}, got {views!r}",
                           source=source, hint="give the number of views of the quilts (45 or 48 on a Portrait)")
    v = _normalize(visual, source)
    inv_view = v.get("invView", 1.0)
    if inv_view != 1.0:
        raise ProfileError(f"field 'invView': is {inv_view!r}; lenticalib supports only invView = 1 "
                           "(the view order of every shipping Looking Glass)", source=source,
                           hint="invView = 0 runs the views the other way, which lenticalib's routing rule "
                                "cannot express with the quilt's view numbers")
    for key in ("flipImageX", "flipImageY"):
        if v.get(key, 0.0) != 0.0:
            raise ProfileError(f"field '{key}': is {v[key]!r}; lenticalib supports only unflipped "
                               "panels (flipImageX = flipImageY = 0)", source=source)
    flip_subp = v.get("flipSubp", 0.0)
    if flip_subp not in (0.0, 1.0):
        raise ProfileError(f"field 'flipSubp': must be 0 or 1, got {flip_subp!r}", source=source)
    constants = routing_constants(v, source)
    extras = {k: val for k, val in v.items() if k not in ROUTING_FIELDS}
    provenance = make_provenance("import-lkg", inputs=[path] if path is not None else [],
                                 views=views,
                                 convention="i_ref = 0, s_ref reduced modulo Delta into [0, Delta)",
                                 view_direction={"value": 1, "method": "import-lkg",
                                                 "evidence": "invView = 1: the view index grows as the viewer "
                                                             "moves right (module docstring of lenticalib.core.lkg)"})
    try:
        return PanelProfile(views=views, width=v["screenW"], height=v["screenH"],
                            subpixel_order="BGR" if flip_subp else "RGB", view_direction=1,
                            looking_glass=extras, provenance=provenance, **constants)
    except ProfileError as exc:  # re-attribute to the visual.json
        raise ProfileError(exc.message, source=source, hint=exc.hint) from None


def import_visual_json(path: str | os.PathLike, views: int) -> PanelProfile:
    """Read ``path`` (a visual.json) and return its profile for ``views`` views.

    See :func:`read_visual_json` and :func:`profile_from_visual`.
    """
    return profile_from_visual(read_visual_json(path), views, source=str(path), path=path)


# --------------------------------------------------------------------------------------------
# profile -> visual.json


def _wrap(value):
    """Numbers (and booleans) are written as ``{"value": x}``; everything else as is."""
    if isinstance(value, (int, float)):
        return {"value": value}
    return value


def visual_from_profile(profile: PanelProfile, dpi: float | None = None) -> dict[str, Any]:
    """The visual.json of ``profile``, in the wrapped form, ready for ``json.dumps``.

    ARGUMENTS
    ``profile``: any valid profile with ``slant != 0``.  ``dpi``: panel pixels per inch; when
    ``None`` it is taken from ``profile.looking_glass["DPI"]``.

    RETURNED VALUE
    dict with ``pitch`` (lenticules per inch) ``= 3 DPI / (Delta cos(atan(C_r)))``,
    ``slope = 1 / C_r``, ``center`` in [0, 1) (module docstring), ``DPI``, ``screenW``,
    ``screenH``, ``flipSubp`` (1 for BGR), ``invView = 1``, ``flipImageX = flipImageY = 0``,
    ``viewCone`` (stored value, else 40 degrees), ``serial`` (stored value, else ``""``) and every
    other field stored in ``profile.looking_glass``.  Numeric fields are wrapped ``{"value": x}``.
    Re-importing it with the profile's ``views`` gives the same routing.

    Raises ProfileError when the slant is 0 (vertical lenses have no slope), no DPI is known, or
    ``profile.view_direction`` is -1 (only ``invView = 1``, direction +1, is modelled; module
    docstring).  An unknown direction is written as ``invView = 1``.
    """
    name = profile.name or "profile"
    extras = dict(profile.looking_glass or {})
    if profile.view_direction == -1:
        raise ProfileError("view_direction is -1 (the view index falls as the viewer moves right), which a "
                           "visual.json with invView = 1 cannot express", source=name,
                           hint="lenticalib writes only invView = 1, where the view index grows to the right; "
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
    slant, period, n = profile.slant, profile.period, profile.views
    slope = 1.0 / slant
    pitch = 3.0 * dpi / (period * math.cos(math.atan(slant)))
    center = profile.reference_view / n + (profile.offset + 1.5
                                           + 3.0 * (profile.height - 0.5) * slant) / period
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
        "invView": 1.0,
        "DPI": dpi,
        "screenW": float(profile.width),
        "screenH": float(profile.height),
        "flipImageX": 0.0,
        "flipImageY": 0.0,
        "flipSubp": 1.0 if profile.subpixel_order == "BGR" else 0.0,
    }
    for key, value in extras.items():
        if key not in fields and key not in ROUTING_FIELDS:
            fields[key] = value
    ordered = {k: fields[k] for k in _EXPORT_ORDER if k in fields}
    ordered.update((k, val) for k, val in fields.items() if k not in ordered)
    return {k: _wrap(val) for k, val in ordered.items()}


def export_visual_json(profile: PanelProfile, path: str | os.PathLike,
                       dpi: float | None = None) -> Path:
    """Write :func:`visual_from_profile` of ``profile`` to ``path`` atomically; returns the path."""
    text = json.dumps(visual_from_profile(profile, dpi=dpi), indent=4) + "\n"
    return write_text_atomic(path, text)


# --------------------------------------------------------------------------------------------
# the golden model: their rule, literally


def lkg_phase(visual: Mapping[str, Any]) -> np.ndarray:
    """Their per-subpixel ``phase``, float64, literally as the shader computes it.

    RETURNED VALUE
    float64 array ``(screenH, 3 * screenW)`` indexed ``[y, x_s]`` with ``y`` counted from the
    top (lenticalib's row) and ``x_s = 3 x + c`` (``c`` the physical position in the pixel):
    ``phase = (uv.x + c * subp + uv.y * tilt) * P - center`` in lenticules, with the GL row
    ``y_gl = H - 1 - y`` in ``uv.y``.  Not reduced.
    """
    v = _normalize(visual, DEFAULT_SOURCE)
    for key in ("flipImageX", "flipImageY"):
        if v.get(key, 0.0) != 0.0:
            raise ProfileError(f"field '{key}': flipped images are not modelled", source=DEFAULT_SOURCE)
    w, h = v["screenW"], v["screenH"]
    pitch, slope, center, dpi = v["pitch"], v["slope"], v["center"], v["DPI"]
    p = pitch * w / dpi * math.cos(math.atan(1.0 / slope))
    tilt = h / (w * slope)
    subp = 1.0 / (3.0 * w)
    x = np.arange(w, dtype=np.float64)
    y_gl = (h - 1) - np.arange(h, dtype=np.float64)
    uv_x = (x + 0.5) / w
    uv_y = (y_gl + 0.5) / h
    c = np.arange(3, dtype=np.float64)
    phase = ((uv_x[None, :, None] + c[None, None, :] * subp + uv_y[:, None, None] * tilt) * p
             - center)
    return phase.reshape(h, 3 * w)


def lkg_view_map(visual: Mapping[str, Any], views: int) -> np.ndarray:
    """View of every subpixel by the Looking Glass shader's rule: the independent golden model.

    ARGUMENTS
    ``visual``: visual.json fields (wrapped or plain).  ``views``: N.

    RETURNED VALUE
    int32 array ``(screenH, 3 * screenW)`` indexed ``[y, x_s]`` (``y`` from the top,
    ``x_s = 3 x + c`` with ``c`` the physical subpixel position), values in ``0..N``:
    ``floor(((1 - invView) frac(phase) + invView (1 - frac(phase))) * N)`` evaluated in float64
    (N occurs for invView = 1 on exact ties ``frac(phase) == 0``; it is view 0 modulo N).
    """
    v = _normalize(visual, DEFAULT_SOURCE)
    inv_view = v.get("invView", 1.0)
    phase = lkg_phase(v)
    frac = phase - np.floor(phase)
    z = (1.0 - inv_view) * frac + inv_view * (1.0 - frac)
    return np.floor(z * views).astype(np.int32)
