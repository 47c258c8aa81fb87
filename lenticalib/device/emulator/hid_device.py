"""An emulated controller behind hidapi's ``hid.device`` API.

hidapi offers no backend hook, so this class implements the part of ``hid.device`` the HID
transport uses, with hidapi's conventions: reports are byte lists whose first byte is the
report ID, ``write`` returns the bytes written or -1, ``read`` returns a list (empty on
timeout) and raises OSError once the device is gone, ``open`` raises OSError("open failed").
Host-to-controller output reports ``[out_id, n, data...]`` are unpacked into the
controller's byte stream, and its replies are packed into input reports ``[in_id, n, ...]``.
"""

from __future__ import annotations

from .controller import LinkDown, controller_for_url


class EmulatedHidDevice:
    def __init__(self, url, description):
        self.url = url
        self.description = description
        self.controller = None

    def open(self, vendor_id: int, product_id: int, serial_number: str | None = None) -> None:
        if (vendor_id, product_id) != (self.description.vid, self.description.pid):
            raise OSError("open failed")
        controller = controller_for_url(self.url)
        if serial_number is not None and serial_number != controller.identity.serial:
            controller.close()
            raise OSError("open failed")
        self.controller = controller

    def set_nonblocking(self, value) -> int:
        return 0

    def close(self) -> None:
        if self.controller is not None:
            self.controller.close()
            self.controller = None

    def write(self, buff) -> int:
        report = bytes(buff)
        size = self.description.report_size
        if self.controller is None or len(report) != size:
            return -1
        if report[0] != self.description.out_report_id or report[1] > size - 2:
            return size  # the device ignores reports it does not know, as firmware would
        try:
            self.controller.host_write(report[2:2 + report[1]])
        except LinkDown:
            return -1
        return size

    def read(self, max_length: int, timeout_ms: int = 0) -> list[int]:
        if self.controller is None:
            raise OSError("read error")
        size = self.description.report_size
        try:
            data = self.controller.host_read(min(size, max_length) - 2, timeout_ms / 1000.0)
        except LinkDown:
            raise OSError("read error") from None
        if not data:
            return []
        report = bytes([self.description.in_report_id, len(data)]) + data
        return list(report + bytes(size - len(report)))[:max_length]

    def get_serial_number_string(self) -> str:
        return self.controller.identity.serial

    def get_product_string(self) -> str:
        return self.controller.identity.model

    def get_manufacturer_string(self) -> str:
        return "lenticalib"
