"""Panel profiles: the routing constants of one slanted-lenticular panel, as JSON.

A profile holds the routing constants (see ``docs/optics.md``; format: ``docs/profile-format.md``):

    views            N, number of views (int, 2..254)
    slant            C_r, pixels per row (float; its sign is the lens direction)
    period           Delta_r, subpixels (float > 0)
    offset           s_ref, subpixels (float)
    reference_view   i_ref, views (float)
    width, height    panel raster in pixels (int)
    subpixel_order   "RGB" or "BGR": which colour sits at subpixel position 0, 1, 2

and, for panels that are not a plain RGB/BGR stripe or that Looking Glass software drives with
flips, the optional routing fields

    subpixel_layout  channel positions per cell and the cell pattern (:mod:`lenticalib.core.layout`);
                     with it the slots of a pixel are the channels R, G, B (subpixel_order "RGB")
    views_reversed   true: the view numbers run the other way, view ``N - 1 - v`` where the rule
                     gives ``v`` (Looking Glass ``invView = 0``; docs/profile-format.md)
    flip_image_x/y   true: every view image is shown mirrored left-right / top-bottom (Looking
                     Glass ``flipImageX`` / ``flipImageY``); sampling only, not routing

plus a format version, the optional ``physical`` block (lens pitch, gap, pixel pitch, the eye
the constants are for: :mod:`lenticalib.core.physical`), the optional ``view_direction`` (+1: the
view index grows as the viewer moves to the right; -1: it falls; absent: unknown), optional
1-sigma uncertainties, optional Looking Glass extras and a provenance record (how, when and from
which inputs it was made, with which lenticalib).

A hand-written file with only the eight constants loads as the current format.  Loading
parses JSON only: nothing in the file is ever executed.  Saving is atomic.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import hashlib
import json
import os
import sys
from pathlib import Path
from typing import Any, Mapping

from .files.atomic import write_text_atomic
from .files.documents import FORMATS, MAX_PROFILE_BYTES, check_envelope, read_json_file
from .errors import InputError, ProfileError
from .files.input_files import UNBOUNDED, open_input
from .files.fields import is_finite_number, is_number, short_repr, unknown_key_message
from .layout import SubpixelLayout, layout_from_dict
from .sizes import MAX_SIDE

DOCUMENT = FORMATS["lenticalib.profile"]
FORMAT_NAME = DOCUMENT.name
FORMAT_VERSION = DOCUMENT.version
MAX_VIEWS = 254  # view indices are stored as uint8 with 255 meaning "no view"

# Physical ranges of the constants, enforced for every profile (load, construction, device
# record).  Beyond them a profile describes no real lens sheet: a slant over 4 pixels/row is a
# lens lying almost flat; a period above 4096 subpixels or wider than a whole panel row
# (3 * width subpixels) is less than one lens across the panel, and the LentiAvatar routing rule then lights
# only a fraction N / period of the subpixels (period 1e9: an all-black raster); offsets and
# reference views beyond these bounds are far outside any reduction of them (s_ref is
# meaningful modulo the period, i_ref modulo N).
SLANT_LIMIT = 4.0            # |C_r| <= 4 pixels per row
PERIOD_LIMIT = 4096.0        # 0 < Delta_r <= 4096 subpixels, and Delta_r <= 3 * width
OFFSET_LIMIT = 1.0e6         # |s_ref| <= 1e6 subpixels
REFERENCE_VIEW_LIMIT = 65535.0  # |i_ref| <= 65535 views

SUBPIXEL_ORDERS = ("RGB", "BGR")
CONSTANT_KEYS = ("views", "slant", "period", "offset", "reference_view", "width", "height",
                 "subpixel_order")
ROUTING_OPTIONAL_KEYS = ("subpixel_layout", "views_reversed", "flip_image_x", "flip_image_y")
OPTIONAL_KEYS = ("format", "format_version", "view_direction", "uncertainty", "provenance", "looking_glass",
                 "name", "notes", "physical") + ROUTING_OPTIONAL_KEYS
VIEW_DIRECTIONS = (1, -1)


def subpixel_position(order: str) -> tuple[int, int, int]:
    """rho: position (0, 1, 2 within the pixel) of the colour channels R, G, B, for ``order``."""
    return (0, 1, 2) if order == "RGB" else (2, 1, 0)


@dataclasses.dataclass(frozen=True)
class PanelProfile:
    """The calibrated routing constants of one panel (units in the module docstring).

    Frozen and hashable on its routing fields, so derived tables can be cached per profile.
    ``uncertainty`` maps a constant's name to its 1-sigma; ``provenance`` and
    ``looking_glass`` are free-form JSON objects carried through load and save.

    ``view_direction`` is which way the view index runs for a viewer in front of the panel,
    facing it: +1 when it grows as the viewer moves to the right, -1 when it falls, None when
    unknown.  It does not change the routing (which subpixel shows which view index) and is not
    part of :meth:`routing_key` or of equality; a renderer needs it to draw view ``i`` from the
    right side (``-1`` reverses the camera order, unknown risks inverted depth).
    """

    views: int
    slant: float
    period: float
    offset: float
    reference_view: float
    width: int
    height: int
    subpixel_order: str = "RGB"
    uncertainty: Mapping[str, float] | None = dataclasses.field(default=None, compare=False, hash=False)
    provenance: Mapping[str, Any] | None = dataclasses.field(default=None, compare=False, hash=False)
    looking_glass: Mapping[str, Any] | None = dataclasses.field(default=None, compare=False, hash=False)
    name: str | None = dataclasses.field(default=None, compare=False, hash=False)
    view_direction: int | None = dataclasses.field(default=None, compare=False, hash=False)
    physical: Mapping[str, Any] | None = dataclasses.field(default=None, compare=False, hash=False)
    subpixel_layout: SubpixelLayout | None = None
    views_reversed: bool = False
    flip_image_x: bool = False
    flip_image_y: bool = False

    def __post_init__(self):
        _validate_constants({f.name: getattr(self, f.name) for f in dataclasses.fields(self)}, source="profile")

    @property
    def subpixels_per_row(self) -> int:
        """3 * width: number of subpixel columns x_s."""
        return 3 * self.width

    @property
    def rho(self) -> tuple[int, int, int]:
        """Slot (0, 1, 2 within the pixel) of the R, G, B channel (see :func:`subpixel_position`).

        With a :attr:`subpixel_layout` the slots are the channels: ``(0, 1, 2)``."""
        return subpixel_position(self.subpixel_order)

    @property
    def is_stripe(self) -> bool:
        """True for a plain RGB/BGR stripe panel: no cell layout (the slot shifts are all 0)."""
        return self.subpixel_layout is None

    @property
    def layout_name(self) -> str:
        """``"RGB"``, ``"BGR"`` or ``"cells (n cells, pattern RxC)"`` for messages and reports."""
        if self.subpixel_layout is None:
            return self.subpixel_order
        lay = self.subpixel_layout
        count = len(lay.cells)
        return f"cells ({count} cell{'' if count == 1 else 's'}, pattern {lay.pattern_rows}x{lay.pattern_columns})"

    def uses_version_2(self) -> bool:
        """True when the profile needs format version 2 (a layout, reversed views or flips).

        Profiles without them are written as version 1, so older lenticalib reads them."""
        return (self.subpixel_layout is not None or self.views_reversed or self.flip_image_x
                or self.flip_image_y)

    def routing_key(self) -> tuple:
        """The fields that decide routing and sampling; equal keys give identical encodings."""
        return (self.views, self.slant, self.period, self.offset, self.reference_view,
                self.width, self.height, self.subpixel_order, self.subpixel_layout,
                self.views_reversed, self.flip_image_x, self.flip_image_y)

    def replace(self, **changes) -> "PanelProfile":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping in the current format."""
        out: dict[str, Any] = DOCUMENT.envelope()
        if not self.uses_version_2():  # readable by every lenticalib since the format began
            out["format_version"] = 1
        if self.name:
            out["name"] = self.name
        for key in CONSTANT_KEYS:
            out[key] = getattr(self, key)
        if self.subpixel_layout is not None:
            out["subpixel_layout"] = self.subpixel_layout.to_dict()
        for key in ("views_reversed", "flip_image_x", "flip_image_y"):
            if getattr(self, key):
                out[key] = True
        if self.view_direction is not None:
            out["view_direction"] = self.view_direction
        if self.uncertainty:
            out["uncertainty"] = dict(self.uncertainty)
        if self.looking_glass:
            out["looking_glass"] = dict(self.looking_glass)
        if self.physical:
            out["physical"] = dict(self.physical)
        if self.provenance:
            out["provenance"] = dict(self.provenance)
        return out

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2) + "\n"


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def constants_problem(data: Mapping[str, Any]) -> tuple[str, str] | None:
    """The first of the eight constants outside its type or physical range, else None.

    Returns ``(field, message)``.  ``data`` maps the names of :data:`CONSTANT_KEYS` to values
    (units as in the module docstring).  The one definition of a valid profile: used by
    :func:`profile_from_dict`, :class:`PanelProfile` and the device record's range check.
    """
    for key in ("views", "width", "height"):
        if not _is_int(data[key]):
            return key, f"must be a whole number, got {short_repr(data[key])}"
    for key in ("slant", "period", "offset", "reference_view"):
        value = data[key]
        if not is_number(value):
            return key, f"must be a number, got {short_repr(value)}"
        if not is_finite_number(value):
            return key, f"must be finite, got {short_repr(value)}"
    if not 2 <= data["views"] <= MAX_VIEWS:
        return "views", f"must be between 2 and {MAX_VIEWS}, got {short_repr(data['views'])}"
    for key in ("width", "height"):
        if not 1 <= data[key] <= MAX_SIDE:
            return key, f"must be between 1 and {MAX_SIDE} pixels, got {short_repr(data[key])}"
    if data["subpixel_order"] not in SUBPIXEL_ORDERS:
        return "subpixel_order", f"must be \"RGB\" or \"BGR\", got {data['subpixel_order']!r}"
    if not abs(data["slant"]) <= SLANT_LIMIT:
        return "slant", f"must be within +-{SLANT_LIMIT:g} pixels/row, got {short_repr(data['slant'])}"
    period, row = data["period"], 3 * data["width"]
    if not period > 0:
        return "period", f"must be > 0 subpixels, got {short_repr(period)}"
    if period > PERIOD_LIMIT:
        return "period", f"must be at most {PERIOD_LIMIT:g} subpixels, got {short_repr(period)}"
    if period > row:
        return "period", (f"{short_repr(period)} subpixels is wider than the {data['width']}-pixel panel's row "
                          f"({row} subpixels)")
    if not abs(data["offset"]) <= OFFSET_LIMIT:
        return "offset", f"must be within +-{OFFSET_LIMIT:g} subpixels, got {short_repr(data['offset'])}"
    if not abs(data["reference_view"]) <= REFERENCE_VIEW_LIMIT:
        return "reference_view", (f"must be within +-{REFERENCE_VIEW_LIMIT:g} views, "
                                  f"got {short_repr(data['reference_view'])}")
    return None


