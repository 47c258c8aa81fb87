"""USB vendor-request transport (pyusb): the byte stream in control transfers on endpoint 0.

Host to controller: ``bmRequestType 0x40, bRequest request_out`` with one request frame as
the data stage.  Controller to host: ``bmRequestType 0xC0, bRequest request_in, wLength
max_in`` returns the reply bytes pending (zero-length when none yet), so the host polls until
its deadline (``drivers/protocol-v1.md`` section 6.3).
"""

from __future__ import annotations

import errno
import math
import time

import usb.core
import usb.util

from ...core.errors import DeviceDisconnectedError, DeviceNotFoundError
from .base import FoundDevice, Transport, family_ids

_POLL_S = 0.002


class UsbTransport(Transport):
    kind = "usb"

    def __init__(self, url, family, description=None, *, backend=None):
        super().__init__(url, family, description)
        self._backend = backend
        self.device = None

    @classmethod
    def list_devices(cls) -> tuple[list[FoundDevice], list[str]]:
        """The USB devices whose VID:PID a controller family file lists (``device list``)."""
        found = []
        for family, t in family_ids("usb"):
            try:
                devices = list(usb.core.find(find_all=True, idVendor=t.vid, idProduct=t.pid))
            except usb.core.NoBackendError:
                return found, ["USB devices not searched: pyusb found no libusb (install libusb-1.0)"]
            except usb.core.USBError as exc:
                return found, [f"USB enumeration failed: {exc}"]
            for dev in devices:
                serial = _serial_of(dev)  # None without permission: still listed, the udev rules fix access
                url = f"usb://{t.vid:04x}:{t.pid:04x}" + (f"/{serial}" if serial else "")
                found.append(FoundDevice(url, "usb", family.name, family.description, serial))
        return found, []

    def _open(self) -> None:
        vid, pid, serial_number = self.url.vid_pid_serial() if self.url.scheme == "usb" else (
            self.description.vid, self.description.pid, None)

        def match(dev):
            return serial_number is None or _serial_of(dev) == serial_number

        try:
            device = usb.core.find(idVendor=vid, idProduct=pid, backend=self._backend, custom_match=match)
        except usb.core.NoBackendError:
            raise DeviceNotFoundError("pyusb found no libusb backend", source=str(self.url),
                                      hint="install libusb-1.0 (e.g. apt install libusb-1.0-0)") from None
        except usb.core.USBError as exc:
            raise OSError(str(exc)) from None
        if device is None:
            raise DeviceNotFoundError(f"no USB device {vid:04x}:{pid:04x}"
                                      + (f" with serial {serial_number}" if serial_number else ""),
                                      source=str(self.url), hint=self.open_hint())
        self.device = device

    def _close(self) -> None:
        usb.util.dispose_resources(self.device)

    def _timeout_ms(self) -> int:
        return int(self.family.flash_timeout_s * 1000)

    def _write(self, data: bytes) -> None:
        try:
            sent = self.device.ctrl_transfer(0x40, self.description.request_out, 0, 0, data, self._timeout_ms())
        except usb.core.USBError as exc:
            raise self._usb_error(exc) from None
        if sent != len(data):
            raise OSError(f"control transfer sent {sent} of {len(data)} bytes")

    def _read(self, max_bytes: int, timeout: float) -> bytes:
        try:  # pyusb's timeout 0 means none: at least 1 ms, at most the time left
            data = self.device.ctrl_transfer(0xC0, self.description.request_in, 0, 0,
                                             min(max_bytes, self.description.max_in),
                                             max(1, math.ceil(timeout * 1000)))
        except usb.core.USBTimeoutError:
            data = b""
        except usb.core.USBError as exc:
            raise self._usb_error(exc) from None
        if len(data):
            return bytes(data)
        time.sleep(min(_POLL_S, timeout))  # nothing pending yet: poll again (protocol-v1.md 6.3)
        return b""

    def _usb_error(self, exc: Exception) -> Exception:
        if getattr(exc, "errno", None) in (errno.ENODEV, errno.EIO) or getattr(exc, "backend_error_code", None) == -4:
            return DeviceDisconnectedError(f"USB device gone: {exc}", source=str(self.url),
                                           hint="check the cable and the controller's power")
        return OSError(str(exc))


def _serial_of(device) -> str | None:
    try:
        return device.serial_number
    except (usb.core.USBError, ValueError):
        return None
