"""The host's protocol engine: requests, retries, stale-reply rejection, flash with read-back.

:class:`PanelController` speaks protocol v1 (``drivers/protocol-v1.md``) over any
:class:`~lenticalib.device.transports.base.Transport`.  Every request waits for its reply at
most the family's timeout and is resent (same SEQ, so the firmware answers a duplicate from
its cache instead of executing it twice) up to ``retries`` times; a reply with another SEQ or
command, or a corrupt frame, is discarded.  Each public operation (identify, read, verify,
flash, ...) is one conversation with one deadline over all its requests and resends,
:meth:`PanelController.conversation_s`: ``10 (retries + 1)`` command timeouts and 2 flash
timeouts (24 s for the lc32 family), so a controller that answers each request just before its
timeout, or only the last resend, ends in one DeviceTimeoutError line instead of taking up to
136 requests x ``retries + 1`` timeouts (a controller asking for one-byte chunks).  :meth:`PanelController.flash` reports success
only when the record read back from the controller is byte-for-byte the record it meant to
write, and refuses (before writing anything) a profile made for another panel than the one the
controller reports.

Protocol 1.1 controllers identify a record by the CRC-32 of its bytes 0..123 (its stored CRC)
in BEGIN_WRITE and VERIFY.  A 1.0 controller (its IDENTIFY reply ends after the serial number)
computes both over all 128 bytes, which for every valid record is the constant
:data:`~.record.LEGACY_CRC_RESIDUE`: the host then sends the CRC that firmware expects,
requires VERIFY to answer that constant, identifies the record by the bytes it reads back, and
checks the panel against the record the controller already holds (1.0 does not report it).
"""

from __future__ import annotations

import dataclasses
import functools
import random
import time
from typing import Callable

from ..core.errors import DeviceProtocolError, DeviceTimeoutError, ProfileError
from ..core.profile import PanelProfile
from .framing import MAX_FRAME, REPLY_BIT, FrameParser, encode_frame
from .protocol import (BEGIN_WRITE, CHUNK_HEADER, STATUS_HELP, VERIFY_REPLY, Command,
                       Identity, PanelGeometry, Status, panel_mismatches, status_name)
from .record import (LAST_SEQUENCE, LAYOUT_VERSION, LEGACY_CRC_RESIDUE, RECORD_SIZE, CalibrationRecord,
                     check_storable, decode_record, encode_record, next_sequence, record_crc, record_from_profile,
                     unstorable_field, wire_crc)
from .transports import open_transport
from .deadline import Deadline
from .transports.base import Transport

Progress = Callable[[int, int], None]
Warn = Callable[[str], None]
CONVERSATION_TIMEOUTS = 10  # an operation's deadline: this many command timeouts per attempt a request may make


def conversation(method):
    """A public operation of :class:`PanelController`: every request it makes shares one deadline,
    :meth:`~PanelController.conversation_s` from its start (an operation called inside another
    runs under the outer one's)."""

    @functools.wraps(method)
    def run(self, *args, **kwargs):
        if self.deadline.ends is None:
            self._operation = method.__name__
        with self.deadline.running(self.conversation_s()):
            return method(self, *args, **kwargs)

    return run


@dataclasses.dataclass(frozen=True)
class FlashResult:
    """A verified flash: the record now current on the controller, and in which slot."""

    record: CalibrationRecord
    slot: int
    retries: int


@dataclasses.dataclass(frozen=True)
class CurrentRecord:
    """The controller's current record: ``slot``, ``record``, its identity ``crc`` (CRC-32 of
    bytes 0..123), and whether the controller itself reported that CRC (``crc_from_device``:
    protocol 1.1) or the host computed it from the bytes read back (1.0 firmware)."""

    slot: int
    record: CalibrationRecord
    crc: int
    crc_from_device: bool