def _validate_constants(data: Mapping[str, Any], source: str) -> None:
    """Check types and ranges of the eight constants; raise ProfileError naming the field."""

    def fail(field, message, hint=None):
        raise ProfileError(f"field '{field}': {message}", source=source, hint=hint)

    problem = constants_problem(data)
    if problem is not None:
        field = problem[0]
        hint = ("the period is the lens pitch in subpixels, about 3 * lens pitch / pixel pitch"
                if field == "period" else None)
        fail(*problem, hint)
    # The LentiAvatar routing rule lights view i on x_s when x_s <= b < x_s + min(1, period/N) for one of the
    # lattice points b = 3*C_r*y + s_ref + (i_ref - j)*period/N (j integer).  The lattice spacing
    # is period/N, so for any period > 0 at most one lattice point falls into that window: no
    # valid profile puts more than two views (in fact more than one) on a subpixel.  The
    # sampling-table builder still counts what it evaluates and rejects more than two.
    unc = data.get("uncertainty")
    if unc is not None:
        if not isinstance(unc, Mapping):
            fail("uncertainty", "must be an object mapping constant names to 1-sigma values")
        for key, value in unc.items():
            if not is_finite_number(value) or value < 0:
                fail(f"uncertainty.{key}", f"must be a finite number >= 0, got {short_repr(value)}")
    for key in ("provenance", "looking_glass"):
        if data.get(key) is not None and not isinstance(data[key], Mapping):
            fail(key, "must be a JSON object")
    if data.get("physical") is not None:
        from .physical import validate_physical

        validate_physical(data["physical"], source)
    layout = data.get("subpixel_layout")
    if layout is not None:
        if not isinstance(layout, SubpixelLayout):
            fail("subpixel_layout", "must be a SubpixelLayout")
        if data["subpixel_order"] != "RGB":
            fail("subpixel_order", f"must be \"RGB\" with a subpixel_layout (its slots are R, G, B), "
                                   f"got {data['subpixel_order']!r}")
    for key in ("views_reversed", "flip_image_x", "flip_image_y"):
        if key in data and not isinstance(data[key], bool):
            fail(key, f"must be true or false, got {short_repr(data[key])}")
    direction = data.get("view_direction")
    if direction is not None and not (_is_int(direction) and direction in VIEW_DIRECTIONS):
        fail("view_direction", f"must be 1 or -1 (or absent when unknown), got {direction!r}",
             "+1: the view index grows as the viewer moves right; -1: it falls; see "
             "'lenticalib patterns --direction'")


