"""The calibration record, the frame format and the controller family files."""

from __future__ import annotations

import re
from pathlib import Path
import struct
import zlib

import pytest
from hypothesis import given, strategies as st

from lenticalib.device.controller_families import families, family_for, load_family
from lenticalib.device.looking_glass.hid import PRODUCT_ID, VENDOR_ID
from lenticalib.device.framing import FrameParser, crc16, encode_frame
from lenticalib.device.record import (RECORD_SIZE, RecordFormatError, encode_record, parse_record,
                                      record_from_profile)
from lenticalib.core.errors import InputError, ProfileError
from lenticalib.core.layout import SubpixelLayout
from lenticalib.core.profile import PanelProfile, save_profile
from lenticalib.device import PanelController

from .cli_support import one_error_line
from .device_support import REPO, profile_b


def test_crc16_is_ccitt_false():
    assert crc16(b"123456789") == 0x29B1  # the catalogue check value of CRC-16/CCITT-FALSE


def test_record_layout_is_little_endian_and_documented():
    bgr = profile_b().replace(subpixel_order="BGR")
    record = record_from_profile(bgr, serial="SN-1", sequence=0x01020304, written=5)
    data = encode_record(record)
    assert len(data) == RECORD_SIZE and data[:4] == b"LTCR"
    assert struct.unpack_from("<HHI", data, 4) == (1, 128, 0x01020304)
    assert data[12:28] == b"SN-1" + bytes(12)
    assert struct.unpack_from("<HHHBB", data, 28) == (3840, 2160, 32, 1, 1)
    assert struct.unpack_from("<dddd", data, 36) == (profile_b().slant, profile_b().period, 3.25, 16.0)
    assert struct.unpack_from("<I", data, 124)[0] == zlib.crc32(data[:124])
    back = parse_record(data)
    assert back.to_profile().routing_key() == bgr.routing_key()
    assert back.sigmas == pytest.approx(record.sigmas, rel=1e-7)  # sigmas are stored as f32


@given(slant=st.floats(-4, 4), period=st.floats(0.01, 4096), offset=st.floats(-1e6, 1e6),
       views=st.integers(2, 254), order=st.sampled_from(["RGB", "BGR"]), seq=st.integers(0, 2**32 - 1))
def test_any_valid_profile_round_trips_exactly(slant, period, offset, views, order, seq):
    profile = PanelProfile(views=views, slant=slant, period=period, offset=offset, reference_view=views / 2,
                           width=1920, height=1080, subpixel_order=order)
    record = parse_record(encode_record(record_from_profile(profile, serial="S", sequence=seq)))
    assert record.to_profile().routing_key() == profile.routing_key() and record.sequence == seq


@pytest.mark.parametrize("change,field", [({"slant": 4.5}, "slant"), ({"period": 5000.0}, "period"),
                                          ({"offset": 2e6}, "offset"), ({"reference_view": 1e6}, "reference_view")])
def test_host_refuses_values_the_record_cannot_hold(change, field):
    with pytest.raises(ProfileError, match=field):
        record_from_profile(profile_b().replace(**change), serial="S", sequence=1)


def test_corrupt_records_are_refused_with_a_status():
    data = bytearray(encode_record(record_from_profile(profile_b(), serial="S", sequence=1)))
    for index in (0, 10, 40, 100, 127):
        bad = bytearray(data)
        bad[index] ^= 0x01
        with pytest.raises(RecordFormatError) as info:
            parse_record(bytes(bad))
        assert info.value.status == "BAD_RECORD"
    with pytest.raises(RecordFormatError):
        parse_record(bytes([0xFF]) * RECORD_SIZE)  # an erased slot
    reserved = bytearray(data)
    reserved[110] = 1
    struct.pack_into("<I", reserved, 124, zlib.crc32(bytes(reserved[:124])))
    with pytest.raises(RecordFormatError, match="reserved") as info:
        parse_record(bytes(reserved))
    assert info.value.status == "OUT_OF_RANGE"


def test_the_record_does_not_hold_the_view_direction():
    """Layout 1 has no room for it (its spare bits must be zero, see above); a record read back is unknown."""
    records = {d: encode_record(record_from_profile(profile_b().replace(view_direction=d), serial="S",
                                                    sequence=1, written=7)) for d in (None, 1, -1)}
    assert records[None] == records[1] == records[-1]
    assert parse_record(records[1]).to_profile().view_direction is None


def test_frame_parser_resynchronises_after_garbage():
    frames = encode_frame(0x01, 7, b"") + b"\xa5\x05\x00garbage" + encode_frame(0x82, 8, b"\x00abc")
    parser = FrameParser()
    got = []
    for i in range(len(frames)):  # one byte at a time, as a slow serial link delivers them
        got += parser.feed(frames[i:i + 1])
    assert [(f.cmd, f.seq, f.payload) for f in got] == [(0x01, 7, b""), (0x82, 8, b"\x00abc")]