@dataclasses.dataclass(frozen=True)
class VerifyResult:
    """``matches`` when the device holds ``profile``; ``differences`` lists field: device vs file."""

    matches: bool
    differences: tuple[str, ...]
    record: CalibrationRecord


class PanelController:
    """One controller reached through ``transport`` (opened).  Use as a context manager."""

    def __init__(self, transport: Transport, *, retries: int | None = None):
        self.transport = transport
        family = transport.family
        self.retries = family.retries if retries is None else retries
        self.command_timeout = family.command_timeout_s
        self.flash_timeout = family.flash_timeout_s
        self._parser = FrameParser()
        self._seq = random.randrange(256)  # a fresh session never matches an old session's replies
        self.deadline = Deadline()  # of the operation in progress
        self._operation = ""  # its name, for the timeout's message
        self.resends = 0       # requests sent again after a timeout or a corrupt/stale reply
        self.discarded = 0     # frames thrown away (wrong SEQ/command, or corrupt)

    @classmethod
    def open(cls, url: str, **kwargs) -> "PanelController":
        return cls(open_transport(url), **kwargs)

    @property
    def url(self) -> str:
        return str(self.transport.url)

    def close(self) -> None:
        self.transport.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def conversation_s(self) -> float:
        """Seconds one operation may take in all: :data:`CONVERSATION_TIMEOUTS` x (``retries`` + 1)
        command timeouts and 2 flash timeouts (BEGIN_WRITE and COMMIT wait for the flash)."""
        return CONVERSATION_TIMEOUTS * (self.retries + 1) * self.command_timeout + 2 * self.flash_timeout

    def _check_deadline(self, command: Command) -> None:
        if not self.deadline.passed():
            return
        raise DeviceTimeoutError(f"{self._operation} did not finish within {self.conversation_s():g} s "
                                 f"({CONVERSATION_TIMEOUTS} x {self.retries + 1} attempts x the "
                                 f"{self.command_timeout:g} s command timeout + 2 x the {self.flash_timeout:g} s "
                                 f"flash timeout; it was at {command.name})", source=self.url,
                                 hint="the controller answers too slowly: check the cable and that nothing else "
                                      "uses the port; a controller in order answers in milliseconds")

    # --- one request ---

    def request(self, command: Command, payload: bytes = b"", *, timeout: float | None = None,
                accept: tuple[Status, ...] = (Status.OK,)) -> tuple[Status, bytes]:
        """Send one request and return (status, reply body after the status byte).

        Raises DeviceTimeoutError after ``retries`` resends without a valid reply, or within
        ``timeout`` when the controller keeps sending unasked (the input is never drained), and
        DeviceProtocolError for a status not in ``accept``.
        """
        timeout = self.command_timeout if timeout is None else timeout
        self._seq = (self._seq + 1) & 0xFF
        seq = self._seq
        frame = encode_frame(command, seq, payload)
        self.transport.discard_input(timeout)  # bounded too: a controller that never stops talking fails here
        self._parser.reset()
        errors_before = self._parser.errors
        for attempt in range(self.retries + 1):
            self._check_deadline(command)
            if attempt:
                self.resends += 1
            self.transport.write(frame)
            deadline = self.deadline.wait_end(timeout)
            while True:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                for reply in self._parser.feed(self.transport.read(MAX_FRAME, left)):
                    if reply.cmd != (command | REPLY_BIT) or reply.seq != seq or not reply.payload:
                        self.discarded += 1
                        continue
                    code = reply.payload[0]
                    self.discarded += self._parser.errors - errors_before
                    if code not in [int(s) for s in accept]:
                        raise self._status_error(command, code)
                    return Status(code), reply.payload[1:]
        self.discarded += self._parser.errors - errors_before
        self._check_deadline(command)
        raise DeviceTimeoutError(f"no valid reply to {command.name} within {timeout:g} s "
                                 f"({self.retries + 1} attempts)", source=self.url,
                                 hint="check the cable, the URL and that the controller is powered")

    def _status_error(self, command: Command, code: int) -> DeviceProtocolError:
        try:
            hint = STATUS_HELP.get(Status(code))
        except ValueError:
            hint = "unknown status code: update lenticalib"
        return DeviceProtocolError(f"{command.name} refused by the controller: {status_name(code)}",
                                   source=self.url, hint=hint, code=code)

    # --- commands ---

    @conversation
    def identify(self) -> Identity:
        _, body = self.request(Command.IDENTIFY)
        try:
            return Identity.unpack(body)
        except ValueError as exc:
            raise DeviceProtocolError(f"malformed IDENTIFY reply: {exc}", source=self.url) from None

    @conversation
    def current(self, identity: Identity) -> CurrentRecord | None:
        """The current record and its identity CRC, cross-checked with VERIFY; None when none.

        Raises DeviceProtocolError when VERIFY's CRC does not identify the record read back (a
        1.1 controller answering another CRC, e.g. the constant of 1.0) or, for a 1.0 controller,
        is not the constant that firmware answers for every valid record.
        """
        raw = self.read_raw_record()
        check = self.verify_crc()
        if raw is None or check is None:
            if raw is None and check is None:
                return None
            raise DeviceProtocolError("READ_RECORD and VERIFY disagree on whether the panel holds a record",
                                      source=self.url, hint="run the command again")
        record = decode_record(raw, self.url)
        expected = wire_crc(raw, identity.protocol_minor)
        if check[2] != expected or check[1] != record.sequence:
            raise DeviceProtocolError(self._crc_complaint(identity, check[2], expected), source=self.url,
                                      hint="run the command again; if it persists, the controller's firmware "
                                           "is faulty")
        return CurrentRecord(check[0], record, record_crc(raw), identity.protocol_minor >= 1)

    @staticmethod
    def _crc_complaint(identity: Identity, got: int, expected: int) -> str:
        if identity.protocol_minor >= 1 and got == LEGACY_CRC_RESIDUE:
            return (f"VERIFY answers CRC-32 {got:08x}, the constant every valid record gives over all 128 bytes, "
                    f"not the record's CRC {expected:08x}: the controller claims protocol {identity.version} "
                    "but computes its CRCs as 1.0 firmware did, so it cannot tell records apart")
        return f"VERIFY reports CRC-32 {got:08x} and another sequence or record than read back ({expected:08x})"

    @conversation
    def read_raw_record(self) -> bytes | None:
        """The current record's 128 bytes as the controller sends them, or None when it holds none."""
        status, body = self.request(Command.READ_RECORD, accept=(Status.OK, Status.NO_RECORD))
        if status is Status.NO_RECORD:
            return None
        if len(body) != 1 + RECORD_SIZE:
            raise DeviceProtocolError(f"READ_RECORD returned {len(body)} bytes, expected {1 + RECORD_SIZE}",
                                      source=self.url)
        return body[1:]

    @conversation
    def read_record(self) -> CalibrationRecord | None:
        """The current record, decoded and checked, or None when the controller holds none."""
        raw = self.read_raw_record()
        return None if raw is None else decode_record(raw, self.url)

    def _require_record(self) -> CalibrationRecord:
        record = self.read_record()
        if record is None:
            raise DeviceProtocolError("the panel holds no calibration record", source=self.url,
                                      hint="flash one with 'lenticalib device flash URL profile.json'",
                                      code=int(Status.NO_RECORD))
        return record

    @conversation
    def read_profile(self) -> PanelProfile:
        return self._require_record().to_profile(device_url=self.url)

    @conversation
    def verify_crc(self) -> tuple[int, int, int] | None:
        """(slot, sequence, CRC-32) of the current record, or None when there is none."""
        status, body = self.request(Command.VERIFY, accept=(Status.OK, Status.NO_RECORD))
        if status is Status.NO_RECORD:
            return None
        if len(body) != VERIFY_REPLY.size:
            raise DeviceProtocolError("malformed VERIFY reply", source=self.url)
        return VERIFY_REPLY.unpack(body)

    @conversation
    def reboot(self) -> None:
        self.request(Command.REBOOT)

    @conversation
    def flash(self, profile: PanelProfile, progress: Progress | None = None, *, force: bool = False,
              warn: Warn | None = None, source: str = "profile") -> FlashResult:
        """Write ``profile`` as the next record; success only after a byte-exact read-back.

        Steps: IDENTIFY (serial, layout, chunk size, panel), VERIFY (current sequence s, the new
        record's is s + 1 modulo 2**32; a 1.0 controller also READ_RECORD, its record standing in
        for the panel it does not report),
        the panel check, BEGIN_WRITE (erases the inactive slot), WRITE_CHUNK x n, COMMIT
        (firmware checks and activates), READ_RECORD and VERIFY (the host compares).
        ``progress(done, total)`` after each write step.

        A profile with a field the record cannot hold (a cell layout, reversed views, flipped
        images: :func:`~.record.check_storable`) is refused with a ProfileError naming ``source``
        and the field before anything is sent, ``force`` or not.
        A profile made for another panel (size, subpixel order, view count) is refused with a
        ProfileError naming ``source`` and both values before anything is written; ``force``
        flashes it anyway (panel bring-up) and says so through ``warn(line)``, which also hears
        when a 1.0 controller gives nothing to check against.
        """
        check_storable(profile, source)  # a field the record cannot hold: refused before anything is sent
        resends_before = self.resends
        identity = self.identify()
        self._check_identity(identity)
        chunk = max(1, min(identity.max_chunk, 64))
        if identity.panel is not None:
            current = self.verify_crc()
            self._check_panel(profile, identity.panel, f"the panel of {self.url}", "panel", force, warn, source)
        else:  # 1.0: no panel reported; the record it holds was made for its panel
            held = self._legacy_record()
            current = self.verify_crc()
            if held is not None:
                panel = PanelGeometry(held.width, held.height, held.subpixel_order, (held.views,))
                self._check_panel(profile, panel, f"the record held by {self.url} (protocol {identity.version} "
                                  "firmware does not report its panel)", "record", force, warn, source)
            elif warn:
                warn(f"{self.url}: protocol {identity.version} firmware does not report its panel and holds no "
                     f"record, so the profile's {profile.width}x{profile.height} panel cannot be checked")
        sequence = next_sequence(current[1]) if current else 1  # 0xFFFFFFFF is followed by 0
        record = record_from_profile(profile, serial=identity.serial, sequence=sequence)
        data = encode_record(record)
        crc = wire_crc(data, identity.protocol_minor)
        offsets = list(range(0, RECORD_SIZE, chunk))
        total = len(offsets) + 4
        done = 0

        def step():
            nonlocal done
            done += 1
            if progress:
                progress(done, total)

        try:
            self.request(Command.BEGIN_WRITE, BEGIN_WRITE.pack(LAYOUT_VERSION, RECORD_SIZE, crc, sequence),
                         timeout=self.flash_timeout)
        except DeviceProtocolError as exc:
            if exc.code == Status.STALE_SEQUENCE and current and current[1] == LAST_SEQUENCE:
                raise DeviceProtocolError(
                    f"BEGIN_WRITE refused by the controller: STALE_SEQUENCE: its record sequence reached "
                    f"0x{LAST_SEQUENCE:08X} and its firmware does not accept the next one, 0 (it predates sequence "
                    "wrap-around, drivers/protocol-v1.md section 4.1)", source=self.url,
                    hint="update the controller's firmware; the panel keeps its record", code=exc.code) from None
            raise
        step()
        for offset in offsets:
            self.request(Command.WRITE_CHUNK, CHUNK_HEADER.pack(offset) + data[offset:offset + chunk])
            step()
        try:
            self.request(Command.COMMIT, timeout=self.flash_timeout)
        except DeviceProtocolError as exc:
            # A COMMIT whose reply was lost and whose retry found the session already closed
            # (BAD_STATE) may have succeeded: the read-back below decides, nothing else.
            if exc.code != Status.BAD_STATE:
                raise
        step()
        back = self.read_raw_record()
        step()
        if back != data:
            raise DeviceProtocolError("flash verification failed: the record read back differs from the one "
                                      "written", source=self.url,
                                      hint="the panel keeps its previous record; flash again")
        check = self.verify_crc()
        step()
        if check is None or check[2] != crc or check[1] != sequence:
            got, reason = "no record", ""
            if check is not None:
                got = f"CRC-32 {check[2]:08x}, sequence {check[1]}"
                if check[2] == LEGACY_CRC_RESIDUE != crc:
                    reason = "; " + self._crc_complaint(identity, check[2], crc)
            raise DeviceProtocolError(f"flash verification failed: VERIFY reports {got}, expected CRC-32 "
                                      f"{crc:08x}, sequence {sequence}{reason}", source=self.url,
                                      hint="do not trust this controller's record; read it back with "
                                           "'lenticalib device read' and flash again")
        return FlashResult(decode_record(back, self.url), check[0], self.resends - resends_before)

    def _check_identity(self, identity: Identity) -> None:
        if LAYOUT_VERSION != identity.layout_version:
            raise DeviceProtocolError(f"controller uses record layout {identity.layout_version}, lenticalib "
                                      f"writes {LAYOUT_VERSION}", source=self.url,
                                      hint="update lenticalib or the controller firmware")
        if identity.record_size != RECORD_SIZE:
            raise DeviceProtocolError(f"controller record size {identity.record_size} != {RECORD_SIZE}",
                                      source=self.url)
        if not (identity.serial.isascii() and identity.serial.isprintable() and len(identity.serial) <= 16):
            raise DeviceProtocolError(f"the controller reports an unusable serial number {identity.serial!r}",
                                      source=self.url, hint="the record stores up to 16 printable ASCII "
                                      "characters; check the controller's factory data")

    def _legacy_record(self) -> CalibrationRecord | None:
        """The record a 1.0 controller holds, or None (none, or one that does not decode)."""
        try:
            return self.read_record()
        except DeviceProtocolError as exc:
            if exc.code is not None:  # the controller refused READ_RECORD: a real error
                raise
            return None  # a corrupt record tells nothing about the panel; flashing replaces it

    def _check_panel(self, profile: PanelProfile, panel: PanelGeometry, what: str, other: str, force: bool,
                     warn: Warn | None, source: str) -> None:
        mismatches = panel_mismatches(profile, panel, other)
        if not mismatches:
            return
        text = f"made for another panel than {what}: {'; '.join(mismatches)}"
        if not force:
            raise ProfileError(text, source=source, hint="flash a profile calibrated on this panel, or use "
                                                         "`force` for panel bring-up")
        if warn:
            warn(f"{source}: {text}; flashing anyway (forced)")

    @conversation
    def verify(self, profile: PanelProfile) -> VerifyResult:
        """Does the controller hold ``profile``'s routing constants exactly?"""
        record = self._require_record()
        held = record.to_profile()
        differences = tuple(f"{key}: device {getattr(held, key)!r}, file {getattr(profile, key)!r}"
                            for key in ("views", "slant", "period", "offset", "reference_view", "width",
                                        "height", "subpixel_order")
                            if getattr(held, key) != getattr(profile, key))
        field = unstorable_field(profile)  # the record cannot hold it, so the device does not
        if field is not None:
            shown = profile.layout_name if field == "subpixel_layout" else getattr(profile, field)
            differences += (f"{field}: device none (the record cannot hold it), file {shown}",)
        return VerifyResult(not differences, differences, record)