def profile_from_dict(data: Any, source: str = "profile") -> PanelProfile:
    """Build a validated :class:`PanelProfile` from parsed JSON; errors name ``source`` and field."""
    if not isinstance(data, dict):
        raise ProfileError("must be a JSON object with the panel constants", source=source)
    check_envelope(data, DOCUMENT, source, ProfileError)
    unknown = set(data) - set(CONSTANT_KEYS) - set(OPTIONAL_KEYS)
    if unknown:  # before the missing ones: a misspelt key is also a missing one
        raise ProfileError(unknown_key_message(unknown, CONSTANT_KEYS + OPTIONAL_KEYS), source=source,
                           hint="check the spelling; known fields are "
                                + ", ".join(CONSTANT_KEYS + OPTIONAL_KEYS))
    missing = [k for k in CONSTANT_KEYS if k not in data]
    if missing:
        raise ProfileError(f"missing field(s): {', '.join(missing)}", source=source,
                           hint="a profile needs " + ", ".join(CONSTANT_KEYS))
    fields = {k: data[k] for k in CONSTANT_KEYS}
    for key in ("uncertainty", "provenance", "looking_glass", "name", "view_direction", "physical"):
        fields[key] = data.get(key)
    for key in ("views_reversed", "flip_image_x", "flip_image_y"):
        fields[key] = data.get(key, False)
    if data.get("subpixel_layout") is not None:
        fields["subpixel_layout"] = layout_from_dict(data["subpixel_layout"], source)
    if fields["name"] is not None and not isinstance(fields["name"], str):
        raise ProfileError("field 'name': must be a string", source=source)
    _validate_constants(fields, source)
    for key in ("slant", "period", "offset", "reference_view"):
        fields[key] = float(fields[key])
    if fields["physical"] is not None:
        from .physical import validate_physical

        fields["physical"] = validate_physical(fields["physical"], source)
    return PanelProfile(**fields)


