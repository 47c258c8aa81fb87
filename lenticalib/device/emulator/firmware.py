"""The panel controller's firmware, emulated byte for byte (protocol v1).

:class:`Firmware` takes the raw bytes the host sends (:meth:`receive`) and returns the reply
frames.  It keeps the calibration in two flash slots (:mod:`.flash`): a write erases and
fills the *inactive* slot, COMMIT reads the slot back, checks its CRC-32 against the one
announced in BEGIN_WRITE and every field's range, and only then programs the slot's commit
word.  At boot the valid committed slot with the newer sequence number is current; a blank,
half-written or corrupt slot is simply not valid, so it never hides the good one.  "Newer" is
serial-number arithmetic modulo 2**32 (:func:`~lenticalib.device.record.sequence_newer`), so the
record after 0xFFFFFFFF is 0 and flashing never ends; protocol 1.0 firmware compared plain
integers (``newer = a > b``) and so refuses every flash once its record reached 0xFFFFFFFF.

A repeated request (same SEQ, same CMD and payload as the last one, i.e. a host retry after a
lost reply) is answered from the cached reply without executing it again.

``protocol_minor`` picks the firmware generation: 1 (current, protocol 1.1) identifies records
by the CRC-32 of bytes 0..123, reports its panel in IDENTIFY and wraps the record sequence; 0
behaves as 1.0 firmware did (CRC-32 over all 128 bytes, a constant for valid records; no panel in
IDENTIFY; plain sequence comparison), so the host's fallback for old controllers is tested
against it.
"""

from __future__ import annotations

import operator
import struct

from ..framing import REPLY_BIT, Frame, FrameParser, encode_frame
from ..protocol import (BEGIN_WRITE, CAP_READ_BACK_COMMIT, CAP_TWO_SLOTS, CHUNK_HEADER, MAX_CHUNK,
                        PROTOCOL_MINOR, PROTOCOL_VERSION, SLOT_SEQUENCE, VERIFY_REPLY, Command, Identity,
                        PanelGeometry, Status)
from ..record import (KNOWN_LAYOUT_VERSIONS, LAYOUT_VERSION, RECORD_SIZE, RecordFormatError, parse_record,
                      sequence_newer, wire_crc)
from .flash import SLOT_COUNT, FlashImage

COMMIT_WORD = 0x4C43_4D54  # b"TMCL" little-endian; programmed over the erased 0xFFFFFFFF
COMMIT_OFFSET = RECORD_SIZE
_WORD = struct.Struct("<I")


