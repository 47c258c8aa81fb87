"""The transport base class: a byte pipe to one controller, with uniform errors and timeouts.

Template method (as python-can's ``BusABC``): the public :meth:`Transport.open`,
:meth:`write`, :meth:`read`, :meth:`discard_input` and :meth:`close` own error mapping,
argument checks and every deadline; a backend overrides only ``_open``, ``_close``, ``_write``
and ``_read`` (one bounded attempt), plus ``_discard_buffered`` when it buffers input itself.  Framing, retries and
sequence numbers live above, in :mod:`lenticalib.device.client`, identical for every
transport: each transport only carries the protocol's byte stream (a serial port carries it
as is, HID packs it into 64-byte reports, USB into control transfers).

A backend may also list the controllers it can reach (``lenticalib device list`` asks every
registered transport, :mod:`lenticalib.device.discovery`): an attribute
``list_devices() -> (list[FoundDevice], list[str])``, the devices and one-line notes about what
could not be searched (a missing library, no permission), on the class (a classmethod) or on
the factory function the registry names.
"""

from __future__ import annotations

import dataclasses
import re
import time
from typing import Iterator

from ...core.errors import DeviceDisconnectedError, DeviceNotFoundError, DeviceTimeoutError, LenticalibError
from ..controller_families import ControllerFamily, TransportDescription, families
from ..url import DeviceURL


_LIBRARY_PREFIXES = re.compile(r"^(?:(?:read|write) failed: |could not open port (?:\S+: )?|\[errno \d+\] )+",
                               re.IGNORECASE)


@dataclasses.dataclass(frozen=True)
class FoundDevice:
    """One controller that can be opened at ``url``."""

    url: str
    transport: str
    family: str
    description: str
    serial: str | None = None


def family_ids(kind: str) -> Iterator[tuple[ControllerFamily, TransportDescription]]:
    """(family, its transport entry) for every controller family file that lists a ``kind`` transport."""
    for family in families():
        for t in family.transports:
            if t.kind == kind:
                yield family, t


def reason(exc: BaseException, url: str | None = None) -> str:
    """The cause in a library's exception text, without the prefixes our own messages add again.

    pyserial says "read failed: socket disconnected" or "Could not open port URL: [Errno 111]
    Connection refused"; the transport's message already says what failed and its source the
    URL, so this keeps "socket disconnected" and "Connection refused".
    """
    text = str(exc) or type(exc).__name__
    if url:
        text = text.replace(f"{url}: ", "")
    return _LIBRARY_PREFIXES.sub("", text).strip() or type(exc).__name__


class Link:
    """Opening and closing one device at ``self.url`` around the backend hooks ``_open`` / ``_close``.

    ``open`` turns an OSError or ValueError of the backend into one DeviceNotFoundError naming the
    URL (``what`` names the device in it, ``open_hint()`` says what to do); ``close`` never raises.
    A context manager.  Shared by controller transports and Looking Glass units.
    """

    what = "the device"
    url: DeviceURL
    is_open: bool = False

    def open(self):
        if self.is_open:
            return self
        try:
            self._open()
        except LenticalibError:  # already says what is wrong (a bad URL parameter, a busy flash image)
            raise
        except (OSError, ValueError) as exc:
            raise DeviceNotFoundError(f"cannot open {self.what}: {reason(exc, str(self.url))}", source=str(self.url),
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

    def open_hint(self) -> str:
        return "check the URL and that the device is plugged in"

    def __enter__(self):
        return self.open()

    def __exit__(self, *exc):
        self.close()

    def _open(self) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError


class Transport(Link):
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

    def write(self, data: bytes) -> None:
        """Send ``data`` (all of it) or raise DeviceDisconnectedError."""
        self._require_open()
        try:
            self._write(bytes(data))
        except LenticalibError:  # already one line (a device error, a bad emu:// parameter met on first use)
            raise
        except (OSError, ValueError) as exc:
            raise DeviceDisconnectedError(f"write failed: {reason(exc)}", source=str(self.url),
                                          hint="check the cable and the controller's power") from None

    def read(self, max_bytes: int, timeout: float) -> bytes:
        """Up to ``max_bytes`` received bytes, waiting at most ``timeout`` seconds (b"" if none).

        The deadline is kept here: ``_read`` makes one attempt bounded by the time left and may
        come back empty early (a report dropped, an empty USB poll); it is asked again until
        bytes come or the deadline passes.  ``timeout`` 0 makes exactly one attempt.
        """
        self._require_open()
        deadline = time.monotonic() + max(0.0, timeout)
        try:
            while True:
                data = self._read(max_bytes, max(0.0, deadline - time.monotonic()))
                if data or time.monotonic() >= deadline:
                    return data
        except LenticalibError:
            raise
        except (OSError, ValueError) as exc:
            raise DeviceDisconnectedError(f"read failed: {reason(exc)}", source=str(self.url),
                                          hint="check the cable and the controller's power") from None

    def discard_input(self, timeout: float) -> int:
        """Throw away bytes already received (stale replies) before a new request; their count.

        Bounded like every wait by ``timeout`` seconds (the command's timeout): a controller
        that is still sending when it has passed talks unasked, no request could be told apart
        from its stream, and DeviceTimeoutError says so.
        """
        self._require_open()
        deadline = time.monotonic() + max(0.0, timeout)
        dropped = self._discard_buffered()
        while True:
            data = self.read(4096, 0.0)
            if not data:
                return dropped
            dropped += len(data)
            if time.monotonic() >= deadline:
                raise DeviceTimeoutError(f"the controller keeps sending unasked ({dropped} bytes in {timeout:g} s "
                                         "before the request), so no request can be sent", source=str(self.url),
                                         hint="check that the URL names a panel controller speaking protocol v1; "
                                              "unplug and replug it")

    def open_hint(self) -> str:
        return "check the URL, that the controller is plugged in, and the udev rules (drivers/70-lenticalib.rules)"

    def _require_open(self):
        if not self.is_open:
            raise DeviceDisconnectedError("the transport is not open", source=str(self.url))

    # --- backend hooks (and _open / _close of Link) ---

    def _write(self, data: bytes) -> None:
        raise NotImplementedError

    def _read(self, max_bytes: int, timeout: float) -> bytes:
        """One attempt: bytes received, waiting at most ``timeout`` s; b"" when none (yet)."""
        raise NotImplementedError

    def _discard_buffered(self) -> int:
        """Drop input the backend buffers itself (beyond what ``_read`` returns); the bytes dropped."""
        return 0