def load_profile(path: str | os.PathLike, argument: str | None = None) -> PanelProfile:
    """Read and validate a profile JSON file.  Raises ProfileError naming the file and field.

    ``argument``: how the user gave the path (e.g. ``"--profile"`` or ``"PROFILE"``), named in
    the hint for a missing file; without it the hint speaks of "the profile path".
    """
    hint = f"check the path given as {argument}" if argument else "check the profile path"
    data = read_json_file(path, "profile", hint, ProfileError, MAX_PROFILE_BYTES)
    return profile_from_dict(data, source=str(path))


def save_profile(profile: PanelProfile, path: str | os.PathLike) -> Path:
    """Write ``profile`` as JSON atomically (an existing file is replaced only on success)."""
    return write_text_atomic(path, profile.to_json())


# Decimals shown for each constant: finer than any calibration resolves (slant 1e-7 px/row is
# 2e-4 px over 2160 rows; period 1e-6 subpixel), coarse enough to read.
_DISPLAY_DECIMALS = {"slant": 7, "period": 6, "offset": 4, "reference_view": 4}


def format_constant(name: str, value) -> str:
    """``value`` of constant ``name`` for people: fixed decimals per constant (slant 7, period 6,
    offset and reference view 4), trailing zeros dropped (``19.47``, ``-0.2871235``, ``16.0``).
    Integers and strings are shown as they are.  The file keeps the full precision."""
    if name not in _DISPLAY_DECIMALS or not is_finite_number(value):
        return str(value)
    text = f"{float(value):.{_DISPLAY_DECIMALS[name]}f}".rstrip("0")
    text = text + "0" if text.endswith(".") else text
    return "0.0" if text in ("-0.0",) else text


