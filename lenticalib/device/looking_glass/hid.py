"""First-generation Looking Glass units over USB HID (hidapi): the calibration in their EEPROM.

The unit (vendor 0x04d8, product 0xef7e, product string "HoloPlay") keeps its ``visual.json``
in an EEPROM read one 64-byte page at a time (``docs/looking-glass-devices.md``):

    request   feature report, 68 bytes: [report ID 0, command 0 (read), page >> 8, page & 0xff,
              64 zero bytes]
    answer    input report, 68 bytes:   [buttons, command, page >> 8, page & 0xff, 64 data bytes]
    EEPROM    bytes 0..3: the text's length L (big-endian u32), bytes 4..4+L-1: the text

The answer's first byte is the state of the unit's buttons, so input reports also come unasked
(a button pressed) or late (the answer to an earlier request): a report whose echo is not the
command and page asked for is skipped, as is one shorter than 68 bytes, and the request is sent
again (:data:`RETRIES` times) when no matching answer comes within :data:`PAGE_TIMEOUT_S`.  What
still fails is one line: the page that was answered instead, the short length, or no answer.
The whole read, every page and every resend, has one deadline: :data:`CONVERSATION_TIMEOUTS`
times the page timeout (30 s at the default 1 s), so a unit that answers each page just before
its timeout ends in one DeviceTimeoutError line instead of taking up to 3 x 1025 page timeouts
(a 64 KiB length).  A unit in order reads even the longest calibration well within it (a page
takes a few milliseconds; 1025 pages at up to 29 ms each fit 30 s).
A length of 0xFFFFFFFF is a blank EEPROM; 0 or more than
:data:`~.unit.MAX_CALIBRATION_BYTES` is refused before any further page is read.

:class:`HidUnit` opens the unit through ``hid.device()``, or through the ``device_factory`` it
is given: the emulated unit (:mod:`lenticalib.device.emulator.looking_glass`) is an object with
hidapi's ``device`` API, so the reader speaks to it exactly as to the hardware.
"""

from __future__ import annotations

import math
import time
from typing import Callable

from ...core.errors import DeviceProtocolError, DeviceTimeoutError, InputError
from ..deadline import Deadline
from ..transports.base import FoundDevice
from ..transports.hid import open_hid_device
from .unit import FAMILY, MAX_CALIBRATION_BYTES, LookingGlassUnit

VENDOR_ID = 0x04D8
PRODUCT_ID = 0xEF7E
PRODUCT_STRING = "HoloPlay"
PAGE_SIZE = 64
HEADER_SIZE = 4  # report ID (request) or buttons (answer), command, page high byte, page low byte
REPORT_SIZE = HEADER_SIZE + PAGE_SIZE
READ_COMMAND = 0x00
LENGTH_BYTES = 4
BLANK_LENGTH = 0xFFFFFFFF  # an erased EEPROM reads as 0xff bytes
PAGE_TIMEOUT_S = 1.0  # per request; the vendor's reader waits 1 s too
RETRIES = 2  # requests sent again after a missing, short or mismatched answer
CONVERSATION_TIMEOUTS = 30  # the whole read (all pages, all resends) ends within this many page timeouts
MAX_PAGE = 0xFFFF


def page_request(page: int) -> bytes:
    """The 68-byte feature report that asks for EEPROM page ``page`` (0..65535)."""
    if not 0 <= page <= MAX_PAGE:
        raise ValueError(f"page {page} is not 0..{MAX_PAGE}")
    return bytes([0, READ_COMMAND, page >> 8, page & 0xFF]) + bytes(PAGE_SIZE)


def page_timeout(url, more_options: tuple[str, ...] = ()) -> float:
    """The URL's ``timeout=S`` (0.01..60 seconds per page answer) or :data:`PAGE_TIMEOUT_S`;
    InputError naming the URL for a bad value or an option other than ``timeout`` and ``more_options``."""
    for key, _ in url.options:
        if key != "timeout" and key not in more_options:
            raise InputError(f"unknown URL parameter '{key}'", source=str(url),
                             hint=f"{url.scheme}:// parameters: {', '.join(('timeout',) + more_options)}")
    text = url.option("timeout")
    if text is None:
        return PAGE_TIMEOUT_S
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.01 <= value <= 60:
        raise InputError(f"URL parameter 'timeout' must be 0.01..60 seconds, got '{text}'", source=str(url))
    return value


