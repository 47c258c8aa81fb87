"""Power loss during a flash: for every flash operation k, cut the power after (and halfway
through) operation k, restart the controller from its flash image, and read: the old record
or the new one, intact, never anything else; a repeated flash then succeeds."""

from __future__ import annotations

import pytest

from lenticalib.device import PanelController
from lenticalib.device.emulator.flash import IMAGE_SIZE, SLOT_SIZE, FACTORY_SIZE
from lenticalib.core.errors import DeviceError

from .device_support import VIAS, emulator_process, profile_a, profile_b, same_constants, wait_exit


@pytest.fixture(autouse=True)
def emulator_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))
    return tmp_path / "emu"


def fast(panel: PanelController) -> PanelController:
    panel.command_timeout, panel.flash_timeout = 0.2, 0.3
    return panel


def flash_operations() -> int:
    """Flash operations (erases + programs) one uninterrupted flash performs, measured."""
    with PanelController.open("emu://count") as panel:
        panel.flash(profile_a())
        flash = panel.transport.port.controller.flash
        before = flash.operations
        panel.flash(profile_b())
        return flash.operations - before


def test_flash_has_the_documented_operations():
    # erase, 128 bytes in 4 programs of 32, commit word
    assert flash_operations() == 6


@pytest.mark.parametrize("via", VIAS)
@pytest.mark.parametrize("torn", [False, True], ids=["after", "during"])
@pytest.mark.parametrize("had_record", [True, False], ids=["over-old", "blank"])
def test_power_cut_at_every_flash_operation(via, torn, had_record):
    total = flash_operations()
    old, new = profile_a(), profile_b()
    outcomes = set()
    for k in range(1, total + 1):
        name = f"cut-{k}"
        if had_record:
            with PanelController.open(f"emu://{name}?via={via}") as panel:
                panel.flash(old)
        cut = f"emu://{name}?via={via}&power-cut-after={k}" + ("&torn=1" if torn else "")
        with fast(PanelController.open(cut)) as panel:
            with pytest.raises(DeviceError):
                panel.flash(new)
        # restart from the image: the old record or the new one, intact
        with PanelController.open(f"emu://{name}?via={via}") as panel:
            record = panel.read_record()
            if record is None:
                assert not had_record, f"k={k}: the old record was lost"
                outcomes.add("none")
            else:
                held = record.to_profile()
                assert same_constants(held, old) or same_constants(held, new), f"k={k}: neither old nor new"
                outcomes.add("new" if same_constants(held, new) else "old")
            result = panel.flash(new)  # a repeated flash succeeds
            assert same_constants(result.record.to_profile(), new)
            assert panel.verify(new).matches
    # a cut before the commit word is complete keeps the old record; after it, the new one
    assert ("old" if had_record else "none") in outcomes
    assert ("new" in outcomes) == (not torn)


def test_corrupt_newer_slot_never_hides_the_good_one(emulator_dir):
    with PanelController.open("emu://c") as panel:
        panel.flash(profile_a())
        first = panel.verify_crc()
        panel.flash(profile_b())
        second = panel.verify_crc()
    assert first[0] != second[0] and second[1] == first[1] + 1
    image = emulator_dir / "c.flash"
    data = bytearray(image.read_bytes())
    assert len(data) == IMAGE_SIZE
    data[FACTORY_SIZE + second[0] * SLOT_SIZE + 40] ^= 0x10  # a flipped bit inside the newer record
    image.write_bytes(bytes(data))
    with PanelController.open("emu://c") as panel:
        record = panel.read_record()
        assert record.sequence == first[1] and same_constants(record.to_profile(), profile_a())
        panel.flash(profile_b())  # overwrites the corrupt slot, not the good one
        assert panel.verify(profile_b()).matches


def test_power_cut_over_a_pseudo_terminal_at_every_operation(tmp_path):
    """The same over a real emulator process on a pty: the process dies, a new one restarts."""
    total = flash_operations()
    image = tmp_path / "pty.flash"
    for k in range(1, total + 1):
        with emulator_process("--flash", str(image)) as (_, url):
            with PanelController.open(url) as panel:
                panel.flash(profile_a())
        with emulator_process("--flash", str(image), "--power-cut-after", str(k)) as (proc, url):
            with fast(PanelController.open(url)) as panel:
                with pytest.raises(DeviceError):
                    panel.flash(profile_b())
            assert wait_exit(proc) == 75
        with emulator_process("--flash", str(image)) as (_, url):
            with PanelController.open(url) as panel:
                held = panel.read_record().to_profile()
                assert same_constants(held, profile_a()) or same_constants(held, profile_b())
                panel.flash(profile_b())
                assert panel.verify(profile_b()).matches
