"""Looking Glass units: read the factory calibration (``visual.json``) a unit keeps inside it.

    unit      the unit base class (template method: errors and checks in one place) and the
              calibration it reads (:class:`~.unit.LookingGlassCalibration`, ``to_profile(views)``)
    hid       first-generation units over USB HID: the EEPROM read page by page
    drive     later units (Portrait and others): ``LKG_calibration/visual.json`` on their USB drive
    emulated  ``lkg-emu://NAME``: the emulated HID unit (:mod:`lenticalib.device.emulator.looking_glass`)
              behind the same reader as the hardware

Units are named by URL (:mod:`lenticalib.device.url`): ``lkg-hid://04d8:ef7e[/SERIAL]``,
``lkg-drive:///MOUNT/POINT``, ``lkg-emu://NAME[?faults]``.  The schemes live in one registry on
the package's loader (:mod:`lenticalib.core.plugins`), :data:`UNITS`; third parties add schemes
through the entry-point group ``lenticalib.looking_glass_units`` (name = scheme, value =
``module:Class``, a :class:`~.unit.LookingGlassUnit` subclass or a factory ``(url) -> unit``).  A
backend with ``list_devices() -> (list[FoundDevice], list[str])`` shows its units in
``lenticalib device list``.  Units are read-only to lenticalib: nothing here writes to one.

Part of the device layer: imports only core and device.
"""

from __future__ import annotations

from ...core.errors import DeviceNotFoundError
from ...core.plugins import Registry
from ..url import DeviceURL, parse_device_url
from .unit import LookingGlassCalibration, LookingGlassUnit

UNITS = Registry("Looking Glass unit", {
    "lkg-hid": "lenticalib.device.looking_glass.hid:HidUnit",
    "lkg-drive": "lenticalib.device.looking_glass.drive:DriveUnit",
    "lkg-emu": "lenticalib.device.looking_glass.emulated:open_emulated_unit",
}, "lenticalib.looking_glass_units", install={"lkg-hid": "hidapi"}, unknown_error=DeviceNotFoundError,
    choices="use one of: {names}")

__all__ = ["UNITS", "LookingGlassCalibration", "LookingGlassUnit", "is_looking_glass", "open_unit",
           "read_calibration"]


def is_looking_glass(url: str | DeviceURL) -> bool:
    """Does ``url`` name a Looking Glass unit (a scheme of :data:`UNITS`)?  False for anything else,
    a malformed URL included (its error comes when it is opened)."""
    if isinstance(url, str):
        scheme = url.split("://", 1)[0].lower() if "://" in url else ""
    else:
        scheme = url.scheme
    return scheme in UNITS


def open_unit(url: str | DeviceURL) -> LookingGlassUnit:
    """The opened unit at ``url``; DeviceNotFoundError naming it when it is not there."""
    url = parse_device_url(url) if isinstance(url, str) else url
    return UNITS.load(url.scheme, str(url))(url).open()


def read_calibration(url: str | DeviceURL) -> LookingGlassCalibration:
    """The calibration of the unit at ``url``, checked (:meth:`LookingGlassUnit.read_calibration`)."""
    with open_unit(url) as unit:
        return unit.read_calibration()
