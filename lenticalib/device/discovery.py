"""Find panel controllers: USB serial ports, HID devices and USB devices whose VID/PID appear
in a controller family file, plus running and saved emulators.

Each transport library is asked separately; one that is missing or cannot enumerate (no
libusb, no hidraw) adds a note instead of failing the whole listing.
"""

from __future__ import annotations

import dataclasses

from .drivers import families


@dataclasses.dataclass(frozen=True)
class FoundDevice:
    """One controller that can be opened at ``url``."""

    url: str
    transport: str
    family: str
    description: str
    serial: str | None = None


def _ids(kind: str):
    for family in families():
        for t in family.transports:
            if t.kind == kind:
                yield family, t


def _serial_ports(found, notes):
    try:
        from serial.tools import list_ports
    except ImportError as exc:
        notes.append(f"serial ports not searched: {exc}")
        return
    wanted = {(t.vid, t.pid): f for f, t in _ids("serial")}
    for port in list_ports.comports():
        family = wanted.get((port.vid, port.pid))
        if family:
            found.append(FoundDevice(f"serial://{port.device}", "serial", family.name,
                                     port.description or family.description, port.serial_number))


def _hid_devices(found, notes):
    try:
        import hid
    except ImportError as exc:
        notes.append(f"HID devices not searched: {exc}")
        return
    for family, t in _ids("hid"):
        try:
            entries = hid.enumerate(t.vid, t.pid)
        except OSError as exc:
            notes.append(f"HID enumeration failed: {exc}")
            return
        for entry in entries:
            serial = entry.get("serial_number") or None
            url = f"hid://{t.vid:04x}:{t.pid:04x}" + (f"/{serial}" if serial else "")
            found.append(FoundDevice(url, "hid", family.name, entry.get("product_string") or family.description,
                                     serial))


def _usb_devices(found, notes):
    try:
        import usb.core
    except ImportError as exc:
        notes.append(f"USB devices not searched: {exc}")
        return
    for family, t in _ids("usb"):
        try:
            devices = list(usb.core.find(find_all=True, idVendor=t.vid, idProduct=t.pid))
        except usb.core.NoBackendError:
            notes.append("USB devices not searched: pyusb found no libusb (install libusb-1.0)")
            return
        except usb.core.USBError as exc:
            notes.append(f"USB enumeration failed: {exc}")
            return
        for dev in devices:
            try:
                serial = dev.serial_number
            except (usb.core.USBError, ValueError):
                serial = None  # no permission to open: still listed, the udev rules fix access
            url = f"usb://{t.vid:04x}:{t.pid:04x}" + (f"/{serial}" if serial else "")
            found.append(FoundDevice(url, "usb", family.name, family.description, serial))


def _emulators(found, notes):
    from .emulator.controller import default_image_dir
    from .emulator.serve import running_emulators

    from ..core.errors import LenticalibError

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


def list_devices(*, emulators: bool = True) -> tuple[list[FoundDevice], list[str]]:
    """(devices found, notes about transports that could not be searched)."""
    found: list[FoundDevice] = []
    notes: list[str] = []
    for search in (_serial_ports, _hid_devices, _usb_devices):
        search(found, notes)
    if emulators:
        _emulators(found, notes)
    return found, notes
