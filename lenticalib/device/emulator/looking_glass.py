"""An emulated first-generation Looking Glass unit behind hidapi's ``hid.device`` API.

The unit's EEPROM is kept in an image file, ``NAME.lkg`` in the emulator directory
(:func:`~.controller.default_image_dir`, as ``emu://NAME`` keeps ``NAME.flash``): the 4-byte
big-endian length of the calibration text, the text, then 0xff (erased) bytes to the end of the
last page.  :func:`create_unit` writes one from a visual.json's bytes (stored as given, so a
damaged calibration can be emulated too); ``lenticalib emulate --looking-glass VISUAL.json``
does the same from the command line.

:class:`EmulatedLookingGlassHid` answers the page protocol of
:mod:`lenticalib.device.looking_glass.hid` with hidapi's conventions (``open`` raises
OSError("open failed"), ``send_feature_report`` returns the bytes sent or -1, ``read`` returns a
list, empty after ``timeout_ms`` without an answer), so the reader talks to it exactly as to
the hardware.  Faults (:class:`~.faults.FaultPlan`, seeded) act per request: ``drop_rate`` (no
answer), ``short_rate`` (an answer cut to 20 bytes), ``wrong_page_rate`` (the next page
answered instead) and ``delay_rate`` (the answer comes ``delay_s`` seconds late: with
``delay=1&delay-s=S`` just under the reader's timeout, a slow unit that answers every page).
Requests other than reads get no answer: the emulated unit, as lenticalib, never writes its
EEPROM.
"""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

from ...core.files.atomic import write_bytes_atomic
from ...core.errors import InputError
from ..looking_glass.hid import (HEADER_SIZE, LENGTH_BYTES, MAX_PAGE, PAGE_SIZE, PRODUCT_ID, PRODUCT_STRING,
                                 READ_COMMAND, VENDOR_ID)
from .controller import default_image_dir
from .faults import FaultPlan

IMAGE_SUFFIX = ".lkg"
MANUFACTURER = "Looking Glass Factory"
SHORT_ANSWER = 20  # bytes of an answer cut short
URL_FAULTS = {"drop": "drop_rate", "short": "short_rate", "wrong-page": "wrong_page_rate", "delay": "delay_rate",
              "delay-s": "delay_s", "seed": "seed"}


def eeprom_bytes(text: bytes | None) -> bytes:
    """The EEPROM holding ``text`` (None: a blank EEPROM, one erased page), whole pages."""
    if text is None:
        return b"\xff" * PAGE_SIZE
    data = len(text).to_bytes(LENGTH_BYTES, "big") + text
    return data + b"\xff" * (-len(data) % PAGE_SIZE)


def unit_image(name: str) -> Path:
    """Where ``lkg-emu://NAME`` keeps its EEPROM: NAME.lkg in the emulator directory."""
    return default_image_dir() / f"{name}{IMAGE_SUFFIX}"


def create_unit(name: str, text: bytes | None) -> str:
    """Write the EEPROM image of an emulated unit named ``name`` holding ``text`` (a visual.json's
    bytes, stored as given; None: blank) and return its URL ``lkg-emu://NAME``."""
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
        raise InputError(f"emulator name '{name}' must be letters, digits, '.', '_' or '-'", source="name")
    path = unit_image(name)
    path.parent.mkdir(parents=True, exist_ok=True)  # the emulators' own state folder
    write_bytes_atomic(path, eeprom_bytes(text), "Looking Glass EEPROM image")
    return f"lkg-emu://{name}"


def serial_for(name: str) -> str:
    """The USB serial number the emulated unit ``name`` reports."""
    return "LKG-EMU-" + ("".join(c for c in name.upper() if c.isascii() and c.isalnum())[:16] or "UNIT")


