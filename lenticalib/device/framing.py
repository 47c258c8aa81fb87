"""Protocol v1 frames and the stream parser shared by the host and the emulated firmware.

A frame (``drivers/protocol-v1.md`` section 2), every multi-byte field little-endian:

    SOF 0xA5 | LEN u16 | CMD u8 | SEQ u8 | PAYLOAD (LEN bytes, 0..MAX_PAYLOAD) | CRC u16

CRC is CRC-16/CCITT-FALSE (polynomial 0x1021, initial 0xFFFF, as ``binascii.crc_hqx``) over
LEN, CMD, SEQ and PAYLOAD.  A reply's CMD is the request's CMD with bit 7 set, its SEQ the
request's SEQ, and its payload starts with a status byte.

:class:`FrameParser` takes bytes in any pieces (a serial stream, HID report fragments, USB
control-transfer data) and yields whole frames; garbage, truncated or corrupt frames are
skipped by resynchronising on the next SOF, so nothing a link does can make it raise or grow
without bound.
"""

from __future__ import annotations

import binascii
import dataclasses
import struct

SOF = 0xA5
HEADER = struct.Struct("<BHBB")  # SOF, LEN, CMD, SEQ
MAX_PAYLOAD = 200
OVERHEAD = HEADER.size + 2
MAX_FRAME = MAX_PAYLOAD + OVERHEAD
REPLY_BIT = 0x80


@dataclasses.dataclass(frozen=True)
class Frame:
    """One decoded frame: ``cmd`` (u8), ``seq`` (u8) and ``payload`` (bytes)."""

    cmd: int
    seq: int
    payload: bytes = b""

    @property
    def is_reply(self) -> bool:
        return bool(self.cmd & REPLY_BIT)


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of ``data``."""
    return binascii.crc_hqx(data, 0xFFFF)


def encode_frame(cmd: int, seq: int, payload: bytes = b"") -> bytes:
    """The bytes of one frame; raises ValueError for a payload over MAX_PAYLOAD."""
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    head = HEADER.pack(SOF, len(payload), cmd & 0xFF, seq & 0xFF)
    body = head[1:] + payload
    return head + payload + struct.pack("<H", crc16(body))


class FrameParser:
    """Incremental frame parser with resynchronisation.

    ``feed(data)`` returns the frames completed by ``data``.  ``errors`` counts discarded
    frames (bad CRC or impossible length); the buffer never holds more than MAX_FRAME bytes.
    """

    def __init__(self):
        self._buffer = bytearray()
        self.errors = 0

    def reset(self) -> None:
        self._buffer.clear()

    def feed(self, data: bytes) -> list[Frame]:
        buf = self._buffer
        buf += data
        frames: list[Frame] = []
        while True:
            start = buf.find(SOF)
            if start < 0:
                buf.clear()
                break
            if start:
                del buf[:start]
            if len(buf) < 3:
                break
            length = buf[1] | (buf[2] << 8)
            if length > MAX_PAYLOAD:
                self.errors += 1
                del buf[:1]
                continue
            total = length + OVERHEAD
            if len(buf) < total:
                break
            crc = buf[total - 2] | (buf[total - 1] << 8)
            if crc16(bytes(buf[1:total - 2])) != crc:
                self.errors += 1
                del buf[:1]
                continue
            frames.append(Frame(buf[3], buf[4], bytes(buf[5:total - 2])))
            del buf[:total]
        return frames