class Firmware:
    """Controller state over one :class:`FlashImage` (closed by the caller), driving ``panel``."""

    def __init__(self, flash: FlashImage, panel: PanelGeometry, *, protocol_minor: int = PROTOCOL_MINOR,
                 max_chunk: int = MAX_CHUNK):
        if protocol_minor not in (0, 1):
            raise ValueError(f"protocol minor version {protocol_minor} is not 0 or 1")
        if not 1 <= max_chunk <= MAX_CHUNK:
            raise ValueError(f"must be 1..{MAX_CHUNK} bytes, got {max_chunk}")
        self.max_chunk = max_chunk  # WRITE_CHUNK's largest data, as IDENTIFY reports it
        self.flash = flash
        self.panel = panel
        self.protocol_minor = protocol_minor
        self.newer = sequence_newer if protocol_minor >= 1 else operator.gt  # is sequence a newer than b?
        self.parser = FrameParser()
        self.boot()

    def boot(self) -> None:
        """Reset RAM state and find the current record in flash (as after power-on)."""
        self.parser.reset()
        self.session: dict | None = None
        self.last: tuple[int, int, bytes, bytes] | None = None  # seq, cmd, payload, reply
        self.current_slot: int | None = None
        self.current_sequence = 0
        for slot in range(SLOT_COUNT):
            sequence = self._valid_sequence(slot)
            if sequence is not None and (self.current_slot is None or self.newer(sequence, self.current_sequence)):
                self.current_slot, self.current_sequence = slot, sequence

    def _valid_sequence(self, slot: int) -> int | None:
        raw = self.flash.read_slot(slot, 0, RECORD_SIZE + 4)
        if _WORD.unpack_from(raw, COMMIT_OFFSET)[0] != COMMIT_WORD:
            return None
        try:
            return parse_record(raw[:RECORD_SIZE]).sequence
        except RecordFormatError:
            return None

    @property
    def identity(self) -> Identity:
        return Identity(PROTOCOL_VERSION, LAYOUT_VERSION, CAP_TWO_SLOTS | CAP_READ_BACK_COMMIT,
                        self.max_chunk, RECORD_SIZE, self.flash.model, self.flash.firmware_version,
                        self.flash.serial, self.protocol_minor, self.panel if self.protocol_minor else None)

    def receive(self, data: bytes) -> list[bytes]:
        """Feed host bytes; return the encoded reply frames (may raise flash.PowerCut)."""
        replies = []
        for frame in self.parser.feed(data):
            if frame.is_reply:
                continue  # our own echo or garbage that parsed: never answered
            replies.append(self.handle(frame))
        return replies

    def handle(self, frame: Frame) -> bytes:
        last = self.last
        if last is not None and last[:3] == (frame.seq, frame.cmd, frame.payload):
            return last[3]
        reboot = False
        try:
            command = Command(frame.cmd)
        except ValueError:
            status, body = Status.UNKNOWN_COMMAND, b""
        else:
            status, body = getattr(self, "_" + command.name.lower())(frame.payload)
            reboot = command is Command.REBOOT and status is Status.OK
        reply = encode_frame(frame.cmd | REPLY_BIT, frame.seq, bytes([status]) + body)
        self.last = (frame.seq, frame.cmd, frame.payload, reply)
        if reboot:
            self.boot()
        return reply

    # --- commands: each takes the request payload, returns (status, reply body) ---

    def _identify(self, payload: bytes):
        if payload:
            return Status.BAD_FRAME, b""
        return Status.OK, self.identity.pack()

    def _read_record(self, payload: bytes):
        if payload:
            return Status.BAD_FRAME, b""
        if self.current_slot is None:
            return Status.NO_RECORD, b""
        return Status.OK, bytes([self.current_slot]) + self.flash.read_slot(self.current_slot, 0, RECORD_SIZE)

    def _verify(self, payload: bytes):
        if payload:
            return Status.BAD_FRAME, b""
        if self.current_slot is None:
            return Status.NO_RECORD, b""
        raw = self.flash.read_slot(self.current_slot, 0, RECORD_SIZE)
        return Status.OK, VERIFY_REPLY.pack(self.current_slot, self.current_sequence,
                                            wire_crc(raw, self.protocol_minor))

    def _begin_write(self, payload: bytes):
        self.session = None  # a new BEGIN_WRITE, even a refused one, ends any earlier session
        if len(payload) != BEGIN_WRITE.size:
            return Status.BAD_FRAME, b""
        layout, length, crc, sequence = BEGIN_WRITE.unpack(payload)
        if layout not in KNOWN_LAYOUT_VERSIONS:
            return Status.BAD_LAYOUT, b""
        if length != RECORD_SIZE:
            return Status.BAD_LENGTH, b""
        if self.current_slot is not None and not self.newer(sequence, self.current_sequence):
            return Status.STALE_SEQUENCE, b""
        slot = 0 if self.current_slot is None else 1 - self.current_slot
        self.flash.erase_slot(slot)
        self.session = {"slot": slot, "crc": crc, "sequence": sequence, "written": 0}
        return Status.OK, bytes([slot])

    def _write_chunk(self, payload: bytes):
        if len(payload) < CHUNK_HEADER.size + 1 or len(payload) > CHUNK_HEADER.size + self.max_chunk:
            return Status.BAD_FRAME, b""
        if self.session is None:
            return Status.BAD_STATE, b""
        (offset,), data = CHUNK_HEADER.unpack_from(payload), payload[CHUNK_HEADER.size:]
        session = self.session
        if offset + len(data) > RECORD_SIZE:
            return Status.BAD_OFFSET, b""
        if offset < session["written"]:
            same = self.flash.read_slot(session["slot"], offset, len(data)) == data
            return (Status.OK if same else Status.BAD_OFFSET), b""
        if offset != session["written"]:
            return Status.BAD_OFFSET, b""
        self.flash.program(session["slot"], offset, data)
        session["written"] = offset + len(data)
        return Status.OK, b""

    def _commit(self, payload: bytes):
        if payload:
            return Status.BAD_FRAME, b""
        session = self.session
        if session is None or session["written"] != RECORD_SIZE:
            return Status.BAD_STATE, b""
        slot = session["slot"]
        self.session = None  # committed or refused, the staged slot is not written to again
        raw = self.flash.read_slot(slot, 0, RECORD_SIZE)
        if wire_crc(raw, self.protocol_minor) != session["crc"]:
            return Status.CRC_MISMATCH, b""
        try:
            record = parse_record(raw)
        except RecordFormatError as exc:
            return Status[exc.status], b""
        if record.sequence != session["sequence"]:
            return Status.BAD_RECORD, b""
        self.flash.program(slot, COMMIT_OFFSET, _WORD.pack(COMMIT_WORD))
        if self._valid_sequence(slot) != record.sequence:
            return Status.FLASH_ERROR, b""
        self.current_slot, self.current_sequence = slot, record.sequence
        return Status.OK, SLOT_SEQUENCE.pack(slot, record.sequence)

    def _reboot(self, payload: bytes):
        if payload:
            return Status.BAD_FRAME, b""
        return Status.OK, b""