def fault_plan(url) -> FaultPlan:
    """The faults an ``lkg-emu://NAME?drop=P&short=P&wrong-page=P&delay=P&delay-s=S&seed=S`` URL asks for
    (``timeout`` is the reader's, passed over); InputError naming the URL and the parameter."""
    values = {}
    for key, text in url.options:
        if key == "timeout":
            continue
        if key not in URL_FAULTS:
            raise InputError(f"unknown URL parameter '{key}'", source=str(url),
                             hint=f"lkg-emu:// parameters: {', '.join(URL_FAULTS)}, timeout")
        try:
            values[URL_FAULTS[key]] = int(text) if key == "seed" else float(text)
        except ValueError:
            raise InputError(f"URL parameter '{key}' must be a number, got '{text}'", source=str(url)) from None
    try:
        return FaultPlan(**values)
    except InputError as exc:
        key = next((k for k, f in URL_FAULTS.items() if f == exc.source), exc.source)
        raise InputError(f"URL parameter '{key}' {exc.message}", source=str(url)) from None


class EmulatedLookingGlassHid:
    """The unit ``lkg-emu://NAME`` with hidapi's ``device`` API (module docstring)."""

    def __init__(self, url):
        self.url = url
        self.name = url.target
        self.faults = fault_plan(url)
        self.eeprom: bytes | None = None
        self._answers: list[tuple[float, bytes]] = []  # (when it is ready, time.monotonic(); the report)
        self.requests = 0

    def open(self, vendor_id: int, product_id: int, serial_number: str | None = None) -> None:
        if (vendor_id, product_id) != (VENDOR_ID, PRODUCT_ID):
            raise OSError("open failed")
        if serial_number is not None and serial_number != serial_for(self.name):
            raise OSError("open failed")
        try:
            self.eeprom = unit_image(self.name).read_bytes()
        except OSError:
            raise OSError("open failed") from None

    def set_nonblocking(self, value) -> int:
        return 0

    def close(self) -> None:
        self.eeprom = None
        self._answers.clear()

    def send_feature_report(self, data) -> int:
        report = bytes(data)
        if self.eeprom is None or len(report) < HEADER_SIZE:
            return -1
        self.requests += 1
        command, page = report[1], report[2] << 8 | report[3]
        if command != READ_COMMAND:
            return len(report)  # writes and other commands: accepted, never carried out, unanswered
        faults = self.faults
        if faults.hit(faults.drop_rate):
            return len(report)
        if faults.hit(faults.wrong_page_rate):
            page = (page + 1) % (MAX_PAGE + 1)
        answer = bytes([0, command, page >> 8, page & 0xFF]) + self.page(page)
        if faults.hit(faults.short_rate):
            answer = answer[:SHORT_ANSWER]
        delay = faults.delay_s if faults.hit(faults.delay_rate) else 0.0
        self._answers.append((time.monotonic() + delay, answer))
        return len(report)

    def page(self, page: int) -> bytes:
        """EEPROM page ``page``: 64 bytes, erased (0xff) beyond the image."""
        start = page * PAGE_SIZE
        data = self.eeprom[start:start + PAGE_SIZE]
        return data + b"\xff" * (PAGE_SIZE - len(data))

    def read(self, max_length: int, timeout_ms: int = 0) -> list[int]:
        if self.eeprom is None:
            raise OSError("read error")
        wait = max(0, timeout_ms) / 1000.0
        if not self._answers:
            time.sleep(wait)  # no answer comes: the wait a device would take
            return []
        ready, answer = self._answers[0]
        early = ready - time.monotonic()
        if early > 0:  # a late answer: waited for, as long as the caller waits
            time.sleep(min(early, wait))
            if early > wait:
                return []
        self._answers.pop(0)
        return list(answer[:max_length])

    def get_serial_number_string(self) -> str:
        return serial_for(self.name)

    def get_product_string(self) -> str:
        return PRODUCT_STRING

    def get_manufacturer_string(self) -> str:
        return MANUFACTURER


def saved_units() -> list[tuple[str, Path]]:
    """(URL, image) of every emulated unit saved in the emulator directory."""
    folder = default_image_dir()
    if not folder.is_dir():
        return []
    return [(f"lkg-emu://{image.name[:-len(IMAGE_SUFFIX)]}", image)
            for image in sorted(folder.glob(f"*{IMAGE_SUFFIX}")) if os.path.isfile(image)]

