"""The calibration record: the binary form of a panel profile kept in the controller's flash.

Layout version 1, 128 bytes, little-endian (``drivers/protocol-v1.md`` section 4 is the
normative table; this module and the emulated firmware both implement it):

    offset size  field
         0    4  magic b"LTCR"
         4    2  layout_version (u16) = 1
         6    2  record_size (u16) = 128
         8    4  sequence (u32): 1 for the first record, +1 modulo 2**32 for each flash;
                 the newer by serial-number arithmetic wins (:func:`sequence_newer`)
        12   16  serial (ASCII, NUL-padded): the panel's serial number
        28    2  width (u16, pixels, 1..65535)
        30    2  height (u16, pixels, 1..65535)
        32    2  views N (u16, 2..254)
        34    1  subpixel_order (u8): 0 = RGB, 1 = BGR
        35    1  flags (u8): bit 0 = the four sigmas below are present
        36    8  slant C_r (f64, pixels per row)
        44    8  period Delta_r (f64, subpixels)
        52    8  offset s_ref (f64, subpixels)
        60    8  reference_view i_ref (f64, views)
        68   16  1-sigma of slant, period, offset, reference_view (4 x f32, >= 0)
        84    8  written (u64): Unix time in seconds when the host built the record
        92    8  profile digest: first 8 bytes of SHA-256 of the routing constants
       100   24  reserved, zero
       124    4  CRC-32 (IEEE 802.3, as zlib.crc32) of bytes 0..123

Floats are stored as f64 so a profile survives the round trip exactly.  A profile's
``view_direction`` is *not* stored: layout 1 has no field for it, and its spare space cannot
take it without breaking older peers -- bits 1..7 of ``flags`` and the reserved bytes must be
zero, which every layout-1 firmware checks (COMMIT answers OUT_OF_RANGE; at boot such a slot is
invalid) and every released host checks when it reads a record (it refuses the record).  A
profile read from a panel therefore has ``view_direction`` None (unknown).  The constants' ranges
(views, width, height, slant, period, offset, reference view) are those of every profile,
:func:`lenticalib.core.profile.constants_problem`; this module adds only what the encoding itself
needs (16-bit sizes, f32 sigmas, the serial's 16 ASCII bytes, 32/64-bit counters).

Nor can layout 1 hold a profile's subpixel cell layout (``subpixel_layout``), reversed views
(``views_reversed``) or mirrored view images (``flip_image_x``, ``flip_image_y``), for the same
reason: a controller would route such a panel as a plain stripe.  The host refuses to flash such
a profile, in one line naming the field, before it talks to the controller
(:func:`check_storable`).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import hashlib
import math
import struct
import time
import zlib

from ..core.errors import DeviceProtocolError, ProfileError
from ..core.profile import (MAX_VIEWS, OFFSET_LIMIT, PERIOD_LIMIT, REFERENCE_VIEW_LIMIT,  # noqa: F401 (re-exported)
                       SLANT_LIMIT, PanelProfile, constants_problem, make_provenance)

MAGIC = b"LTCR"
LAYOUT_VERSION = 1
KNOWN_LAYOUT_VERSIONS = (1,)
RECORD_SIZE = 128
SERIAL_BYTES = 16
FLAG_SIGMAS = 0x01
KNOWN_FLAGS = FLAG_SIGMAS

_STRUCT = struct.Struct("<4sHHI16sHHHBBddddffffQ8s24s")
_CRC_OFFSET = RECORD_SIZE - 4
assert _STRUCT.size == _CRC_OFFSET

F32_MAX = 3.0e38  # sigmas are stored as f32
_ORDERS = ("RGB", "BGR")
_SIGMA_KEYS = ("slant", "period", "offset", "reference_view")


class RecordRangeError(ValueError):
    """A record field outside its allowed range; ``field`` names it."""

    def __init__(self, field: str, message: str):
        super().__init__(f"field '{field}': {message}")
        self.field = field


@dataclasses.dataclass(frozen=True)
class CalibrationRecord:
    """The decoded fields of one record (units as in the module docstring)."""

    sequence: int
    serial: str
    width: int
    height: int
    views: int
    subpixel_order: str
    slant: float
    period: float
    offset: float
    reference_view: float
    sigmas: tuple[float, float, float, float] | None = None
    written: int = 0
    digest: bytes = b"\0" * 8
    layout_version: int = LAYOUT_VERSION

    @property
    def written_iso(self) -> str | None:
        """``written`` as an ISO 8601 UTC time (seconds), or None when the record has none (0)."""
        if not self.written:
            return None
        try:
            return _dt.datetime.fromtimestamp(self.written, _dt.timezone.utc).isoformat(timespec="seconds")
        except (OverflowError, OSError, ValueError):
            return None

    def to_profile(self, *, device_url: str | None = None) -> PanelProfile:
        """The record as a :class:`PanelProfile`, with the provenance of a read from ``device_url``.

        Provenance: ``method`` "read from device", ``created`` the record's ``written`` time
        (when the host built it, ISO 8601 UTC), ``read`` the time of this read,
        ``lenticalib_version`` of the reader, the device URL, the panel serial and the record's
        sequence number.  ``view_direction`` is None: the record does not hold it (module docstring).
        """
        uncertainty = dict(zip(_SIGMA_KEYS, self.sigmas)) if self.sigmas else None
        prov = make_provenance("read from device", device_url=device_url, panel_serial=self.serial,
                               record_sequence=self.sequence)
        prov["read"] = prov["created"]
        prov["created"] = self.written_iso
        return PanelProfile(views=self.views, slant=self.slant, period=self.period, offset=self.offset,
                            reference_view=self.reference_view, width=self.width, height=self.height,
                            subpixel_order=self.subpixel_order, uncertainty=uncertainty, provenance=prov)


# Profile fields record layout 1 has no room for, and what each means (module docstring).
UNSTORABLE_FIELDS = {"subpixel_layout": "a subpixel cell layout", "views_reversed": "reversed views",
                     "flip_image_x": "mirrored view images", "flip_image_y": "mirrored view images"}


def unstorable_field(profile: PanelProfile) -> str | None:
    """The first field of ``profile`` that record layout 1 cannot hold (:data:`UNSTORABLE_FIELDS`), else None."""
    if profile.subpixel_layout is not None:
        return "subpixel_layout"
    return next((key for key in ("views_reversed", "flip_image_x", "flip_image_y") if getattr(profile, key)), None)


def check_storable(profile: PanelProfile, source: str = "profile") -> None:
    """ProfileError naming ``source`` and the field when ``profile`` uses one that record layout 1
    cannot hold: a controller would route the panel as a plain stripe."""
    field = unstorable_field(profile)
    if field is None:
        return
    layout = f" ({profile.layout_name})" if field == "subpixel_layout" else ""
    raise ProfileError(f"field '{field}': the controller's calibration record (layout {LAYOUT_VERSION}) has no room "
                       f"for {UNSTORABLE_FIELDS[field]}{layout}, so the controller would route this panel as a plain "
                       f"{profile.subpixel_order} stripe", source=source,
                       hint="drive the panel with the profile file itself (encode, show, play) instead of "
                            "flashing it")


def profile_digest(profile: PanelProfile) -> bytes:
    """First 8 bytes of SHA-256 over the routing constants (repr of each, in a fixed order)."""
    text = "|".join(repr(v) for v in profile.routing_key())
    return hashlib.sha256(text.encode()).digest()[:8]


def record_from_profile(profile: PanelProfile, *, serial: str, sequence: int,
                        written: int | None = None) -> CalibrationRecord:
    """A record carrying ``profile``; raises ProfileError naming the field if it cannot be stored."""
    check_storable(profile)
    sigmas = None
    if profile.uncertainty and all(k in profile.uncertainty for k in _SIGMA_KEYS):
        sigmas = tuple(float(profile.uncertainty[k]) for k in _SIGMA_KEYS)
    record = CalibrationRecord(
        sequence=sequence, serial=serial, width=profile.width, height=profile.height,
        views=profile.views, subpixel_order=profile.subpixel_order, slant=float(profile.slant),
        period=float(profile.period), offset=float(profile.offset),
        reference_view=float(profile.reference_view), sigmas=sigmas,
        written=int(time.time()) if written is None else written, digest=profile_digest(profile))
    try:
        check_ranges(record)
    except RecordRangeError as exc:
        raise ProfileError(f"cannot be stored in the panel: {exc}", source="profile",
                           hint="fix the profile; the ranges are in drivers/protocol-v1.md") from None
    return record


def check_ranges(record: CalibrationRecord) -> None:
    """Raise RecordRangeError for the first field outside its range (see the module docstring)."""

    def need(ok: bool, field: str, message: str):
        if not ok:
            raise RecordRangeError(field, message)

    need(0 <= record.sequence <= 0xFFFFFFFF, "sequence", "must fit in 32 bits")
    need(len(record.serial.encode("ascii", "replace")) <= SERIAL_BYTES
         and record.serial.isascii() and record.serial.isprintable(),
         "serial", f"must be printable ASCII of at most {SERIAL_BYTES} characters")
    problem = constants_problem({key: getattr(record, key) for key in
                                 ("views", "slant", "period", "offset", "reference_view", "width", "height",
                                  "subpixel_order")})
    if problem is not None:
        raise RecordRangeError(*problem)
    if record.sigmas is not None:
        for key, value in zip(_SIGMA_KEYS, record.sigmas):
            need(math.isfinite(value) and 0 <= value <= F32_MAX, f"uncertainty.{key}",
                 f"must be a number in [0, 3e38] (stored as f32), got {value!r}")
    need(0 <= record.written <= 0xFFFFFFFFFFFFFFFF, "written", "must fit in 64 bits")


SEQUENCE_MODULUS = 1 << 32
LAST_SEQUENCE = SEQUENCE_MODULUS - 1


def next_sequence(sequence: int) -> int:
    """The sequence of the record after ``sequence``: +1 modulo 2**32, so 0xFFFFFFFF is followed by 0."""
    return (sequence + 1) % SEQUENCE_MODULUS


def sequence_newer(a: int, b: int) -> bool:
    """Is record sequence ``a`` newer than ``b``?  Serial-number arithmetic (RFC 1982, 32 bits):
    ``a`` is newer when ``(a - b) mod 2**32`` is 1..2**31-1, so 0 is newer than 0xFFFFFFFF.  Equal
    sequences and sequences exactly 2**31 apart are neither (``drivers/protocol-v1.md`` 4.1)."""
    return 0 < (a - b) % SEQUENCE_MODULUS < SEQUENCE_MODULUS >> 1


# zlib.crc32 of *any* 128 bytes whose last four hold the CRC-32 of the first 124 (the CRC-32
# residue): what protocol 1.0 firmware answered in VERIFY for every valid record.
LEGACY_CRC_RESIDUE = 0x2144DF1C


def record_crc(data: bytes) -> int:
    """The record's identity: CRC-32 of bytes 0..123, i.e. the CRC it stores at 124..127.

    What protocol 1.1 announces in BEGIN_WRITE and answers in VERIFY; two records that differ
    in any byte differ here (up to CRC-32 collisions, 2**-32 for random changes).
    """
    return zlib.crc32(data[:_CRC_OFFSET])


def wire_crc(data: bytes, protocol_minor: int) -> int:
    """The CRC-32 that BEGIN_WRITE and VERIFY carry for ``data`` at this protocol minor version:
    :func:`record_crc` from 1.1 on; 1.0 firmware computes it over all 128 bytes, which for a valid
    record is always :data:`LEGACY_CRC_RESIDUE`."""
    return record_crc(data) if protocol_minor >= 1 else zlib.crc32(data)


def encode_record(record: CalibrationRecord) -> bytes:
    """The 128 bytes of ``record`` (ranges are checked first)."""
    check_ranges(record)
    sigmas = record.sigmas if record.sigmas is not None else (0.0, 0.0, 0.0, 0.0)
    body = _STRUCT.pack(MAGIC, record.layout_version, RECORD_SIZE, record.sequence,
                        record.serial.encode("ascii"), record.width, record.height, record.views,
                        _ORDERS.index(record.subpixel_order),
                        FLAG_SIGMAS if record.sigmas is not None else 0,
                        record.slant, record.period, record.offset, record.reference_view,
                        *sigmas, record.written, record.digest, b"\0" * 24)
    return body + struct.pack("<I", record_crc(body))


class RecordFormatError(ValueError):
    """Bytes that are not a valid record; ``status`` is the firmware status name that fits."""

    def __init__(self, message: str, status: str):
        super().__init__(message)
        self.status = status


def parse_record(data: bytes) -> CalibrationRecord:
    """Decode and check 128 bytes; raise RecordFormatError (never anything else) when invalid.

    Status names: ``BAD_LENGTH``, ``BAD_RECORD`` (magic or CRC), ``BAD_LAYOUT`` (unknown
    layout version), ``OUT_OF_RANGE`` (a field outside its range).
    """
    if len(data) != RECORD_SIZE:
        raise RecordFormatError(f"record is {len(data)} bytes, expected {RECORD_SIZE}", "BAD_LENGTH")
    body, (crc,) = data[:_CRC_OFFSET], struct.unpack_from("<I", data, _CRC_OFFSET)
    if body[:4] != MAGIC:
        raise RecordFormatError("no record magic (blank or foreign data)", "BAD_RECORD")
    if zlib.crc32(body) != crc:
        raise RecordFormatError("record CRC-32 does not match (corrupt or half-written)", "BAD_RECORD")
    (_, version, size, sequence, serial, width, height, views, order, flags, slant, period, offset,
     ref, s0, s1, s2, s3, written, digest, reserved) = _STRUCT.unpack(body)
    if version not in KNOWN_LAYOUT_VERSIONS:
        raise RecordFormatError(f"unknown record layout version {version}", "BAD_LAYOUT")
    if size != RECORD_SIZE:
        raise RecordFormatError(f"record_size field says {size}, expected {RECORD_SIZE}", "BAD_LAYOUT")
    if order > 1:
        raise RecordFormatError(f"field 'subpixel_order': unknown code {order}", "OUT_OF_RANGE")
    if any(reserved):
        raise RecordFormatError("field 'reserved': must be zero in layout 1", "OUT_OF_RANGE")
    if flags & ~KNOWN_FLAGS:
        raise RecordFormatError(f"field 'flags': unknown bits 0x{flags:02x}", "OUT_OF_RANGE")
    try:
        serial_text = serial.rstrip(b"\0").decode("ascii")
    except UnicodeDecodeError:
        raise RecordFormatError("field 'serial': not ASCII", "OUT_OF_RANGE") from None
    record = CalibrationRecord(sequence=sequence, serial=serial_text, width=width, height=height,
                               views=views, subpixel_order=_ORDERS[order], slant=slant, period=period,
                               offset=offset, reference_view=ref,
                               sigmas=(s0, s1, s2, s3) if flags & FLAG_SIGMAS else None,
                               written=written, digest=digest, layout_version=version)
    try:
        check_ranges(record)
    except RecordRangeError as exc:
        raise RecordFormatError(str(exc), "OUT_OF_RANGE") from None
    return record


def decode_record(data: bytes, source: str) -> CalibrationRecord:
    """:func:`parse_record` for the host: a bad record becomes a DeviceProtocolError naming ``source``."""
    try:
        return parse_record(data)
    except RecordFormatError as exc:
        raise DeviceProtocolError(f"the calibration record read back is invalid: {exc}", source=source,
                                  hint="flash a profile again with 'lenticalib device flash'") from None
