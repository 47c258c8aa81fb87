"""The transport base class: a byte pipe to one controller, with uniform errors and timeouts.

Template method (as python-can's ``BusABC``): the public :meth:`Transport.open`,
:meth:`write`, :meth:`read` and :meth:`close` own error mapping and argument checks; a backend
overrides only ``_open``, ``_close``, ``_write`` and ``_read``.  Framing, retries and
sequence numbers live above, in :mod:`lenticalib.device.client`, identical for every
transport: each transport only carries the protocol's byte stream (a serial port carries it
as is, HID packs it into 64-byte reports, USB into control transfers).
"""

from __future__ import annotations

from ...errors import DeviceDisconnectedError, DeviceError, DeviceNotFoundError
from ..drivers import ControllerFamily, TransportDescription
from ..url import DeviceURL


class Transport:
    """A byte stream to one controller.  Use as a context manager.

    ``url`` is the parsed device URL; ``family`` the controller family (timeouts) and
    ``description`` its entry for this transport kind (report sizes, request codes).
    """

    kind = "base"

    def __init__(self, url: DeviceURL, family: ControllerFamily, description: TransportDescription | None = None):
        self.url = url
        self.family = family
        self.description = description or family.transport(self.kind) or TransportDescription(self.kind, 0, 0)
        self.is_open = False

    # --- public API: owns errors ---

    def open(self) -> "Transport":
        if self.is_open:
            return self
        try:
            self._open()
        except DeviceError:
            raise
        except (OSError, ValueError) as exc:
            raise DeviceNotFoundError(f"cannot open the device: {exc}", source=str(self.url),
                                      hint=self.open_hint()) from None
        self.is_open = True
        return self

    def close(self) -> None:
        if self.is_open:
            self.is_open = False
            try:
                self._close()
            except Exception:  # closing a dead link must never mask the error that killed it
                pass

    def write(self, data: bytes) -> None:
        """Send ``data`` (all of it) or raise DeviceDisconnectedError."""
        self._require_open()
        try:
            self._write(bytes(data))
        except DeviceError:
            raise
        except (OSError, ValueError) as exc:
            raise DeviceDisconnectedError(f"write failed: {exc}", source=str(self.url),
                                          hint="check the cable and the controller's power") from None

    def read(self, max_bytes: int, timeout: float) -> bytes:
        """Up to ``max_bytes`` received bytes, waiting at most ``timeout`` seconds (b"" if none)."""
        self._require_open()
        try:
            return self._read(max_bytes, max(0.0, timeout))
        except DeviceError:
            raise
        except (OSError, ValueError) as exc:
            raise DeviceDisconnectedError(f"read failed: {exc}", source=str(self.url),
                                          hint="check the cable and the controller's power") from None

    def discard_input(self) -> None:
        """Throw away bytes already received (stale replies) before a new request."""
        while self.read(4096, 0.0):
            pass

    def open_hint(self) -> str:
        return "check the URL, that the controller is plugged in, and the udev rules (drivers/70-lenticalib.rules)"

    def __enter__(self):
        return self.open()

    def __exit__(self, *exc):
        self.close()

    def _require_open(self):
        if not self.is_open:
            raise DeviceDisconnectedError("the transport is not open", source=str(self.url))

    # --- backend hooks ---

    def _open(self) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError

    def _write(self, data: bytes) -> None:
        raise NotImplementedError

    def _read(self, max_bytes: int, timeout: float) -> bytes:
        raise NotImplementedError
