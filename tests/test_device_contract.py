"""One contract suite over every transport: in-process serial (pyserial URL handler), HID
(hidapi-style device), USB (pyusb with the emulator backend), and real emulator processes on a
pseudo-terminal and on TCP.  Set LENTICALIB_TEST_DEVICE to a device URL to run the same cases
against real hardware (its record is read first and flashed back at the end); a Looking Glass
unit's URL there runs tests/test_looking_glass_contract.py instead."""

from __future__ import annotations

import os
import struct
import zlib

import pytest

from lenticalib.device import PanelController
from lenticalib.device.looking_glass import is_looking_glass
from lenticalib.device.protocol import BEGIN_WRITE, CHUNK_HEADER, Command, Status
from lenticalib.device.record import RECORD_SIZE, encode_record, record_crc, record_from_profile
from lenticalib.core.errors import DeviceProtocolError, ProfileError

from .device_support import emulator_process, profile_a, profile_b, same_constants

TRANSPORTS = ["emu-serial", "emu-hid", "emu-usb", "pty", "tcp"]
HARDWARE = os.environ.get("LENTICALIB_TEST_DEVICE")
if HARDWARE and not is_looking_glass(HARDWARE):  # a Looking Glass unit: tests/test_looking_glass_contract.py
    TRANSPORTS.append("hardware")


@pytest.fixture(params=TRANSPORTS)
def url(request, tmp_path, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))
    kind = request.param
    if kind.startswith("emu-"):
        yield f"emu://contract?via={kind[4:]}"
    elif kind in ("pty", "tcp"):
        with emulator_process("--transport", kind, "--flash", str(tmp_path / "c.flash")) as (_, address):
            yield address
    else:
        with PanelController.open(HARDWARE) as panel:
            original = panel.read_record()
        yield HARDWARE
        if original is not None:
            with PanelController.open(HARDWARE) as panel:
                panel.flash(original.to_profile())


def test_identify(url):
    with PanelController.open(url) as panel:
        identity = panel.identify()
    assert identity.protocol_version == 1 and identity.layout_version == 1
    assert identity.record_size == RECORD_SIZE and 1 <= identity.max_chunk <= 64 and identity.serial


def test_flash_read_verify_round_trip(url):
    with PanelController.open(url) as panel:
        for profile in (profile_a(), profile_b(), profile_a()):
            result = panel.flash(profile)
            assert panel.verify(profile).matches
            held = panel.read_profile()
            assert same_constants(held, profile)
        assert result.record.serial == panel.identify().serial
        assert result.record.sequence == panel.verify_crc()[1]


def test_verify_reports_differences(url):
    with PanelController.open(url) as panel:
        panel.flash(profile_a())
        result = panel.verify(profile_a().replace(period=19.48))
    assert not result.matches and any(d.startswith("period:") for d in result.differences)


def test_record_survives_reboot(url):
    with PanelController.open(url) as panel:
        panel.flash(profile_b())
        panel.reboot()
        assert same_constants(panel.read_profile(), profile_b())


def test_host_validates_before_writing(url):
    with PanelController.open(url) as panel:
        panel.flash(profile_a())
        before = panel.verify_crc()
        with pytest.raises(ProfileError, match="slant"):
            panel.flash(profile_a().replace(slant=7.5))
        assert panel.verify_crc() == before  # nothing was sent


def write_raw(panel: PanelController, data: bytes, *, layout: int = 1, sequence: int | None = None) -> None:
    """BEGIN_WRITE / WRITE_CHUNK / COMMIT with raw record bytes, bypassing host validation."""
    sequence = sequence if sequence is not None else (panel.verify_crc() or (0, 0))[1] + 1
    panel.request(Command.BEGIN_WRITE, BEGIN_WRITE.pack(layout, RECORD_SIZE, record_crc(data), sequence))
    for offset in range(0, RECORD_SIZE, 32):
        panel.request(Command.WRITE_CHUNK, CHUNK_HEADER.pack(offset) + data[offset:offset + 32])
    panel.request(Command.COMMIT)


def forged(field_offset: int, fmt: str, value, sequence: int) -> bytes:
    """A record with one field overwritten and a correct CRC (so only the range check can catch it)."""
    good = bytearray(encode_record(record_from_profile(profile_a(), serial="X", sequence=sequence)))
    struct.pack_into(fmt, good, field_offset, value)
    struct.pack_into("<I", good, RECORD_SIZE - 4, zlib.crc32(bytes(good[:RECORD_SIZE - 4])))
    return bytes(good)


@pytest.mark.parametrize("offset,fmt,value", [(32, "<H", 300), (36, "<d", 9.0), (44, "<d", -1.0),
                                              (44, "<d", float("nan")), (34, "<B", 7), (28, "<H", 0)],
                         ids=["views", "slant", "period", "period-nan", "order", "width"])
def test_firmware_rejects_out_of_range_values(url, offset, fmt, value):
    with PanelController.open(url) as panel:
        panel.flash(profile_a())
        before = panel.verify_crc()
        with pytest.raises(DeviceProtocolError) as info:
            write_raw(panel, forged(offset, fmt, value, before[1] + 1))
        assert info.value.code == Status.OUT_OF_RANGE
        assert panel.verify_crc() == before and same_constants(panel.read_profile(), profile_a())


def test_firmware_rejects_unknown_layout_and_stale_sequence(url):
    with PanelController.open(url) as panel:
        panel.flash(profile_a())
        current = panel.verify_crc()
        data = encode_record(record_from_profile(profile_b(), serial="X", sequence=current[1] + 1))
        with pytest.raises(DeviceProtocolError) as info:
            write_raw(panel, data, layout=2)
        assert info.value.code == Status.BAD_LAYOUT
        with pytest.raises(DeviceProtocolError) as info:
            write_raw(panel, forged(4, "<H", 2, current[1] + 1))  # layout 2 inside the record
        assert info.value.code == Status.BAD_LAYOUT
        with pytest.raises(DeviceProtocolError) as info:
            write_raw(panel, data, sequence=current[1])
        assert info.value.code == Status.STALE_SEQUENCE
        with pytest.raises(DeviceProtocolError) as info:
            panel.request(Command.COMMIT)
        assert info.value.code == Status.BAD_STATE
        assert panel.verify_crc() == current


def test_crc_mismatch_is_refused(url):
    with PanelController.open(url) as panel:
        panel.flash(profile_a())
        current = panel.verify_crc()
        data = encode_record(record_from_profile(profile_b(), serial="X", sequence=current[1] + 1))
        panel.request(Command.BEGIN_WRITE, BEGIN_WRITE.pack(1, RECORD_SIZE, record_crc(data) ^ 1, current[1] + 1))
        for offset in range(0, RECORD_SIZE, 32):
            panel.request(Command.WRITE_CHUNK, CHUNK_HEADER.pack(offset) + data[offset:offset + 32])
        with pytest.raises(DeviceProtocolError) as info:
            panel.request(Command.COMMIT)
        assert info.value.code == Status.CRC_MISMATCH
        assert panel.verify_crc() == current
