"""USB HID transport (hidapi): the protocol's byte stream in 64-byte numbered reports.

Host to controller: output reports ``[out_report_id, n, n stream bytes, zero padding]``;
controller to host: input reports ``[in_report_id, n, ...]`` (``drivers/protocol-v1.md``
section 6.2).  ``report_size`` counts the report-ID byte, so each report carries at most
``report_size - 2`` stream bytes.  An input report with another ID or an impossible length is
dropped (the frame CRC above catches what is left).
"""

from __future__ import annotations

from ...core.errors import DeviceNotFoundError
from .base import FoundDevice, Transport, family_ids


def open_hid_device(factory, vid: int, pid: int, serial: str | None, what: str, url, hint: str):
    """A hidapi ``hid.device`` (or ``factory()``, an object with its API) opened on ``vid:pid``
    (and ``serial``); DeviceNotFoundError naming ``what`` and ``url`` when none answers."""
    if factory is None:
        import hid

        device = hid.device()
    else:
        device = factory()
    try:
        device.open(vid, pid, serial)
    except OSError:
        raise DeviceNotFoundError(f"no {what} {vid:04x}:{pid:04x}" + (f" with serial {serial}" if serial else ""),
                                  source=str(url), hint=hint) from None
    return device


class HidTransport(Transport):
    kind = "hid"

    def __init__(self, url, family, description=None, *, device_factory=None):
        super().__init__(url, family, description)
        self._factory = device_factory
        self._pending = bytearray()
        self.dropped_reports = 0
        self.device = None

    @classmethod
    def list_devices(cls) -> tuple[list[FoundDevice], list[str]]:
        """The HID devices whose VID:PID a controller family file lists (``device list``)."""
        try:
            import hid
        except ImportError as exc:
            return [], [f"HID devices not searched: {exc}"]
        found = []
        for family, t in family_ids("hid"):
            try:
                entries = hid.enumerate(t.vid, t.pid)
            except OSError as exc:
                return found, [f"HID enumeration failed: {exc}"]
            for entry in entries:
                serial = entry.get("serial_number") or None
                url = f"hid://{t.vid:04x}:{t.pid:04x}" + (f"/{serial}" if serial else "")
                found.append(FoundDevice(url, "hid", family.name, entry.get("product_string") or family.description,
                                         serial))
        return found, []

    def _open(self) -> None:
        vid, pid, serial_number = self.url.vid_pid_serial() if self.url.scheme == "hid" else (
            self.description.vid, self.description.pid, None)
        device = open_hid_device(self._factory, vid, pid, serial_number, "HID device", self.url, self.open_hint())
        device.set_nonblocking(False)
        self.device = device

    def _close(self) -> None:
        self.device.close()

    def _write(self, data: bytes) -> None:
        size = self.description.report_size
        room = size - 2
        for start in range(0, len(data), room):
            piece = data[start:start + room]
            report = bytes([self.description.out_report_id, len(piece)]) + piece
            report += bytes(size - len(report))
            if self.device.write(report) != size:
                raise OSError("HID write failed (device gone?)")

    def _read(self, max_bytes: int, timeout: float) -> bytes:
        size = self.description.report_size
        if not self._pending:
            # hidapi's read(size, 0) would block without end: wait at least 1 ms, at most the time left
            report = self.device.read(size, max(1, int(round(timeout * 1000))))
            if not report:
                return b""
            if report[0] != self.description.in_report_id or len(report) < 2 or report[1] > min(
                    size, len(report)) - 2:
                self.dropped_reports += 1
                return b""
            self._pending += bytes(report[2:2 + report[1]])
        out = bytes(self._pending[:max_bytes])
        del self._pending[:max_bytes]
        return out

    def _discard_buffered(self) -> int:
        dropped = len(self._pending)
        self._pending.clear()
        return dropped