def describe_provenance(prov: Mapping[str, Any]) -> list[str]:
    """Lines saying how a profile was made: method, when, with which lenticalib, from what.

    ``created`` (ISO 8601) is when the constants were made: for a profile read from a panel,
    when the record was written; such a profile also names the device, panel serial, record
    number and when it was read.
    """
    when = prov.get("created") or (f"{prov['read']} (when read; the calibration itself is undated)"
                                   if prov.get("read") else "an unknown date")
    lines = [f"{prov.get('method') or 'unknown method'} on {when}"
             f" (lenticalib {prov.get('lenticalib_version') or 'version unknown'})"]
    if prov.get("device_url") or prov.get("panel_serial"):
        parts = [f"device {prov['device_url']}" if prov.get("device_url") else None,
                 f"panel serial {prov['panel_serial']}" if prov.get("panel_serial") else None,
                 f"record #{prov['record_sequence']}" if prov.get("record_sequence") is not None else None,
                 f"read on {prov['read']}" if prov.get("read") else None]
        lines.append(", ".join(p for p in parts if p))
    return lines


def make_provenance(method: str, inputs: list[str | os.PathLike] = (), **extra) -> dict[str, Any]:
    """A provenance record: what made the profile, when, from which files (with SHA-256)."""
    from .. import __version__

    record: dict[str, Any] = {
        "method": method,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "lenticalib_version": __version__,
        "command": " ".join([Path(sys.argv[0]).name] + sys.argv[1:]) if sys.argv and sys.argv[0] else None,
        "inputs": [describe_input(p) for p in inputs],
    }
    record.update(extra)
    return record


def describe_input(path) -> dict[str, Any]:
    p = Path(path)
    entry: dict[str, Any] = {"path": str(p)}
    try:  # streamed: a 4 GiB avatar is hashed in 1 MiB pieces; a FIFO or folder gets no digest
        with open_input(p, "input", UNBOUNDED) as fh:
            digest = hashlib.sha256()
            for piece in iter(lambda: fh.read(1 << 20), b""):
                digest.update(piece)
        entry["sha256"] = digest.hexdigest()
    except (OSError, InputError):
        pass
    return entry
