"""Reading a Looking Glass unit's calibration: the emulated HID unit (its EEPROM page protocol)
and a drive folder give the profile that importing the same visual.json gives; every fault of
the unit (no answer, short answers, wrong page echoes, a blank EEPROM, an absurd length, text
that is not a visual.json) ends in one line, exit 2, and no output file; units are listed, shown
and never written."""

from __future__ import annotations

import json

import pytest

from lenticalib.core.errors import DeviceNotFoundError, DeviceProtocolError, DeviceTimeoutError, InputError
from lenticalib.core.looking_glass.convert import import_visual_json
from lenticalib.core.profile import load_profile, save_profile
from lenticalib.device.emulator.looking_glass import EmulatedLookingGlassHid, create_unit, eeprom_bytes, unit_image
from lenticalib.device.looking_glass import is_looking_glass, open_unit, read_calibration
from lenticalib.device.looking_glass.drive import find_drives
from lenticalib.device.looking_glass.hid import PAGE_SIZE, HidUnit, page_request, pages_for
from lenticalib.device.url import parse_device_url

from .cli_support import one_error_line
from .device_support import profile_b
from .looking_glass_support import CALIBRATIONS, STRIPE, VIEWS, make_drive, visual_bytes, without_provenance

FAST = "timeout=0.05"  # seconds per page answer: the faults below time out quickly


@pytest.fixture(autouse=True)
def emulator_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))
    return tmp_path / "emu"


@pytest.mark.parametrize("kind", sorted(CALIBRATIONS))
def test_emulated_unit_and_drive_give_the_profile_import_gives(kind, tmp_path, cli):
    text = visual_bytes(CALIBRATIONS[kind])
    path = tmp_path / "visual.json"
    path.write_bytes(text)
    imported = import_visual_json(path, VIEWS)
    drive = make_drive(tmp_path / "LKG-DRIVE", text)
    for url in (create_unit("unit", text), f"lkg-drive://{drive}", f"lkg-drive://{drive / 'LKG_calibration'}"):
        calibration = read_calibration(url)
        assert without_provenance(calibration.to_profile(VIEWS)) == without_provenance(imported)
        out = tmp_path / "read.json"
        code, stdout, err = cli("device", "read", url, "-o", out, "--views", VIEWS)
        assert code == 0, err
        read = load_profile(out)
        assert without_provenance(read) == without_provenance(imported)
        assert read.routing_key() == imported.routing_key()
        prov = read.provenance
        assert prov["device_url"] == url and prov["panel_serial"] == CALIBRATIONS[kind]["serial"]
        assert prov["read"] and prov["config_version"] == CALIBRATIONS[kind]["configVersion"]
        assert CALIBRATIONS[kind]["serial"] in stdout and CALIBRATIONS[kind]["configVersion"] in stdout


def test_pages_are_asked_by_big_endian_number_until_the_length_is_read(tmp_path):
    visual = dict(STRIPE, notes="x" * (300 * PAGE_SIZE))  # past page 255: the page number's high byte counts
    text = visual_bytes(visual)
    url = parse_device_url(create_unit("long", text))
    sent = []

    class Recording(EmulatedLookingGlassHid):
        def send_feature_report(self, data):
            sent.append(bytes(data))
            return super().send_feature_report(data)

    with HidUnit(url, device_factory=lambda: Recording(url), ids=(0x04D8, 0xEF7E, None)) as unit:
        calibration = unit.read_calibration()
    assert calibration.size == len(text) and calibration.field("notes") == visual["notes"]
    assert sent == [page_request(page) for page in range(pages_for(len(text)))]
    assert len(sent) > 256 and sent[258][:4] == bytes([0, 0, 1, 2]) and len(sent[0]) == 68


def test_late_and_broken_answers_are_skipped_and_the_page_asked_again(tmp_path):
    text = visual_bytes(STRIPE)
    url = create_unit("flaky", text) + f"?drop=0.1&short=0.1&wrong-page=0.1&seed=1&{FAST}"
    with open_unit(url) as unit:
        calibration = unit.read_calibration()
        assert unit.skipped > 0
    assert calibration.sha256 == read_calibration("lkg-emu://flaky").sha256


def _write_image(name: str, data: bytes) -> str:
    unit_image(name).parent.mkdir(parents=True, exist_ok=True)
    unit_image(name).write_bytes(data)
    return f"lkg-emu://{name}?{FAST}"


