"""Transport registry: URL scheme -> ``"module:attribute"``, imported only when used.

    base      the :class:`~.base.Transport` base class (a byte pipe to one controller, uniform
              errors and timeouts) and ``FoundDevice``
    serial    pyserial: USB CDC ports, pseudo-terminals and ``socket://`` TCP links
    hid       hidapi: the byte stream in 64-byte numbered reports
    usb       pyusb: the byte stream in vendor control transfers on endpoint 0
    emulated  ``emu://NAME[?via=serial|hid|usb&faults...]``: the in-process emulated controller

Part of the device layer: imports only core and device.  As python-can's interface registry, on
the package's one loader (:mod:`lenticalib.core.plugins`): third parties add schemes through the
entry-point group ``lenticalib.transports`` (name = scheme, value = ``module:Class``, or a
factory ``(url, family) -> Transport``); a registered backend that does not import becomes one
BackendUnavailableError naming the missing library.  A backend that can list its devices
(``list_devices``, :mod:`.base`) shows them in ``lenticalib device list``.
"""

from __future__ import annotations

from ...core.errors import DeviceNotFoundError
from ...core.plugins import Registry
from ..controller_families import family_for
from ..url import DeviceURL, parse_device_url
from .base import FoundDevice, Transport

TRANSPORTS = Registry("transport", {
    "serial": "lenticalib.device.transports.serial:SerialTransport",
    "socket": "lenticalib.device.transports.serial:SerialTransport",
    "hid": "lenticalib.device.transports.hid:HidTransport",
    "usb": "lenticalib.device.transports.usb:UsbTransport",
    "emu": "lenticalib.device.transports.emulated:open_emulated",
}, "lenticalib.transports",
    install={"serial": "pyserial", "socket": "pyserial", "hid": "hidapi", "usb": "pyusb", "emu": "pyserial"},
    unknown_error=DeviceNotFoundError, choices="use one of: {names}")

__all__ = ["TRANSPORTS", "FoundDevice", "Transport", "open_transport"]


def open_transport(url: str | DeviceURL) -> Transport:
    """An opened transport for ``url`` (see :mod:`lenticalib.device.url`)."""
    url = parse_device_url(url) if isinstance(url, str) else url
    factory = TRANSPORTS.load(url.scheme, str(url))
    if url.scheme in ("hid", "usb"):
        vid, pid, _ = url.vid_pid_serial()
        family = family_for(url.scheme, vid, pid)
    else:
        family = family_for()
    return factory(url, family).open()
