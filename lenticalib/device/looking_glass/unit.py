"""What every Looking Glass reader shares: the unit base class and the calibration it reads.

Template method, as :class:`~lenticalib.device.transports.base.Transport`: the public
:meth:`LookingGlassUnit.open`, :meth:`~LookingGlassUnit.read_calibration` and
:meth:`~LookingGlassUnit.close` own the error mapping and the checks of what was read (its
length, UTF-8, JSON, a JSON object); a backend overrides ``_open``, ``_close`` and
``_read_text`` (the calibration's bytes, as the unit keeps them) and may offer
``list_devices() -> (list[FoundDevice], list[str])`` for ``lenticalib device list``.

A unit is only ever read: lenticalib never writes a Looking Glass calibration back.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import hashlib
import os
from typing import Any, Mapping

from ...core.files.documents import MAX_VISUAL_JSON_BYTES, json_from_bytes
from ...core.errors import DeviceDisconnectedError, DeviceProtocolError, InputError, \
    LenticalibError
from ...core.looking_glass.convert import normalize_visual, profile_from_visual
from ...core.profile import PanelProfile
from ..transports.base import Link, reason
from ..url import DeviceURL

# The calibration text a unit may hold, in bytes: a visual.json is a few hundred bytes (a
# few thousand with subpixel cells); more than this is a damaged length field or a foreign file.
MAX_CALIBRATION_BYTES = MAX_VISUAL_JSON_BYTES  # 65536, the one cap of a visual.json (docs/input-limits.md)
FAMILY = "lkg"  # the family column of ``device list``


@dataclasses.dataclass(frozen=True)
class LookingGlassCalibration:
    """A calibration read from a unit.

    ``url``: the unit's device URL; ``kind``: how it was read ("hid", "drive", ...);
    ``usb_serial``: the serial number the unit reports on USB (None when it has none or it was
    read from a folder); ``visual``: the visual.json object as parsed (values still wrapped as
    ``{"value": x}``); ``size``: its length in bytes; ``sha256``: of its bytes; ``path``: the
    file it was read from (a drive), else None; ``read``: when it was read (ISO 8601 UTC);
    ``fields``: ``visual`` unwrapped and checked (:func:`~lenticalib.core.looking_glass.convert.normalize_visual`:
    numbers as float, ``screenW``/``screenH`` as int, ``serial``/``configVersion`` as str), what
    :meth:`field` returns, or None for a calibration made by hand (then ``visual`` unwrapped).
    """

    url: str
    kind: str
    usb_serial: str | None
    visual: Mapping[str, Any]
    size: int
    sha256: str
    path: str | None
    read: str
    fields: Mapping[str, Any] | None = None

    def _field(self, key: str) -> Any:
        if self.fields is not None:
            return self.fields.get(key)
        value = self.visual.get(key)
        return value["value"] if isinstance(value, dict) and set(value) == {"value"} else value

    @property
    def serial(self) -> str | None:
        """The unit's serial: visual.json's ``serial`` when it has one, else the USB serial."""
        value = self._field("serial")
        return value if isinstance(value, str) and value else self.usb_serial

    @property
    def config_version(self) -> str | None:
        """visual.json's ``configVersion`` (the calibration format's version), None when absent."""
        value = self._field("configVersion")
        return None if value is None else str(value)

    def field(self, key: str) -> Any:
        """visual.json's field ``key`` unwrapped (``{"value": x}`` -> ``x``), None when absent."""
        return self._field(key)

    def to_profile(self, views: int) -> PanelProfile:
        """The panel profile of this calibration for ``views`` quilt views.

        :func:`lenticalib.core.looking_glass.convert.profile_from_visual` makes it (errors name the device URL);
        the provenance says it was read from this device: ``method`` "read from Looking Glass",
        ``device_url``, ``panel_serial``, ``read`` (when), ``calibration_sha256`` and, for a
        drive, the file in ``inputs``.
        """
        profile = profile_from_visual(self.visual, views, source=self.url, path=self.path)
        provenance = dict(profile.provenance or {})
        provenance.update(method="read from Looking Glass", created=None, device_url=self.url,
                          panel_serial=self.serial, read=self.read, calibration_sha256=self.sha256,
                          config_version=self.config_version)
        return profile.replace(provenance=provenance)


class LookingGlassUnit(Link):
    """One Looking Glass unit at ``url`` (a parsed :class:`DeviceURL`).  Use as a context manager."""

    kind = "base"
    what = "the Looking Glass unit"

    def __init__(self, url: DeviceURL):
        self.url = url
        self.is_open = False
        self.usb_serial: str | None = None

    # --- public API: owns errors and checks ---

    def read_calibration(self) -> LookingGlassCalibration:
        """The unit's calibration, checked: at most :data:`MAX_CALIBRATION_BYTES`, UTF-8 JSON text
        holding one object (each problem one DeviceError line naming the URL), and every field
        (:func:`~lenticalib.core.looking_glass.convert.normalize_visual`: one ProfileError line naming the URL and the
        field), before anything of it is shown or used."""
        if not self.is_open:
            self.open()
        try:
            raw, path = self._read_text()
        except LenticalibError:
            raise
        except (OSError, ValueError) as exc:
            raise DeviceDisconnectedError(f"reading the calibration failed: {reason(exc)}", source=str(self.url),
                                          hint="check the cable and read again") from None
        visual = parse_calibration(raw, str(self.url), self.retry_hint())
        fields = normalize_visual(visual, str(self.url))
        read = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        return LookingGlassCalibration(str(self.url), self.kind, self.usb_serial, visual, len(raw),
                                       hashlib.sha256(raw).hexdigest(), None if path is None else os.fspath(path),
                                       read, fields)

    def open_hint(self) -> str:
        return "check the URL ('lenticalib device list' prints those of the units it finds)"

    def retry_hint(self) -> str:
        """What to do when the calibration read is unusable."""
        return "read it again; if it persists, the unit's calibration is damaged"

    # --- backend hooks (and _open / _close of Link) ---

    def _read_text(self) -> tuple[bytes, str | os.PathLike | None]:
        """(the calibration's bytes, the file they came from or None)."""
        raise NotImplementedError


def parse_calibration(raw: bytes, source: str, hint: str) -> dict[str, Any]:
    """The JSON object in ``raw`` (a visual.json's bytes); DeviceProtocolError naming ``source`` when
    it is longer than :data:`MAX_CALIBRATION_BYTES`, not UTF-8 JSON, or not an object."""
    if len(raw) > MAX_CALIBRATION_BYTES:
        raise DeviceProtocolError(f"the calibration is longer than a visual.json can be ({MAX_CALIBRATION_BYTES} "
                                  "bytes)", source=source, hint=hint)
    try:
        visual = json_from_bytes(raw, source, "visual.json", hint, InputError, MAX_VISUAL_JSON_BYTES)
    except InputError as exc:
        text = exc.message if exc.message.startswith("field") else exc.message.removeprefix("is ")
        raise DeviceProtocolError(f"the calibration read is not a usable visual.json: {text}", source=source,
                                  hint=hint) from None
    if not isinstance(visual, dict):
        raise DeviceProtocolError(f"the calibration read is JSON but not an object of fields "
                                  f"({type(visual).__name__})", source=source, hint=hint)
    return visual
