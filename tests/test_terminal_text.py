"""Rule 4 of issue 45: text from outside is made safe before it reaches a terminal.

A serial, a field or a name from a unit, a drive or a file is printed with its control characters
escaped (C0, DEL, C1, Unicode format and bidi controls) and, when long, cut with its length stated:
by :func:`lenticalib.core.terminal_text.terminal_safe`, used by every error line
(:func:`lenticalib.cli.main`) and by ``device info|read|list`` and ``profile show|compare``.
"""

from __future__ import annotations

import json
import unicodedata

import pytest

from lenticalib.core.profile import save_profile
from lenticalib.core.terminal_text import MAX_LINE_CHARS, safe_line, terminal_safe
from lenticalib.device.emulator.looking_glass import create_unit

from .cli_support import one_error_line
from .device_support import profile_b
from .looking_glass_support import STRIPE, VIEWS, make_drive, visual_bytes

TITLE = "\x1b]0;pwned title\x07"      # OSC 0: sets the terminal's title
CLEAR = "\x1b[2J\x1b[H"               # CSI 2J: clears the screen
CLIPBOARD = "\x1b]52;c;cm0gLXJmIH4=\x07"  # OSC 52: writes the clipboard
BIDI = "\u202egnp.exe\u2066x\u2069"   # right-to-left override, an isolate
C1 = "\x9b31m\x85"                    # 8-bit CSI, next line
EVIL = f"LKG-{TITLE}{CLEAR}{CLIPBOARD}{BIDI}{C1}\x7f\x00\r\n-END"


def raw_controls(text: str) -> list[str]:
    """The characters of ``text`` a terminal would act on (line ends between lines aside); written
    independently of the module under test."""
    return sorted({c for line in text.split("\n") for c in line
                   if unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp", "Cs")})


@pytest.fixture(autouse=True)
def emulator_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))


# --- the function ---


@pytest.mark.parametrize("text,shown", [
    (TITLE, r"\x1b]0;pwned title\x07"),
    (CLEAR, r"\x1b[2J\x1b[H"),
    (CLIPBOARD, r"\x1b]52;c;cm0gLXJmIH4=\x07"),
    (BIDI, r"\u202egnp.exe\u2066x\u2069"),
    (C1, r"\x9b31m\x85"),
    ("a\x7fb\x00c\td\r\ne", r"a\x7fb\x00c\td\r\ne"),
    ("zero\u200bwidth\ufeff\u2028\U000e0041", r"zero\u200bwidth\ufeff\u2028\U000e0041"),
    ("undecodable \udcff", r"undecodable \udcff"),
    ("Grüße 日本 ΑΒΓ C:\\path", "Grüße 日本 ΑΒΓ C:\\path"),  # text of every script passes unchanged
])
def test_control_characters_are_shown_escaped(text, shown):
    assert terminal_safe(text) == shown
    assert raw_controls(terminal_safe(text)) == []


def test_a_long_value_is_cut_with_its_length_stated():
    value = "5" * 200_000
    shown = terminal_safe(value)
    assert len(shown) < 160 and "(200000 characters)" in shown and shown.startswith("5555") and "..." in shown
    escapes = "\x1b" * 100_000  # escaping expands fourfold: the cut still bounds the result
    shown = terminal_safe(escapes)
    assert len(shown) < 160 and "(100000 characters)" in shown and raw_controls(shown) == []
    assert not shown.split("...")[0].endswith("\\")  # never cut inside an escape
    line = safe_line("x" * 300_000 + " (the hint)")
    assert len(line) < MAX_LINE_CHARS + 40 and line.endswith("(the hint) (300011 characters)")
    assert terminal_safe(None) == "None" and terminal_safe(3.5) == "3.5"


# --- where text reaches the terminal ---


def test_device_info_and_read_show_a_hostile_serial_escaped(tmp_path, cli):
    url = create_unit("u", visual_bytes(dict(STRIPE, serial=EVIL, configVersion=BIDI)))
    code, out, err = cli("device", "info", url)
    assert code == 0, err
    assert raw_controls(out + err) == []
    assert r"serial LKG-\x1b]0;pwned title\x07\x1b[2J" in out and r"\u202egnp.exe" in out
    code, out, _ = cli("device", "info", url, "--json")  # JSON escapes by itself (ensure_ascii)
    assert code == 0 and raw_controls(out) == [] and json.loads(out)["serial"] == EVIL and "\\u001b" in out
    code, out, err = cli("device", "read", url, "-o", tmp_path / "p.json", "--views", VIEWS)
    assert code == 0, err
    assert raw_controls(out + err) == [] and r"\x1b]52;c;" in out
    code, out, err = cli("profile", "show", tmp_path / "p.json")  # the serial travelled into the provenance
    assert code == 0, err
    assert raw_controls(out + err) == [] and r"panel serial LKG-\x1b]0;pwned" in out


