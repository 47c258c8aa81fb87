"""Device URLs: how a panel controller is named on the command line and in code.

    serial:///dev/ttyACM0          USB CDC serial port (any pyserial port path)
    socket://127.0.0.1:7000        the same byte protocol over TCP (pyserial's socket handler)
    hid://1209:0002[/SERIAL]       USB HID, vendor:product in hex, optional serial number
    usb://1209:0003[/SERIAL]       USB vendor control transfers (pyusb)
    emu://NAME[?via=serial|hid|usb]  an in-process emulated controller whose flash image is
                                   NAME.flash in the emulator directory (see
                                   lenticalib.device.emulator.controller.default_image_dir)

Looking Glass units (read-only, :mod:`lenticalib.device.looking_glass`):

    lkg-hid://04d8:ef7e[/SERIAL]   a first-generation unit over USB HID (calibration in its EEPROM)
    lkg-drive:///media/USER/LKG    a later unit's USB drive (its LKG_calibration/visual.json)
    lkg-emu://NAME                 an emulated HID unit, EEPROM image NAME.lkg in the emulator
                                   directory (``lenticalib emulate --looking-glass``)

Options after ``?`` (``&``-separated ``key=value``) are passed to the transport: ``via`` for
``emu://``, ``baudrate`` for serial ports.  A bare device path is not a URL: the error for
``/dev/pts/0`` or ``COM3`` suggests ``serial:///dev/pts/0`` or ``serial://COM3``, the one for
``/dev/hidraw0`` ``hid://VID:PID``.
"""

from __future__ import annotations

import dataclasses
import re
from urllib.parse import parse_qsl

from ..core.errors import DeviceNotFoundError

_HINT = ("write it like serial:///dev/ttyACM0, socket://HOST:PORT, hid://VID:PID, usb://VID:PID, emu://NAME, "
         "lkg-hid://04d8:ef7e or lkg-drive:///MOUNT/POINT")
_VIDPID = re.compile(r"^([0-9a-fA-F]{4}):([0-9a-fA-F]{4})(?:/(.+))?$")
# bare names of serial ports: /dev/ttyACM0, /dev/pts/3, /dev/cu.usbmodem1, /dev/serial/by-id/..., COM3
_SERIAL_PATH = re.compile(r"^(?:/dev/(?:tty|pts/|cu\.|serial/|rfcomm)\S*|COM\d+|\\\\\.\\COM\d+)$", re.IGNORECASE)
_TTY_NAME = re.compile(r"^(?:tty(?:ACM|USB|S|AMA)\d+|pts/\d+)$")


def _did_you_mean(text: str) -> str:
    """The hint for something that is not a URL: the URL a bare device path most likely meant."""
    if _SERIAL_PATH.match(text):
        return f"did you mean serial://{text}?"
    if _TTY_NAME.match(text):
        return f"did you mean serial:///dev/{text}?"
    if re.match(r"^(?:/dev/)?(?:hidraw|usb/hiddev)\d+$", text):
        return ("did you mean hid://VID:PID? HID controllers are named by their USB vendor and product IDs; "
                "'lenticalib device list' prints the URL of each")
    return _HINT


@dataclasses.dataclass(frozen=True)
class DeviceURL:
    """A parsed device URL: ``scheme``, ``target`` (path, host:port, VID:PID or name), options."""

    text: str
    scheme: str
    target: str
    options: tuple[tuple[str, str], ...] = ()

    def option(self, key: str, default: str | None = None) -> str | None:
        return dict(self.options).get(key, default)

    def vid_pid_serial(self) -> tuple[int, int, str | None]:
        """For hid://, usb:// and lkg-hid://: (vendor id, product id, serial number or None)."""
        match = _VIDPID.match(self.target)
        if not match:
            raise DeviceNotFoundError(f"'{self.target}' is not VID:PID in hex", source=self.text,
                                      hint="e.g. lkg-hid://04d8:ef7e" if self.scheme == "lkg-hid"
                                      else "e.g. hid://1209:0002 or usb://1209:0003/SERIAL")
        return int(match[1], 16), int(match[2], 16), match[3]

    def __str__(self) -> str:
        return self.text


def parse_device_url(text: str) -> DeviceURL:
    """Parse ``text``; raises DeviceNotFoundError naming it when it is not a device URL."""
    if "://" not in text:
        raise DeviceNotFoundError("not a device URL", source=text, hint=_did_you_mean(text))
    scheme, rest = text.split("://", 1)
    scheme = scheme.lower()
    target, _, query = rest.partition("?")
    if not target:
        raise DeviceNotFoundError("the URL names no device", source=text, hint=_HINT)
    options = tuple(parse_qsl(query, keep_blank_values=True)) if query else ()
    url = DeviceURL(text, scheme, target, options)
    if scheme in ("hid", "usb", "lkg-hid"):
        url.vid_pid_serial()
    if scheme == "lkg-drive" and not target.startswith("/"):
        raise DeviceNotFoundError("the drive's folder must be an absolute path", source=text,
                                  hint="write it like lkg-drive:///media/USER/LKG-DRIVE (three slashes)")
    if scheme == "socket":
        host, sep, port = target.rpartition(":")
        if not sep or not host or not port.isdigit():
            raise DeviceNotFoundError(f"'{target}' is not HOST:PORT", source=text,
                                      hint="write it like socket://127.0.0.1:7000")
        if not 1 <= int(port) <= 65535:
            raise DeviceNotFoundError(f"TCP port {port} is not in 1..65535", source=text,
                                      hint="use the port 'lenticalib emulate --transport tcp' printed")
    if scheme in ("emu", "lkg-emu") and not re.fullmatch(r"[A-Za-z0-9_.-]+", target):
        raise DeviceNotFoundError(f"emulator name '{target}' must be letters, digits, '.', '_' or '-'",
                                  source=text, hint="e.g. emu://bench")
    return url
