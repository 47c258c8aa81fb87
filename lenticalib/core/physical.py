"""The optional physical block of a profile: the panel as lenses and pixels in millimetres.

The routing constants of a profile are right for one eye position.  The physical block says what
they are made of, so that they can be recomputed for another eye (:mod:`lenticalib.core.retarget`):

    pixel_pitch_mm      p, the panel's (square) pixel pitch
    lens_pitch_mm       P_h, the horizontal lens pitch (along a panel row), mm
    gap_mm              g, the effective optical gap lens surface -> pixel plane (thickness /
                        refractive index)
    slant_angle_deg     phi = atan(C_r), the lens axes' angle from the panel's vertical
    lens_position_mm    x0 of the lens boundaries ``x = x0 + k P_h + y tan(phi)`` (panel-centred
                        frame below), reduced into [0, P_h)
    eye_mm              [x, y, D]: the eye (calibration camera) the profile's routing constants
                        are for; x right, y down from the panel centre, D its distance to the
                        lens surface
    design_distance_mm  the viewing distance the panel is made for (data sheet)
    view_cone_deg       the full horizontal view-cone angle in air (data sheet)
    source              where the numbers come from: "fit", "data sheet", ...
    uncertainty         {field: 1-sigma} for any of the numbers above (eye_mm: a 3-list)

Frame (docs/physical.md): world millimetres with the origin at the panel centre on the lens
surface, x right along rows, y down along columns, z into the screen; the pixel plane is at
z = +g; an eye at distance D sits at z = -D.  Only ``pixel_pitch_mm`` is required; every other
field is optional (a data sheet may give the gap or the cone angle only).
"""

from __future__ import annotations

import math
from typing import Any, Mapping

from .errors import ProfileError
from .files.fields import is_finite_number, unknown_key_message

NUMBER_FIELDS = ("pixel_pitch_mm", "lens_pitch_mm", "gap_mm", "slant_angle_deg", "lens_position_mm",
                 "design_distance_mm", "view_cone_deg")
POSITIVE_FIELDS = ("pixel_pitch_mm", "lens_pitch_mm", "gap_mm", "design_distance_mm")
FIELDS = NUMBER_FIELDS + ("eye_mm", "source", "uncertainty", "notes")
# Plausible ranges: a pixel pitch from a phone (0.03 mm) to a video wall (3 mm), gaps up to 50 mm.
LIMITS = {"pixel_pitch_mm": (0.005, 5.0), "lens_pitch_mm": (0.005, 50.0), "gap_mm": (1e-4, 50.0),
          "design_distance_mm": (10.0, 1e5), "view_cone_deg": (0.5, 170.0), "slant_angle_deg": (-60.0, 60.0),
          "lens_position_mm": (-1e4, 1e4)}


