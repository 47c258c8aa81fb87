"""Serial transport (pyserial): USB CDC ports, pseudo-terminals and ``socket://`` TCP links.

``serial:///dev/ttyACM0`` opens the port path, ``socket://HOST:PORT`` goes to pyserial's own
socket handler, and the emulator's ``emu://NAME`` is reached through a pyserial URL handler
(:mod:`lenticalib.device.emulator.protocol_emu`).  The protocol's byte stream is carried as
is, 8N1, no flow control.
"""

from __future__ import annotations

import serial

try:
    from termios import error as _TermiosError  # tcdrain on a vanished pseudo-terminal raises it
except ImportError:  # not POSIX
    class _TermiosError(Exception):
        pass

from ...core.errors import DeviceDisconnectedError
from .base import FoundDevice, Transport, family_ids


class SerialTransport(Transport):
    kind = "serial"

    def __init__(self, url, family, description=None, *, port_url: str | None = None):
        super().__init__(url, family, description)
        if port_url is None:
            port_url = url.target if url.scheme == "serial" else f"{url.scheme}://{url.target}"
        self.port_url = port_url
        self.port = None

    def _open(self) -> None:
        baudrate = int(self.url.option("baudrate", self.description.baudrate))
        try:
            self.port = serial.serial_for_url(self.port_url, baudrate=baudrate, timeout=0,
                                              write_timeout=self.family.flash_timeout_s, exclusive=True)
        except serial.SerialException as exc:
            raise OSError(str(exc)) from None

    @classmethod
    def list_devices(cls) -> tuple[list[FoundDevice], list[str]]:
        """The serial ports whose USB VID:PID a controller family file lists (``device list``)."""
        try:
            from serial.tools import list_ports
        except ImportError as exc:
            return [], [f"serial ports not searched: {exc}"]
        wanted = {(t.vid, t.pid): f for f, t in family_ids("serial")}
        found = []
        for port in list_ports.comports():
            family = wanted.get((port.vid, port.pid))
            if family:
                found.append(FoundDevice(f"serial://{port.device}", "serial", family.name,
                                         port.description or family.description, port.serial_number))
        return found, []

    def open_hint(self) -> str:
        if self.url.scheme == "socket":
            return "check the host and port, and that the controller or 'lenticalib emulate --transport tcp' is running"
        return super().open_hint()

    def _close(self) -> None:
        self.port.close()

    def _write(self, data: bytes) -> None:
        try:
            self.port.write(data)
            self.port.flush()
        except serial.SerialTimeoutException:
            raise DeviceDisconnectedError("write timed out (the controller stopped reading)",
                                          source=str(self.url)) from None
        except serial.SerialException as exc:
            raise OSError(str(exc)) from None
        except _TermiosError as exc:  # (errno, text): the port went away under the write
            raise OSError(exc.args[-1] if exc.args else "the port went away") from None

    def _read(self, max_bytes: int, timeout: float) -> bytes:
        try:
            self.port.timeout = timeout
            first = self.port.read(1)
            if not first:
                return b""
            self.port.timeout = 0  # then whatever else has arrived, without waiting
            return first + (self.port.read(max_bytes - 1) if max_bytes > 1 else b"")
        except serial.SerialException as exc:
            raise OSError(str(exc)) from None