FAULTS = {
    "no answer": (lambda: create_unit("u", visual_bytes(STRIPE)) + f"?drop=1&{FAST}", DeviceTimeoutError,
                  "no answer to the request for EEPROM page 0"),
    "short answers": (lambda: create_unit("u", visual_bytes(STRIPE)) + f"?short=1&{FAST}", DeviceProtocolError,
                      "cut short (20 bytes; a page answer is 68)"),
    "wrong page echoes": (lambda: create_unit("u", visual_bytes(STRIPE)) + f"?wrong-page=1&{FAST}",
                          DeviceProtocolError, "asked for EEPROM page 0, the unit answered page 1 instead"),
    "blank EEPROM": (lambda: create_unit("u", None) + f"?{FAST}", DeviceProtocolError, "holds no calibration"),
    "length zero": (lambda: _write_image("u", bytes(PAGE_SIZE)), DeviceProtocolError,
                    "length field says the calibration is 0 bytes"),
    "absurd length": (lambda: _write_image("u", (70000).to_bytes(4, "big") + visual_bytes(STRIPE)),
                      DeviceProtocolError, "length field says the calibration is 70000 bytes"),
    "not JSON": (lambda: create_unit("u", b"pitch=49.91; slope=5.45"), DeviceProtocolError,
                 "not a usable visual.json: not valid JSON"),
    "not UTF-8": (lambda: create_unit("u", b"{\"serial\": \"\xff\xfe\"}"), DeviceProtocolError,
                  "not a usable visual.json: not a JSON visual.json: not UTF-8"),
    "not an object": (lambda: create_unit("u", b"[49.91, 5.45]"), DeviceProtocolError,
                      "JSON but not an object of fields"),
}


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_every_fault_is_one_line_exit_2_and_no_output_file(fault, tmp_path, cli):
    make_url, error, words = FAULTS[fault]
    url = make_url()
    with pytest.raises(error) as info:
        read_calibration(url)
    assert words in str(info.value) and info.value.source == url
    out = tmp_path / "out.json"
    code, stdout, err = cli("device", "read", url, "-o", out, "--views", VIEWS)
    line = one_error_line(err, url)
    assert code == 2 and words in line and not out.exists() and list(tmp_path.glob("out.json*")) == []
    kept = tmp_path / "kept.json"  # an earlier result is left as it was
    save_profile(profile_b(), kept)
    before = kept.read_bytes()
    assert cli("device", "read", url, "-o", kept, "--views", VIEWS)[0] == 2 and kept.read_bytes() == before
    assert cli("device", "info", url)[0] == 2


def test_a_calibration_import_refuses_is_one_line_naming_the_unit(tmp_path, cli):
    url = create_unit("nofields", visual_bytes({"serial": "LKG-X", "pitch": {"value": 49.9}}))
    out = tmp_path / "out.json"
    code, _, err = cli("device", "read", url, "-o", out, "--views", VIEWS)
    assert code == 2 and "missing field(s)" in one_error_line(err, url) and not out.exists()


@pytest.mark.parametrize("url,error,words", [
    ("lkg-drive:///no/such/folder", DeviceNotFoundError, "no such folder"),
    ("lkg-drive://relative/folder", DeviceNotFoundError, "absolute path"),
    ("lkg-hid://04d8", DeviceNotFoundError, "VID:PID"),
    ("lkg-emu://missing", DeviceNotFoundError, "lenticalib emulate --looking-glass"),
    ("lkg-emu://u?explode=1", InputError, "unknown URL parameter 'explode'"),
    ("lkg-emu://u?timeout=0", InputError, "'timeout' must be 0.01..60"),
    ("lkg-hid://04d8:ef7e?retries=9", InputError, "unknown URL parameter 'retries'"),
    ("lkg-drive:///media?x=1", InputError, "unknown URL parameter 'x'"),
])
def test_bad_urls_and_missing_units_are_one_line(url, error, words, tmp_path, cli):
    create_unit("u", visual_bytes(STRIPE))
    with pytest.raises(error, match=words):
        read_calibration(url)
    code, _, err = cli("device", "read", url, "-o", tmp_path / "o.json", "--views", VIEWS)
    assert code == 2 and words in one_error_line(err)


