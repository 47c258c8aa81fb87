"""Transport registry: URL scheme -> ``"module:attribute"``, imported only when used.

As python-can's interface registry: third parties add schemes through the entry-point group
``lenticalib.transports`` (name = scheme, value = ``module:Class``); a registered backend that
does not import becomes one BackendUnavailableError naming the missing library.
"""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points

from ...core.errors import BackendUnavailableError, DeviceNotFoundError
from ..drivers import family_for
from ..url import DeviceURL, parse_device_url
from .base import Transport

TRANSPORTS = {
    "serial": "lenticalib.device.transports.serial:SerialTransport",
    "socket": "lenticalib.device.transports.serial:SerialTransport",
    "hid": "lenticalib.device.transports.hid:HidTransport",
    "usb": "lenticalib.device.transports.usb:UsbTransport",
    "emu": "lenticalib.device.transports.emulated:open_emulated",
}
_LIBRARY = {"serial": "pyserial", "socket": "pyserial", "hid": "hidapi", "usb": "pyusb", "emu": "pyserial"}


def _registry() -> dict[str, str]:
    table = dict(TRANSPORTS)
    for ep in entry_points(group="lenticalib.transports"):
        table.setdefault(ep.name, ep.value)
    return table


def _load(scheme: str, url: DeviceURL):
    table = _registry()
    if scheme not in table:
        raise DeviceNotFoundError(f"unknown transport '{scheme}'", source=str(url),
                                  hint=f"use one of: {', '.join(sorted(table))}")
    module_name, _, attr = table[scheme].partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        lib = _LIBRARY.get(scheme, module_name)
        raise BackendUnavailableError(f"transport '{scheme}' is not available: {exc}", source=str(url),
                                      hint=f"install {lib} (pip install {lib})") from None
    return getattr(module, attr)


def open_transport(url: str | DeviceURL) -> Transport:
    """An opened transport for ``url`` (see :mod:`lenticalib.device.url`)."""
    url = parse_device_url(url) if isinstance(url, str) else url
    factory = _load(url.scheme, url)
    if url.scheme in ("hid", "usb"):
        vid, pid, _ = url.vid_pid_serial()
        family = family_for(url.scheme, vid, pid)
    else:
        family = family_for()
    return factory(url, family).open()
