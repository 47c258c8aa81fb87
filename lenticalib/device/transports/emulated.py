"""``emu://NAME[?via=serial|hid|usb&faults...]``: the in-process emulated controller.

Each ``via`` reaches the same :class:`~lenticalib.device.emulator.controller.EmulatedController`
through the real client library of that transport wherever the library allows it:

- ``serial`` (default): pyserial's ``serial_for_url`` with lenticalib's ``emu://`` URL handler;
- ``usb``: pyusb's ``usb.core.find(backend=...)`` with the emulator as a pyusb backend;
- ``hid``: hidapi has no backend hook, so an object with hidapi's ``device`` API (report-ID
  byte first, 64-byte reports) stands in for ``hid.device()``.

:func:`list_emulators` (``open_emulated.list_devices``) lists the running emulators and the saved
flash images of in-process ones for ``device list``.
"""

from __future__ import annotations

import serial

from ...core.errors import DeviceNotFoundError, LenticalibError
from .base import FoundDevice

_PACKAGE = "lenticalib.device.emulator"


def register_pyserial_handler() -> None:
    if _PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(_PACKAGE)


def open_emulated(url, family):
    via = url.option("via", "serial")
    if via == "serial":
        from .serial import SerialTransport

        register_pyserial_handler()
        return SerialTransport(url, family, port_url=url.text)
    if via == "hid":
        from ..emulator.hid_device import EmulatedHidDevice
        from .hid import HidTransport

        return HidTransport(url, family, device_factory=lambda: EmulatedHidDevice(url, family.transport("hid")))
    if via == "usb":
        from ..emulator.usb_backend import EmulatorBackend
        from .usb import UsbTransport

        return UsbTransport(url, family, backend=EmulatorBackend(url, family.transport("usb")))
    raise DeviceNotFoundError(f"unknown via '{via}'", source=str(url), hint="use via=serial, via=hid or via=usb")


def list_emulators() -> tuple[list[FoundDevice], list[str]]:
    """Running emulators (``lenticalib emulate``) and the saved flash images ``emu://NAME`` opens."""
    from ..emulator.controller import default_image_dir
    from ..emulator.serve import running_emulators

    found, notes = [], []
    try:
        running = running_emulators()
    except LenticalibError as exc:  # an unsafe runtime folder: say so, list the rest
        notes.append(f"running emulators not listed: {exc}")
        running = []
    for entry in running:
        found.append(FoundDevice(entry["url"], entry.get("transport", "?"), "lc32",
                                 f"running emulator (pid {entry['pid']}, flash {entry.get('flash')})",
                                 entry.get("serial")))
    folder = default_image_dir()
    for image in sorted(folder.glob("*.flash")) if folder.is_dir() else []:
        found.append(FoundDevice(f"emu://{image.stem}", "emu", "lc32", f"in-process emulator ({image})"))
    return found, notes


open_emulated.list_devices = list_emulators  # asked by device list (lenticalib.device.discovery)