def test_a_folder_without_the_calibration_is_one_line(tmp_path, cli):
    (tmp_path / "USB").mkdir()
    url = f"lkg-drive://{tmp_path / 'USB'}"
    code, _, err = cli("device", "info", url)
    assert code == 2 and "holds no LKG_calibration/visual.json" in one_error_line(err, url)


def test_views_is_required_for_a_unit_and_refused_for_a_controller(tmp_path, cli):
    url = create_unit("u", visual_bytes(dict(STRIPE, serial="ACME-04321")))  # a serial of no known model
    out = tmp_path / "out.json"
    code, _, err = cli("device", "read", url, "-o", out)
    assert code == 2 and "--views" in one_error_line(err, "--views") and not out.exists()
    url = create_unit("u", visual_bytes(STRIPE))  # LKG-2K: the 8.9" unit's quilt has 45 views
    code, stdout, err = cli("device", "read", url, "-o", out)
    assert code == 0 and "45 views" in stdout, err
    out.unlink()
    code, _, err = cli("device", "read", url, "-o", out, "--views", 1)
    assert code == 2 and "2..254" in one_error_line(err, "--views") and not out.exists()
    code, _, err = cli("device", "read", "emu://c", "-o", out, "--views", VIEWS)
    assert code == 2 and "Looking Glass units only" in one_error_line(err, "--views") and not out.exists()


def test_a_unit_is_never_written(tmp_path, cli):
    url = create_unit("u", visual_bytes(STRIPE))
    image = unit_image("u").read_bytes()
    profile = tmp_path / "p.json"
    save_profile(profile_b(), profile)
    for action in ("flash", "verify"):
        code, out, err = cli("device", action, url, profile)
        assert code == 2 and "is a Looking Glass unit" in one_error_line(err, url) and out == ""
    assert unit_image("u").read_bytes() == image


def test_info_shows_the_serial_and_the_calibration_version(cli):
    url = create_unit("u", visual_bytes(CALIBRATIONS["cells"]))
    code, out, err = cli("device", "info", url)
    assert code == 0, err
    assert "serial LKG-P-01234" in out and "calibration version 3.0" in out and "USB serial LKG-EMU-U" in out
    code, out, _ = cli("device", "info", url, "--json")
    info = json.loads(out)
    assert info["serial"] == "LKG-P-01234" and info["config_version"] == "3.0" and info["usb_serial"] == "LKG-EMU-U"
    assert info["calibration"]["screenW"] == 1536.0
    from lenticalib.device.info import device_info

    assert info == device_info(url)  # the command prints the library's document


def test_device_list_shows_units_beside_the_controllers(cli):
    url = create_unit("bench", visual_bytes(STRIPE))
    code, out, _ = cli("device", "list", "--json")
    listed = {d["url"]: d for d in json.loads(out)["devices"]}
    assert code == 0 and listed[url]["family"] == "lkg" and listed[url]["serial"] == "LKG-EMU-BENCH"
    code, out, _ = cli("device", "list")
    assert code == 0 and url in out


def test_drives_are_found_in_the_mount_table_and_the_media_folders(tmp_path):
    mounted = make_drive(tmp_path / "LKG drive", visual_bytes(STRIPE))  # a space: written \040 in the table
    other = tmp_path / "USB STICK"
    other.mkdir()
    network = make_drive(tmp_path / "nfs", visual_bytes(STRIPE))
    mounts = tmp_path / "mounts"
    mounts.write_text(f"/dev/sdb1 {str(mounted).replace(' ', chr(92) + '040')} vfat rw 0 0\n"
                      f"/dev/sdc1 {str(other).replace(' ', chr(92) + '040')} exfat rw 0 0\n"
                      f"server:/x {network} nfs4 rw 0 0\nproc /proc proc rw 0 0\n")
    media = tmp_path / "media" / "user"
    desktop = make_drive(media / "LKG-P03996", visual_bytes(STRIPE))
    (media / "EMPTY").mkdir()
    assert find_drives(mounts, [media, tmp_path / "no-such-root"]) == sorted([mounted, desktop])


