"""One contract for every way a Looking Glass unit is read: the emulated HID unit (EEPROM page
protocol, through the same reader as the hardware) and a drive folder.  Set
LENTICALIB_TEST_DEVICE to a Looking Glass URL (``lkg-hid://04d8:ef7e``, ``lkg-drive:///media/USER/LKG``)
to run the same cases against a real unit; a controller URL there runs tests/test_device_contract.py
instead.  Nothing here writes to the unit."""

from __future__ import annotations

import hashlib
import json
import os

import pytest

from lenticalib.core.looking_glass.convert import import_visual_json
from lenticalib.device.emulator.looking_glass import create_unit
from lenticalib.device.looking_glass import is_looking_glass, open_unit, read_calibration
from lenticalib.device.looking_glass.hid import LENGTH_BYTES, PAGE_SIZE, HidUnit

from .cli_support import one_error_line
from .looking_glass_support import CALIBRATIONS, VIEWS, make_drive, visual_bytes, without_provenance

UNITS = ["emulated-hid", "drive"]
HARDWARE = os.environ.get("LENTICALIB_TEST_DEVICE")
if HARDWARE and is_looking_glass(HARDWARE):
    UNITS.append("hardware")


@pytest.fixture(params=UNITS)
def url(request, tmp_path, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))
    text = visual_bytes(CALIBRATIONS["cells"])
    if request.param == "emulated-hid":
        return create_unit("contract", text)
    if request.param == "drive":
        return f"lkg-drive://{make_drive(tmp_path / 'LKG-DRIVE', text)}"
    return HARDWARE


def test_two_reads_agree_and_name_the_unit(url):
    first, second = read_calibration(url), read_calibration(url)
    assert first.sha256 == second.sha256 and first.visual == second.visual and first.url == url
    assert first.serial and first.size > 0
    for key in ("pitch", "slope", "center", "DPI", "screenW", "screenH"):
        assert isinstance(first.field(key), (int, float)), key


def test_the_profile_read_is_the_profile_import_gives(url, tmp_path):
    calibration = read_calibration(url)
    path = tmp_path / "visual.json"
    path.write_text(json.dumps(calibration.visual))
    profile = calibration.to_profile(VIEWS)
    assert without_provenance(profile) == without_provenance(import_visual_json(path, VIEWS))
    assert profile.provenance["device_url"] == url and profile.provenance["panel_serial"] == calibration.serial
    assert profile.provenance["calibration_sha256"] == calibration.sha256


def test_the_hid_eeprom_holds_the_length_then_the_text(url):
    with open_unit(url) as unit:
        if not isinstance(unit, HidUnit):  # a drive has no pages: its file is the text
            calibration = unit.read_calibration()
            assert calibration.path and hashlib.sha256(open(calibration.path, "rb").read()).hexdigest() \
                == calibration.sha256
            return
        first = unit.read_page(0)
        calibration = unit.read_calibration()
    assert len(first) == PAGE_SIZE and int.from_bytes(first[:LENGTH_BYTES], "big") == calibration.size


def test_the_cli_reads_shows_and_refuses_to_write(url, tmp_path, cli):
    out = tmp_path / "profile.json"
    code, stdout, err = cli("device", "read", url, "-o", out, "--views", VIEWS)
    assert code == 0 and out.is_file(), err
    code, stdout, err = cli("device", "info", url, "--json")
    info = json.loads(stdout)
    assert code == 0 and info["serial"] and "config_version" in info
    code, stdout, err = cli("device", "flash", url, out)
    assert code == 2 and "is a Looking Glass unit" in one_error_line(err, url)