def pages_for(length: int) -> int:
    """How many pages hold the length field and ``length`` bytes of text."""
    return -(-(LENGTH_BYTES + length) // PAGE_SIZE)


class HidUnit(LookingGlassUnit):
    """A first-generation unit at ``lkg-hid://04d8:ef7e[/SERIAL]``.

    ``device_factory``: makes the hidapi ``device`` object (default ``hid.device``); ``ids``:
    (vendor, product, serial or None) to open, by default the URL's; ``retries``: requests sent
    again.  The URL option ``timeout=S`` sets the seconds to wait for each page's answer (default
    :data:`PAGE_TIMEOUT_S`); the whole read ends within :data:`CONVERSATION_TIMEOUTS` times it
    (``deadline_s``); ``more_options`` are further options the caller reads itself.
    """

    kind = "hid"

    def __init__(self, url, *, device_factory: Callable | None = None, ids: tuple[int, int, str | None] | None = None,
                 retries: int = RETRIES, more_options: tuple[str, ...] = ()):
        super().__init__(url)
        self._factory = device_factory
        self._ids = ids
        self.timeout = page_timeout(url, more_options)
        self.deadline_s = CONVERSATION_TIMEOUTS * self.timeout  # the whole read, seconds
        self.deadline = Deadline()  # of the read in progress
        self._pages: tuple[int, int | None] = (0, None)  # (pages read, pages to read or None) of that read
        self.retries = retries
        self.device = None
        self.skipped = 0  # reports skipped: unasked, late, short or for another page

    @classmethod
    def list_devices(cls) -> tuple[list[FoundDevice], list[str]]:
        """The HoloPlay HID units connected (``device list``)."""
        try:
            import hid
        except ImportError as exc:
            return [], [f"Looking Glass HID units not searched: {exc}"]
        try:
            entries = hid.enumerate(VENDOR_ID, PRODUCT_ID)
        except OSError as exc:
            return [], [f"Looking Glass HID enumeration failed: {exc}"]
        found, seen = [], set()
        for entry in entries:
            serial = entry.get("serial_number") or None
            if serial in seen:  # one unit may show several HID interfaces
                continue
            seen.add(serial)
            url = f"lkg-hid://{VENDOR_ID:04x}:{PRODUCT_ID:04x}" + (f"/{serial}" if serial else "")
            product = entry.get("product_string") or PRODUCT_STRING
            found.append(FoundDevice(url, "lkg-hid", FAMILY, f"Looking Glass ({product}, calibration in EEPROM)",
                                     serial))
        return found, []

    def open_hint(self) -> str:
        return ("check that the unit is plugged in over USB, and the udev rule drivers/70-lenticalib.rules "
                "(without it only root may open the unit)")

    def retry_hint(self) -> str:
        return "unplug and replug the unit and read again; if it persists, its EEPROM calibration is damaged"

    def _open(self) -> None:
        vid, pid, serial = self._ids or self.url.vid_pid_serial()
        device = open_hid_device(self._factory, vid, pid, serial, "Looking Glass HID unit", self.url,
                                 self.open_hint())
        self.device = device
        try:
            self.usb_serial = device.get_serial_number_string() or serial
        except (OSError, ValueError):
            self.usb_serial = serial

    def _close(self) -> None:
        self.device.close()

    def _read_text(self) -> tuple[bytes, None]:
        self._pages = (0, None)
        with self.deadline.running(self.deadline_s):
            return self._read_pages()

    def _read_pages(self) -> tuple[bytes, None]:
        first = self.read_page(0)
        length = int.from_bytes(first[:LENGTH_BYTES], "big")
        if length == BLANK_LENGTH:
            raise DeviceProtocolError("the unit's EEPROM holds no calibration (it reads as erased)",
                                      source=str(self.url),
                                      hint="the unit has lost its factory calibration; ask Looking Glass "
                                           "for its visual.json and import it with 'lenticalib profile "
                                           "import-lkg'")
        if not 0 < length <= MAX_CALIBRATION_BYTES:
            raise DeviceProtocolError(f"the EEPROM's length field says the calibration is {length} bytes; a "
                                      f"visual.json is 1..{MAX_CALIBRATION_BYTES}", source=str(self.url),
                                      hint=self.retry_hint())
        data = bytearray(first)
        for page in range(1, pages_for(length)):
            self._pages = (page, pages_for(length))
            data += self.read_page(page)
        return bytes(data[LENGTH_BYTES:LENGTH_BYTES + length]), None

    def read_page(self, page: int) -> bytes:
        """The 64 bytes of EEPROM page ``page``: the request is sent (again, up to ``retries``
        times) until an answer echoes command and page; DeviceProtocolError or
        DeviceTimeoutError naming the page when none does, DeviceTimeoutError when the whole
        read's deadline (:meth:`_read_text`) passes first."""
        request = page_request(page)
        echo = request[1:HEADER_SIZE]
        wrong: list[int] = []
        short: list[int] = []
        for _ in range(self.retries + 1):
            self._check_deadline()
            if self.device.send_feature_report(request) < 0:
                raise OSError(f"sending the request for page {page} failed (unit gone?)")
            deadline = self.deadline.wait_end(self.timeout)
            while (left := deadline - time.monotonic()) > 0:
                report = bytes(self.device.read(REPORT_SIZE, max(1, int(round(left * 1000)))))
                if not report:
                    continue
                if len(report) < REPORT_SIZE:
                    short.append(len(report))
                elif report[1:HEADER_SIZE] != echo:
                    wrong.append(report[2] << 8 | report[3] if report[1] == READ_COMMAND else -1)
                else:
                    return report[HEADER_SIZE:REPORT_SIZE]
                self.skipped += 1
        self._check_deadline()
        attempts = f"{self.retries + 1} requests"
        if wrong:
            pages = sorted({p for p in wrong if p >= 0})
            told = (f"page{'s' if len(pages) > 1 else ''} {', '.join(map(str, pages))}" if pages else "")
            other = "another command" if -1 in wrong else ""
            raise DeviceProtocolError(f"asked for EEPROM page {page}, the unit answered "
                                      f"{' and '.join(t for t in (told, other) if t)} instead ({attempts})",
                                      source=str(self.url), hint=self.retry_hint())
        if short:
            raise DeviceProtocolError(f"the answers to EEPROM page {page} were cut short ({max(short)} bytes; a "
                                      f"page answer is {REPORT_SIZE}) in {attempts}", source=str(self.url),
                                      hint=self.retry_hint())
        raise DeviceTimeoutError(f"no answer to the request for EEPROM page {page} within {self.timeout:g} s "
                                 f"({attempts})", source=str(self.url),
                                 hint="check that the URL names a Looking Glass unit (product HoloPlay) and "
                                      "that nothing else (HoloPlay Service, another reader) is using it")

    def _check_deadline(self) -> None:
        """DeviceTimeoutError when the read in progress has passed its deadline (one line: how long,
        the page timeout it is a multiple of, how far the read came)."""
        if not self.deadline.passed():
            return
        done, total = self._pages
        came = f"{done} of {total} pages" if total is not None else "the length page not yet"
        raise DeviceTimeoutError(f"the calibration read did not finish within {self.deadline_s:g} s "
                                 f"({CONVERSATION_TIMEOUTS} x the {self.timeout:g} s page timeout): {came} read",
                                 source=str(self.url),
                                 hint="the unit answers too slowly (a unit in order answers a page in "
                                      "milliseconds); unplug and replug it, close other programs using it, or "
                                      "give a longer 'timeout=S' in the URL")