def test_emulate_saves_a_unit_from_a_visual_json(tmp_path, cli):
    path = tmp_path / "visual.json"
    path.write_bytes(visual_bytes(STRIPE))
    code, out, err = cli("emulate", "--looking-glass", path, "--name", "bench")
    assert code == 0, err
    assert out.strip() == "lkg-emu://bench" and unit_image("bench").read_bytes() == eeprom_bytes(path.read_bytes())
    assert read_calibration("lkg-emu://bench").visual == STRIPE
    code, _, err = cli("emulate", "--looking-glass", tmp_path / "missing.json")
    assert code == 2 and "missing.json" in one_error_line(err)
    code, _, err = cli("emulate", "--name", "bench")
    assert code == 2 and "--looking-glass" in one_error_line(err, "--name")


def test_only_looking_glass_schemes_are_units():
    assert is_looking_glass("lkg-hid://04d8:ef7e") and is_looking_glass("lkg-drive:///media/u/LKG")
    assert is_looking_glass(parse_device_url("lkg-emu://x"))
    assert not any(map(is_looking_glass, ("emu://x", "hid://04d8:ef7e", "/dev/hidraw0", "serial:///dev/ttyACM0")))


def test_listing_drives_reads_their_serial(tmp_path, monkeypatch):
    from lenticalib.device.looking_glass import drive

    good = make_drive(tmp_path / "LKG-A", visual_bytes(STRIPE))
    bad = make_drive(tmp_path / "LKG-B", b"not json")
    monkeypatch.setattr(drive, "find_drives", lambda: [good, bad])
    found, notes = drive.DriveUnit.list_devices()
    assert [(d.url, d.serial) for d in found] == [(f"lkg-drive://{good}", STRIPE["serial"]),
                                                  (f"lkg-drive://{bad}", None)]
    assert len(notes) == 1 and notes[0].startswith(f"lkg-drive://{bad}: ") and "not valid JSON" in notes[0]


def test_a_slow_unit_ends_in_one_timeout_line_within_the_reads_deadline(tmp_path, cli):
    import time

    from lenticalib.device.looking_glass.hid import CONVERSATION_TIMEOUTS

    timeout = 0.1
    text = visual_bytes(dict(STRIPE, notes="x" * (100 * PAGE_SIZE)))  # 106 pages: 9.5 s at 0.09 s a page
    create_unit("slow", text)
    slow = f"lkg-emu://slow?delay=1&delay-s=0.09&timeout={timeout}"  # every page answered just in time
    deadline = CONVERSATION_TIMEOUTS * timeout
    start = time.monotonic()
    with pytest.raises(DeviceTimeoutError) as info:
        read_calibration(slow)
    took = time.monotonic() - start
    assert deadline <= took < deadline + 0.5, took
    assert (f"did not finish within {deadline:g} s ({CONVERSATION_TIMEOUTS} x the {timeout:g} s page timeout)"
            in str(info.value)) and f" of {pages_for(len(text))} pages read" in str(info.value) and info.value.source == slow
    out = tmp_path / "out.json"
    start = time.monotonic()
    code, _, err = cli("device", "read", slow, "-o", out, "--views", VIEWS)
    assert code == 2 and "did not finish within" in one_error_line(err, slow) and not out.exists()
    assert time.monotonic() - start < deadline + 0.5
    # the same calibration from a unit in order, at the same timeout, is read whole
    assert read_calibration(f"lkg-emu://slow?timeout={timeout}").size == len(text)


@pytest.mark.parametrize("field,value,words", [
    ("slope", {"value": "5.45"}, "field 'slope': must be a number"),
    ("serial", {"value": 1234}, "field 'serial': must be a string"),
    ("viewCone", {"value": [40.0]}, "field 'viewCone': must be a number"),
    ("screenW", {"value": 1e300}, "field 'screenW': must be a whole number"),
])
def test_info_and_read_check_every_field_they_show(field, value, words, tmp_path, cli):
    url = create_unit("u", visual_bytes(dict(STRIPE, **{field: value})))
    drive = make_drive(tmp_path / "LKG", visual_bytes(dict(STRIPE, **{field: value})))
    for where in (url, f"lkg-drive://{drive}"):
        code, out, err = cli("device", "info", where)
        assert code == 2 and out == "" and words in one_error_line(err, where)
        code, _, err = cli("device", "read", where, "-o", tmp_path / "o.json", "--views", VIEWS)
        assert code == 2 and words in one_error_line(err, where) and not (tmp_path / "o.json").exists()