def test_device_list_and_a_drive_show_what_units_report_escaped(tmp_path, cli, monkeypatch):
    from lenticalib.device import discovery
    from lenticalib.device.transports.base import FoundDevice

    unit = FoundDevice("lkg-hid://04d8:ef7e/" + TITLE, "lkg-hid", "lkg", f"Looking Glass ({CLEAR}HoloPlay)", EVIL)
    monkeypatch.setattr(discovery, "list_devices", lambda: ([unit], [f"enumeration failed: {CLIPBOARD}"]))
    code, out, err = cli("device", "list")
    assert code == 0 and raw_controls(out + err) == [] and r"serial LKG-\x1b]0;" in out and r"\x1b]52" in out
    drive = make_drive(tmp_path / "LKG", visual_bytes(dict(STRIPE, serial=EVIL)))
    code, out, err = cli("device", "info", f"lkg-drive://{drive}")
    assert code == 0 and raw_controls(out + err) == [] and r"\x1b[2J" in out


def test_profile_show_escapes_the_files_words(tmp_path, cli):
    path = tmp_path / "p.json"
    document = profile_b().to_dict()
    document["provenance"] = {"method": f"fit{TITLE}", "created": CLEAR, "lenticalib_version": CLIPBOARD,
                              "device_url": "emu://x" + BIDI, "panel_serial": "S" * 200_000,
                              "view_direction": {"method": f"set{C1}", "set": "\x1b]8;;http://x\x07link"}}
    document["view_direction"] = 1
    document["physical"] = {"pixel_pitch_mm": 0.1, "source": f"sheet{CLEAR}"}
    path.write_text(json.dumps(document))
    code, out, err = cli("profile", "show", path)
    assert code == 0, err
    assert raw_controls(out + err) == [] and r"fit\x1b]0;pwned title\x07" in out
    assert max(map(len, out.splitlines())) < 1000 and " characters)" in out  # the 200 KB serial, cut
    save_profile(profile_b(), tmp_path / "b.json")
    code, out, err = cli("profile", "compare", path, tmp_path / "b.json")
    assert code == 0 and raw_controls(out + err) == []


@pytest.mark.parametrize("case", ["pitch string", "period string", "unknown field", "subpixel order"])
def test_error_lines_quoting_a_file_are_escaped_and_short(case, tmp_path, cli):
    if case == "pitch string":  # a 60 KB pitch string read from a unit's drive
        drive = make_drive(tmp_path / "LKG", visual_bytes(dict(STRIPE, pitch={"value": TITLE + "5" * 60_000})))
        url = f"lkg-drive://{drive}"
        code, out, err = cli("device", "read", url, "-o", tmp_path / "o.json", "--views", VIEWS)
        assert code == 2 and "field 'pitch'" in one_error_line(err, url)
        code, _, err = cli("device", "info", url)
        assert code == 2 and "field 'pitch'" in one_error_line(err, url)
    else:
        document = profile_b().to_dict()
        if case == "unknown field":  # the message quotes the key as written
            document[CLEAR + TITLE * 10_000] = 1
        elif case == "period string":  # 200 KB
            document["period"] = TITLE + "5" * 200_000
        else:
            document["subpixel_order"] = ("RGB" + CLIPBOARD) * 10_000
        path = tmp_path / "p.json"
        path.write_text(json.dumps(document))
        code, out, err = cli("profile", "show", path)
        assert code == 2 and out == ""
    line = one_error_line(err)
    assert len(line) < 1000 and raw_controls(err) == [], (len(line), raw_controls(err))


def test_names_monitors_report_and_warnings_are_escaped(cli, monkeypatch):
    from lenticalib.cli.shared.avatar_options import warning_line
    from lenticalib.render.gpu import monitors

    class Monitor:
        def describe(self):
            return f"0: {TITLE}Panel{BIDI} 3840x2160 at (0, 0)"

    monkeypatch.setattr(monitors, "list_monitors", lambda: [Monitor()])
    code, out, err = cli("show", "--list-displays")
    assert code == 0 and raw_controls(out + err) == [] and r"0: \x1b]0;pwned title\x07Panel" in out
    assert warning_line(f"avatar {CLEAR}.ply: {'x' * 100_000}").startswith(r"avatar \x1b[2J\x1b[H.ply: xxx")
    assert len(warning_line("x" * 100_000)) < 1000
