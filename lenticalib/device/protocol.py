"""Protocol v1: command codes, status codes and payload layouts (``drivers/protocol-v1.md``).

Shared by the host engine (:mod:`lenticalib.device.client`) and the emulated firmware
(:mod:`lenticalib.device.emulator.firmware`), as a real firmware and its host tool share one
header.  All multi-byte fields are little-endian.
"""

from __future__ import annotations

import dataclasses
import enum
import struct

PROTOCOL_VERSION = 1
PROTOCOL_MINOR = 1  # 1.1: CRCs identify the record, IDENTIFY reports the panel (protocol-v1.md 1.1)
MAX_CHUNK = 32  # bytes of record data per WRITE_CHUNK (one flash program operation)
MAX_VIEW_COUNTS = 32  # at most this many supported view counts in an IDENTIFY reply


class Command(enum.IntEnum):
    IDENTIFY = 0x01      # -> IdentifyReply
    READ_RECORD = 0x02   # -> slot u8, record bytes (RECORD_SIZE)
    BEGIN_WRITE = 0x03   # layout u16, length u16, crc32 u32, sequence u32 -> slot u8
    WRITE_CHUNK = 0x04   # offset u16, data (1..MAX_CHUNK) -> (nothing)
    COMMIT = 0x05        # (nothing) -> slot u8, sequence u32
    VERIFY = 0x06        # (nothing) -> slot u8, sequence u32, crc32 u32
    REBOOT = 0x07        # (nothing) -> (nothing); state is reloaded from flash


class Status(enum.IntEnum):
    OK = 0x00
    BAD_FRAME = 0x01        # request payload malformed for its command
    UNKNOWN_COMMAND = 0x02
    BAD_LENGTH = 0x03       # record length other than the layout's
    BAD_STATE = 0x04        # WRITE_CHUNK/COMMIT without BEGIN_WRITE, COMMIT before all data
    BAD_OFFSET = 0x05       # chunk not at the next offset, or past the record
    OUT_OF_RANGE = 0x06     # a record field outside its range (checked at COMMIT)
    BAD_LAYOUT = 0x07       # unknown record layout version
    CRC_MISMATCH = 0x08     # the slot read back does not match BEGIN_WRITE's CRC-32
    STALE_SEQUENCE = 0x09   # sequence not newer than the current record's (record.sequence_newer)
    NO_RECORD = 0x0A        # no valid record in either slot
    FLASH_ERROR = 0x0B      # erase or program failed
    BAD_RECORD = 0x0C       # magic or CRC wrong in the staged record


STATUS_HELP = {
    Status.BAD_FRAME: "the controller could not parse the request (host/firmware version mismatch?)",
    Status.UNKNOWN_COMMAND: "the controller's firmware does not support this command",
    Status.BAD_LENGTH: "the record length does not match the controller's layout",
    Status.BAD_STATE: "the write session was lost (controller rebooted?); flash again",
    Status.BAD_OFFSET: "a chunk arrived out of order; flash again",
    Status.OUT_OF_RANGE: "the profile holds a value the panel cannot store",
    Status.BAD_LAYOUT: "the controller does not know this record layout version; update lenticalib "
                       "or the firmware",
    Status.CRC_MISMATCH: "the data written differs from what was sent (link errors); flash again",
    Status.STALE_SEQUENCE: "another host flashed the panel meanwhile; read it and flash again",
    Status.NO_RECORD: "the panel holds no calibration yet; flash a profile",
    Status.FLASH_ERROR: "the controller's flash memory failed; the previous record is kept",
    Status.BAD_RECORD: "the staged record is corrupt; flash again",
}


def status_name(code: int) -> str:
    try:
        return Status(code).name
    except ValueError:
        return f"0x{code:02x}"


BEGIN_WRITE = struct.Struct("<HHII")     # layout_version, length, crc32, sequence
CHUNK_HEADER = struct.Struct("<H")       # offset
SLOT_SEQUENCE = struct.Struct("<BI")     # slot, sequence
VERIFY_REPLY = struct.Struct("<BII")     # slot, sequence, crc32
_IDENTIFY_FIXED = struct.Struct("<BHIHH")  # protocol, layout, capabilities, max_chunk, record_size
_IDENTIFY_PANEL = struct.Struct("<BHHBB")  # 1.1 tail: minor, width, height, subpixel order, n view counts
_ORDERS = ("RGB", "BGR")

CAP_TWO_SLOTS = 0x01
CAP_READ_BACK_COMMIT = 0x02