def test_family_file_loads():
    family = family_for()
    assert family.name == "lc32" and family.retries >= 1 and family.command_timeout_s > 0
    assert {t.kind for t in family.transports} == {"serial", "hid", "usb"}
    assert family.transport("hid").report_size == 64
    assert family_for("usb", 0x1209, 0x0003) is family


def test_the_package_ships_the_documented_families(monkeypatch, tmp_path):
    """drivers/*.toml is the specification; lenticalib/device/families/ the same bytes, found by
    importlib.resources (not by a path relative to the source file), so a wheel finds them too."""
    from lenticalib.device.controller_families import packaged_families, search_path

    shipped = {p.name: p.read_bytes() for p in packaged_families().glob("*.toml")}
    assert shipped == {p.name: p.read_bytes() for p in (REPO / "drivers").glob("*.toml")}
    assert "lc32.toml" in shipped and packaged_families() != REPO / "drivers"
    monkeypatch.delenv("LENTICALIB_DRIVERS", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert search_path()[-1] == packaged_families() and REPO / "drivers" not in search_path()
    assert {f.name for f in families()} == {"lc32"} and Path(family_for().source).parent == packaged_families()


def test_bad_family_file_names_the_field(tmp_path):
    text = (REPO / "drivers" / "lc32.toml").read_text().replace("retries = 3", "retries = \"three\"")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(InputError, match="timeouts.retries") as info:
        load_family(path)
    assert str(path) in str(info.value)


def test_udev_rules_cover_every_controller_and_use_uaccess():
    rules_path = REPO / "drivers" / "70-lenticalib.rules"
    assert rules_path.name < "73-seat-late.rules"  # uaccess is applied in 73-seat-late
    rules = [line for line in rules_path.read_text().splitlines() if line.strip() and not line.startswith("#")]
    assert rules and not any("MODE" in line for line in rules)
    assert all('TAG+="uaccess"' in line for line in rules)
    covered = {(m[1].lower(), m[2].lower()) for line in rules
               for m in [re.search(r'idVendor}=="([0-9a-fA-F]{4})".*idProduct}=="([0-9a-fA-F]{4})"', line)] if m}
    for family in families():
        for t in family.transports:
            assert (f"{t.vid:04x}", f"{t.pid:04x}") in covered, f"{family.name} {t.kind} has no udev rule"
    hidraw = [line for line in rules if 'SUBSYSTEM=="hidraw"' in line]
    assert any(f'idVendor}}=="{VENDOR_ID:04x}"' in line and f'idProduct}}=="{PRODUCT_ID:04x}"' in line
               for line in hidraw), "the Looking Glass HID unit has no hidraw rule"


def _cell_layout_profile() -> PanelProfile:
    third = 1.0 / 3.0
    cells = (((-third, 0.0), (0.0, 0.0), (third, 0.0)), ((-third, 0.5), (0.0, 0.0), (third, -0.5)))
    return profile_b().replace(subpixel_layout=SubpixelLayout(cells=cells, pattern=((0, 1),)))


@pytest.mark.parametrize("field", ["subpixel_layout", "views_reversed", "flip_image_x", "flip_image_y"])
def test_a_field_the_record_cannot_hold_is_refused_before_anything_is_sent(field, tmp_path, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path))
    profile = _cell_layout_profile() if field == "subpixel_layout" else profile_b().replace(**{field: True})
    with pytest.raises(ProfileError, match=f"field '{field}'"):
        record_from_profile(profile, serial="S", sequence=1)
    with PanelController.open("emu://held?via=serial") as panel:
        panel.flash(profile_b())
        before = panel.verify_crc()
        sent = []  # the frames sent: none may follow the refusal
        write = panel.transport.write
        monkeypatch.setattr(panel.transport, "write", lambda data: (sent.append(data), write(data)))
        with pytest.raises(ProfileError, match=f"field '{field}'") as info:
            panel.flash(profile, source="cells.json", force=True)
        assert sent == [] and info.value.source == "cells.json"
        assert panel.verify_crc() == before
        result = panel.verify(profile)
        assert not result.matches and any(d.startswith(f"{field}: device none") for d in result.differences)


def test_device_flash_of_a_cell_layout_is_one_line(tmp_path, cli, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path))
    path = tmp_path / "cells.json"
    save_profile(_cell_layout_profile(), path)
    code, out, err = cli("device", "flash", "emu://cells", path)
    line = one_error_line(err, path)
    assert code == 2 and "subpixel_layout" in line and "cells (2 cells" in line