def validate_physical(data: Any, source: str = "profile") -> dict[str, Any]:
    """The checked physical block (a new dict); ProfileError naming ``physical.FIELD`` otherwise."""

    def fail(field, message, hint=None):
        raise ProfileError(f"field 'physical.{field}': {message}" if field else f"field 'physical': {message}",
                           source=source, hint=hint)

    if not isinstance(data, Mapping):
        fail(None, "must be a JSON object (pixel_pitch_mm, lens_pitch_mm, gap_mm, ...)")
    unknown = set(data) - set(FIELDS)
    if unknown:
        raise ProfileError(unknown_key_message([f"physical.{k}" for k in unknown], [f"physical.{k}" for k in FIELDS]),
                           source=source, hint="known: " + ", ".join(FIELDS))
    if "pixel_pitch_mm" not in data:
        fail("pixel_pitch_mm", "is missing", "give the panel's pixel pitch in mm (panel width / pixels)")
    out: dict[str, Any] = {}
    for key in NUMBER_FIELDS:
        if key not in data or data[key] is None:
            continue
        value = data[key]
        if not is_finite_number(value):
            fail(key, f"must be a finite number, got {value!r}")
        low, high = LIMITS[key]
        if not low <= value <= high:
            fail(key, f"{value!r} is outside {low:g}..{high:g}")
        out[key] = float(value)
    if data.get("eye_mm") is not None:
        eye = data["eye_mm"]
        if (not isinstance(eye, (list, tuple)) or len(eye) != 3
                or not all(is_finite_number(v) for v in eye)):
            fail("eye_mm", f"must be [x, y, D] in mm, got {eye!r}")
        if not eye[2] > 0:
            fail("eye_mm", f"the distance D must be > 0 mm, got {eye[2]!r}")
        out["eye_mm"] = [float(v) for v in eye]
    for key in ("source", "notes"):
        if data.get(key) is not None:
            if not isinstance(data[key], str):
                fail(key, "must be a string")
            out[key] = data[key]
    if data.get("uncertainty") is not None:
        unc = data["uncertainty"]
        if not isinstance(unc, Mapping):
            fail("uncertainty", "must be an object mapping a field to its 1-sigma")
        checked: dict[str, Any] = {}
        for key, value in unc.items():
            values = value if key == "eye_mm" else [value]
            if key not in NUMBER_FIELDS + ("eye_mm",) or not isinstance(values, (list, tuple)) \
                    or (key == "eye_mm" and len(values) != 3) \
                    or not all(is_finite_number(v) and v >= 0 for v in values):
                fail(f"uncertainty.{key}", f"must name a number field with a 1-sigma >= 0, got {value!r}")
            checked[key] = [float(v) for v in values] if key == "eye_mm" else float(value)
        out["uncertainty"] = checked
    return out


def gap_from_view_cone(lens_pitch_mm: float, slant_angle_deg: float, view_cone_deg: float) -> float:
    """g (mm) of a sheet whose full view cone in air is ``view_cone_deg``: ``P_u / (2 tan(cone/2))``.

    One lens pitch across the lenses, ``P_u = P_h cos(phi)``, seen from the pixel plane through the
    gap, spans the cone: a data-sheet cone angle and lens pitch give the gap.
    """
    p_u = lens_pitch_mm * math.cos(math.radians(slant_angle_deg))
    return p_u / (2.0 * math.tan(math.radians(view_cone_deg) / 2.0))


def view_cone_deg(lens_pitch_mm: float, slant_angle_deg: float, gap_mm: float) -> float:
    """The inverse of :func:`gap_from_view_cone`: the full view-cone angle (degrees) in air."""
    p_u = lens_pitch_mm * math.cos(math.radians(slant_angle_deg))
    return math.degrees(2.0 * math.atan(p_u / (2.0 * gap_mm)))


def with_data_sheet(block: Mapping[str, Any] | None, slant: float, source: str = "data sheet",
                    **given: float) -> dict[str, Any]:
    """A profile's physical ``block`` (or None) with the data-sheet values ``given`` (``pixel_pitch_mm``,
    ``gap_mm``, ``lens_pitch_mm``, ``view_cone_deg``, ``design_distance_mm``), checked.

    The gap follows from the view cone and the lens pitch when neither block nor ``given`` has it
    (``slant``: the profile's C_r, pixels per row); ``source`` says where the block came from
    ("data sheet", or "FIT + data sheet").  InputError when nothing is given, ProfileError naming
    ``physical.FIELD`` (in ``source``) when a value is out of range.
    """
    from .errors import InputError

    given = {k: v for k, v in given.items() if v is not None}
    if not given:
        raise InputError("nothing to set", source=source,
                         hint="give pixel_pitch_mm, gap_mm, lens_pitch_mm, view_cone_deg or design_distance_mm")
    out = dict(block or {})
    out.update(given)
    if "gap_mm" not in out and "view_cone_deg" in out and "lens_pitch_mm" in out:
        out["gap_mm"] = gap_from_view_cone(out["lens_pitch_mm"], math.degrees(math.atan(slant)), out["view_cone_deg"])
    out["source"] = "data sheet" if out.get("source") in (None, "data sheet") else f"{out['source']} + data sheet"
    return validate_physical(out, source)