@dataclasses.dataclass(frozen=True)
class PanelGeometry:
    """The panel a controller drives: raster ``width`` x ``height`` in pixels, the colour at
    subpixel positions 0, 1, 2 (``subpixel_order`` "RGB" or "BGR"), and the view counts N its
    renderer supports (``view_counts``, each 2..254, ascending)."""

    width: int
    height: int
    subpixel_order: str
    view_counts: tuple[int, ...]

    def __post_init__(self):
        if not (1 <= self.width <= 0xFFFF and 1 <= self.height <= 0xFFFF):
            raise ValueError(f"panel size {self.width}x{self.height} is not 1..65535 pixels per side")
        if self.subpixel_order not in _ORDERS:
            raise ValueError(f"subpixel order {self.subpixel_order!r} is not RGB or BGR")
        if not (1 <= len(self.view_counts) <= MAX_VIEW_COUNTS and all(2 <= n <= 254 for n in self.view_counts)):
            raise ValueError(f"view counts {list(self.view_counts)} are not 1 to {MAX_VIEW_COUNTS} numbers "
                             "in 2..254")

    @property
    def size(self) -> str:
        return f"{self.width}x{self.height}"

    def describe(self) -> str:
        """e.g. ``3840x2160 RGB, 32 views``."""
        counts = ", ".join(map(str, self.view_counts))
        return f"{self.size} {self.subpixel_order}, {counts} views"


def panel_mismatches(profile, panel: PanelGeometry, other: str = "panel") -> list[str]:
    """What makes ``profile`` (a PanelProfile) unfit for ``panel``: one phrase per mismatch, naming
    both values (size, subpixel order, view count), ``other`` naming the panel's side; empty when
    it fits."""
    out = []
    if (profile.width, profile.height) != (panel.width, panel.height):
        out.append(f"profile {profile.width}x{profile.height} pixels, {other} {panel.size}")
    if profile.subpixel_order != panel.subpixel_order:
        out.append(f"profile subpixel order {profile.subpixel_order}, {other} {panel.subpixel_order}")
    if profile.views not in panel.view_counts:
        counts = ", ".join(map(str, panel.view_counts))
        out.append(f"profile {profile.views} views, " + (f"controller supports {counts}" if other == "panel"
                                                           else f"{other} {counts}"))
    return out


@dataclasses.dataclass(frozen=True)
class Identity:
    """What IDENTIFY returns: versions, capabilities, the controller's names and (1.1) its panel.

    ``protocol_minor`` is 0 for a 1.0 reply (which ends after the serial number): such a
    controller reports no ``panel`` and its CRCs are over all 128 record bytes (a constant).
    """

    protocol_version: int
    layout_version: int
    capabilities: int
    max_chunk: int
    record_size: int
    model: str
    firmware_version: str
    serial: str
    protocol_minor: int = 0
    panel: PanelGeometry | None = None

    @property
    def version(self) -> str:
        return f"{self.protocol_version}.{self.protocol_minor}"

    def pack(self) -> bytes:
        out = _IDENTIFY_FIXED.pack(self.protocol_version, self.layout_version, self.capabilities,
                                   self.max_chunk, self.record_size)
        for text in (self.model, self.firmware_version, self.serial):
            raw = text.encode("ascii")[:32]
            out += bytes([len(raw)]) + raw
        if self.protocol_minor >= 1:  # a 1.0 reply ends here
            panel = self.panel
            out += _IDENTIFY_PANEL.pack(self.protocol_minor, panel.width, panel.height,
                                        _ORDERS.index(panel.subpixel_order), len(panel.view_counts))
            out += bytes(panel.view_counts)
        return out

    @classmethod
    def unpack(cls, data: bytes) -> "Identity":
        """Decode an IDENTIFY reply body; raises ValueError when malformed.

        A reply ending after the serial number is protocol 1.0 (minor 0, no panel); bytes after
        the 1.1 tail (a later minor version's additions) are ignored.
        """
        fixed = _IDENTIFY_FIXED.size
        if len(data) < fixed:
            raise ValueError("identify reply too short")
        values = list(_IDENTIFY_FIXED.unpack_from(data))
        pos = fixed
        texts = []
        for _ in range(3):
            if pos >= len(data):
                raise ValueError("identify reply truncated")
            n = data[pos]
            raw = data[pos + 1:pos + 1 + n]
            if len(raw) != n:
                raise ValueError("identify reply truncated")
            texts.append(raw.decode("ascii", "replace"))
            pos += 1 + n
        if pos == len(data):
            return cls(*values, *texts)
        if len(data) < pos + _IDENTIFY_PANEL.size:
            raise ValueError("identify reply: panel description truncated")
        minor, width, height, order, count = _IDENTIFY_PANEL.unpack_from(data, pos)
        pos += _IDENTIFY_PANEL.size
        counts = tuple(data[pos:pos + count])
        if minor < 1 or order >= len(_ORDERS) or len(counts) != count:
            raise ValueError("identify reply: malformed panel description")
        return cls(*values, *texts, minor, PanelGeometry(width, height, _ORDERS[order], counts))
