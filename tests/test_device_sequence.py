"""The record sequence wraps: a controller whose records sit at 0xFFFFFFFE/0xFFFFFFFF is
flashed again and again (0, 1, 2, ...), the newer record is chosen by serial-number arithmetic
at every boot, also after a power cut in the middle of the flash that wraps; firmware that
predates the wrap gets one line that says so, not a complaint about the profile."""

from __future__ import annotations

import pytest

from lenticalib.device import PanelController
from lenticalib.device.protocol import BEGIN_WRITE, CHUNK_HEADER, Command
from lenticalib.device.record import (LAYOUT_VERSION, RECORD_SIZE, encode_record, next_sequence, record_from_profile,
                                      sequence_newer, wire_crc)
from lenticalib.core.errors import DeviceError, DeviceProtocolError

from .device_support import VIAS, profile_a, profile_b, same_constants

TOP = 0xFFFFFFFF


@pytest.fixture(autouse=True)
def emulator_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))


def write_record(url: str, profile, sequence: int) -> None:
    """Commit ``profile`` as record ``sequence`` by speaking the protocol directly (section 3):
    the host's flash always writes the current sequence + 1, this puts a controller anywhere."""
    with PanelController.open(url) as panel:
        identity = panel.identify()
        data = encode_record(record_from_profile(profile, serial=identity.serial, sequence=sequence))
        panel.request(Command.BEGIN_WRITE, BEGIN_WRITE.pack(LAYOUT_VERSION, RECORD_SIZE,
                                                            wire_crc(data, identity.protocol_minor), sequence))
        for offset in range(0, RECORD_SIZE, 32):
            panel.request(Command.WRITE_CHUNK, CHUNK_HEADER.pack(offset) + data[offset:offset + 32])
        panel.request(Command.COMMIT)


def at_the_top(url: str) -> None:
    """Slot 0 holds profile_b as record 0xFFFFFFFE, slot 1 profile_a as record 0xFFFFFFFF (current)."""
    write_record(url, profile_b(), TOP - 1)
    write_record(url, profile_a(), TOP)


def held(url: str) -> tuple[int, int, object]:
    """(slot, sequence, profile) of the record a freshly started controller on ``url``'s image chooses."""
    with PanelController.open(url) as panel:
        slot, sequence, _ = panel.verify_crc()
        return slot, sequence, panel.read_record().to_profile()


def test_sequence_arithmetic():
    assert next_sequence(TOP - 1) == TOP and next_sequence(TOP) == 0 and next_sequence(0) == 1
    assert sequence_newer(0, TOP) and sequence_newer(1, TOP - 1) and not sequence_newer(TOP, 0)
    assert sequence_newer(5, 4) and not sequence_newer(4, 5) and not sequence_newer(7, 7)
    assert sequence_newer(2**31 - 1, 0) and not sequence_newer(2**31, 0) and not sequence_newer(0, 2**31)


@pytest.mark.parametrize("via", VIAS)
def test_flashing_goes_on_across_the_wrap(via):
    url = f"emu://wrap?via={via}"
    at_the_top(url)
    slot, sequence, back = held(url)
    assert (slot, sequence) == (1, TOP) and same_constants(back, profile_a())
    for n, profile in enumerate([profile_b(), profile_a(), profile_b(), profile_a()]):
        with PanelController.open(url) as panel:
            result = panel.flash(profile)
        assert result.record.sequence == n and result.slot == n % 2  # 0 goes into slot 0, over 0xFFFFFFFE
        slot, sequence, back = held(url)  # a restart picks the newer record: 0 over 0xFFFFFFFF
        assert (slot, sequence) == (n % 2, n) and same_constants(back, profile)


@pytest.mark.parametrize("torn", [False, True], ids=["after", "during"])
def test_power_cut_in_the_flash_that_wraps(torn):
    """One flash is 6 flash operations (test_device_power); the new record 0 counts only once
    the 6th, its commit word, is complete, and is then chosen over 0xFFFFFFFF."""
    for k in range(1, 7):
        name = f"wrapcut-{k}"
        at_the_top(f"emu://{name}")
        cut = PanelController.open(f"emu://{name}?power-cut-after={k}" + ("&torn=1" if torn else ""))
        cut.command_timeout, cut.flash_timeout = 0.2, 0.3
        with cut, pytest.raises(DeviceError):
            cut.flash(profile_b())
        slot, sequence, back = held(f"emu://{name}")
        if k == 6 and not torn:
            assert (slot, sequence) == (0, 0) and same_constants(back, profile_b())
        else:
            assert (slot, sequence) == (1, TOP) and same_constants(back, profile_a())
        with PanelController.open(f"emu://{name}") as panel:  # and flashing goes on from there
            result = panel.flash(profile_a())
        assert result.record.sequence == next_sequence(sequence) == held(f"emu://{name}")[1]


def test_firmware_without_wrap_gets_one_line_naming_the_firmware():
    url = "emu://old?protocol=1.0"
    at_the_top(url)
    with PanelController.open(url) as panel:
        with pytest.raises(DeviceProtocolError) as info:
            panel.flash(profile_b())
    text = str(info.value)
    assert "\n" not in text and "0xFFFFFFFF" in text and "firmware" in text and "profile" not in text
    assert held(url)[1] == TOP and same_constants(held(url)[2], profile_a())
