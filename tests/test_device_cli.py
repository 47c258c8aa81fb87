"""The device CLI end to end against an emulator on a pseudo-terminal: flash, read back,
verify, compare with the original profile; and every user error as one line, exit 2."""

from __future__ import annotations

import json
import re

import pytest

from lenticalib.core.profile import load_profile, save_profile
from lenticalib.device.info import device_info

from .device_support import emulator_process, profile_a, profile_b, same_constants


def test_emulate_flash_read_verify_compare(tmp_path, cli_process):
    original = tmp_path / "panel.json"
    save_profile(profile_b(), original)
    image = tmp_path / "panel.flash"
    with emulator_process("--flash", str(image)) as (_, url):
        assert url.startswith("serial:///dev/pts/")
        info = cli_process("device", "info", url)
        assert info.returncode == 0 and "no calibration record" in info.stdout
        flashed = cli_process("device", "flash", url, str(original))
        assert flashed.returncode == 0, flashed.stderr
        assert "verified by read-back" in flashed.stdout
        back = tmp_path / "back.json"
        read = cli_process("device", "read", url, "-o", str(back))
        assert read.returncode == 0, read.stderr
        verify = cli_process("device", "verify", url, str(original))
        assert verify.returncode == 0 and "holds" in verify.stdout
        compare = cli_process("profile", "compare", str(back), str(original), "--json")
        assert compare.returncode == 0
        report = json.loads(compare.stdout)
        assert report["rms"] == 0.0 and report["worst"] == 0.0 and report["order_match"]
        assert same_constants(load_profile(back), profile_b())
        info = json.loads(cli_process("device", "info", url, "--json").stdout)
        assert info["record"]["sequence"] == 1 and info["serial"]
        assert info == device_info(url)  # the command prints the library's document
        listed = cli_process("device", "list", "--json")
        assert url in [d["url"] for d in json.loads(listed.stdout)["devices"]]
        other = tmp_path / "other.json"
        save_profile(profile_a(), other)
        mismatch = cli_process("device", "verify", url, str(other))
        assert mismatch.returncode == 1 and "slant: device" in mismatch.stdout
    # the flash image persists across emulator restarts
    with emulator_process("--flash", str(image), "--transport", "tcp") as (_, url):
        assert url.startswith("socket://127.0.0.1:")
        assert cli_process("device", "verify", url, str(original)).returncode == 0


def test_cli_power_cut_then_recover(tmp_path, cli_process):
    profile = tmp_path / "p.json"
    save_profile(profile_b(), profile)
    image = tmp_path / "x.flash"
    with emulator_process("--flash", str(image), "--power-cut-after", "3") as (proc, url):
        result = cli_process("device", "flash", url, str(profile))
        assert result.returncode == 2 and "Traceback" not in result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
    with emulator_process("--flash", str(image)) as (_, url):
        assert "no calibration record" in cli_process("device", "info", url).stdout
        assert cli_process("device", "flash", url, str(profile)).returncode == 0
        assert cli_process("device", "verify", url, str(profile)).returncode == 0


@pytest.mark.parametrize("args,expect", [
    (["device", "info", "serial:///dev/does-not-exist"], "/dev/does-not-exist"),
    (["device", "info", "ttyACM0"], "not a device URL"),
    (["device", "info", "hid://12:34"], "VID:PID"),
    (["device", "info", "carrier-pigeon://x"], "unknown transport"),
    (["device", "info", "emu://x?via=bluetooth"], "unknown via"),
    (["device", "info", "emu://x?explode=1"], "unknown URL parameter 'explode'"),
    (["device", "info", "usb://1209:0003"], "usb://1209:0003"),
    (["device", "read", "emu://blank", "-o", "OUT"], "no calibration record"),
    (["device", "flash", "emu://x", "missing.json"], "missing.json"),
    (["emulate", "--drop", "2"], "--drop"),
    (["emulate", "--torn"], "--power-cut-after"),
    (["emulate", "--flash", "DIR"], "is a folder, not a file name for the flash image"),
    (["emulate", "--flash", "DIR/new.flash", "--serial", "\u00c4\u00d6"], "--serial"),
    (["emulate", "--delay-s", "-1"], "--delay-s"),
])
def test_user_errors_are_one_line(tmp_path, args, expect, cli_process):
    args = [a.replace("OUT", str(tmp_path / "o.json")).replace("DIR", str(tmp_path)) for a in args]
    result = cli_process(*args, env={"LENTICALIB_EMULATOR_DIR": str(tmp_path / "emu")})
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and expect in lines[0], result.stderr
    assert not (tmp_path / "o.json").exists()


def test_flash_refuses_an_invalid_profile_before_sending(tmp_path, cli_process):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**profile_a().to_dict(), "slant": 12.0}))
    result = cli_process("device", "flash", "emu://v", str(bad), env={"LENTICALIB_EMULATOR_DIR": str(tmp_path)})
    assert result.returncode == 2 and "slant" in result.stderr and "Traceback" not in result.stderr


def test_busy_tcp_port_is_a_clear_error(tmp_path, cli_process):
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        result = cli_process("emulate", "--transport", "tcp", "--port", str(port), "--flash", str(tmp_path / "b.flash"))
    assert result.returncode == 2 and "--port" in result.stderr and "Traceback" not in result.stderr


def test_emulator_survives_a_client_that_resets_or_never_reads(tmp_path, cli_process):
    import socket
    import struct

    from lenticalib.device.framing import encode_frame

    with emulator_process("--transport", "tcp", "--flash", str(tmp_path / "r.flash")) as (proc, url):
        host, port = url[len("socket://"):].split(":")
        flood = encode_frame(0x01, 1, b"") * 20000  # IDENTIFY requests whose replies nobody reads
        with socket.create_connection((host, int(port))) as rude:
            rude.sendall(flood)
            rude.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))  # close = reset
        info = cli_process("device", "info", url)
        assert info.returncode == 0, info.stderr
        assert proc.poll() is None


@pytest.mark.parametrize("args,expect,absent", [
    # pyserial's "socket://<host>:<port>[?logging={debug|info|warning|error}]" never reaches the user
    (["device", "info", "socket://127.0.0.1:99999"], "socket://127.0.0.1:99999: TCP port 99999 is not in 1..65535",
     ["debug|info", "Could not open port"]),
    (["device", "info", "socket://127.0.0.1"], "is not HOST:PORT", ["debug|info"]),
    # a bad emu:// parameter speaks of the URL parameter and its range, not of --drop or udev
    (["device", "info", "emu://x?drop=2"], "emu://x?drop=2: URL parameter 'drop' must be a probability between 0 and 1",
     ["--drop", "udev", "cannot open"]),
    (["device", "info", "emu://x?via=usb&corrupt=-1"], "URL parameter 'corrupt' must be a probability",
     ["--corrupt", "udev", "read failed"]),
    (["device", "info", "emu://x?via=hid&panel=4k"], "URL parameter 'panel' must be WIDTHxHEIGHT", ["udev"]),
    (["device", "info", "emu://x?protocol=2.0"], "URL parameter 'protocol' must be 1.0 or 1.1", ["udev"]),
    # output paths: a missing folder is refused, never created, before the device is opened
    (["emulate", "--flash", "DIR/missing/x.flash"], "DIR/missing: the folder for the flash image does not exist", []),
    (["device", "read", "socket://127.0.0.1:1", "-o", "DIR/missing/p.json"],
     "DIR/missing: the folder for the profile does not exist", ["refused"]),
    (["device", "read", "emu://blank", "-o", "DIR"], "is a folder, not a file name for the profile", ["no calibration"]),
    (["emulate", "--panel", "4k"], "--panel: must be WIDTHxHEIGHT", []),
    (["emulate", "--view-counts", "1"], "--view-counts: must be 1 to 32 view counts in 2..254", []),
    (["emulate", "--protocol", "0.9"], "--protocol: must be 1.0 or 1.1", []),
    # a bare device path: the URL it most likely meant, not the generic examples
    (["device", "info", "/dev/pts/0"], "/dev/pts/0: not a device URL (did you mean serial:///dev/pts/0?)",
     ["write it like"]),
    (["device", "info", "COM3"], "COM3: not a device URL (did you mean serial://COM3?)", ["write it like"]),
    (["device", "info", "/dev/hidraw0"], "(did you mean hid://VID:PID?", ["write it like", "serial://"]),
    # a controller that never stops talking: one timeout line, within the command timeout
    (["device", "info", "emu://chatty?via=hid&babble=1"], "emu://chatty?via=hid&babble=1: the controller keeps "
     "sending unasked", ["IDENTIFY", "attempts"]),
])
def test_device_user_errors_name_the_real_cause(tmp_path, args, expect, absent, cli_process):
    args = [a.replace("DIR", str(tmp_path)) for a in args]
    result = cli_process(*args, env={"LENTICALIB_EMULATOR_DIR": str(tmp_path / "emu")})
    assert result.returncode == 2, result.stdout + result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and expect.replace("DIR", str(tmp_path)) in lines[0], result.stderr
    assert not [text for text in absent if text in lines[0]], lines[0]
    assert not (tmp_path / "missing").exists()


def test_a_disconnect_is_one_line_without_doubled_prefixes(tmp_path, cli_process):
    for transport in ("tcp", "pty"):
        with emulator_process("--transport", transport, "--flash", str(tmp_path / f"{transport}.flash"),
                              "--disconnect-after", "1") as (_, url):
            result = cli_process("device", "info", url)
        assert result.returncode == 2 and "Traceback" not in result.stderr
        (line,) = result.stderr.strip().splitlines()
        # the link died under a read or a resend: either way one prefix, the URL once
        assert re.match(f"lenticalib: error: {re.escape(url)}: (read|write) failed: [^:]", line), line
        assert line.count("failed") == 1 and line.count(url) == 1, line


def test_info_shows_a_crc_per_record_and_readable_constants(tmp_path, cli_process):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    save_profile(profile_a(), a)
    save_profile(profile_b(), b)
    env = {"LENTICALIB_EMULATOR_DIR": str(tmp_path / "emu")}
    crcs = []
    for path in (a, b, a):
        assert cli_process("device", "flash", "emu://two", str(path), env=env).returncode == 0
        info = cli_process("device", "info", "emu://two", env=env)
        record_line = info.stdout.splitlines()[-1]
        crcs.append(record_line.split("CRC-32 ")[1][:8])
        assert "2144df1c" not in record_line
    assert crcs[0] != crcs[1] and crcs[0] != crcs[2]  # the third record differs in sequence and time
    info = cli_process("device", "info", "emu://two?protocol=1.0", env=env)
    assert f"CRC-32 {crcs[2]}, from the bytes read back" in info.stdout and "panel not reported" in info.stdout
    flash_b = cli_process("device", "flash", "emu://two", str(b), env=env)
    assert flash_b.returncode == 0
    line = cli_process("device", "info", "emu://two", env=env).stdout.splitlines()[-1]
    # profile_b: slant -0.2871234567, period 17.123456789; no 17-digit floats
    assert "slant -0.2871235," in line and "period 17.123457," in line and "offset 3.25," in line
    data = json.loads(cli_process("device", "info", "emu://two", "--json", env=env).stdout)
    assert data["record"]["slant"] == profile_b().slant and data["protocol_version"] == "1.1"
    assert data["panel"] == {"width": 3840, "height": 2160, "subpixel_order": "RGB", "view_counts": [32]}


def test_a_profile_read_from_a_device_says_where_when_and_by_what(tmp_path, cli_process):
    import datetime

    from lenticalib import __version__

    env = {"LENTICALIB_EMULATOR_DIR": str(tmp_path / "emu")}
    original = tmp_path / "p.json"
    save_profile(profile_a(), original)
    assert cli_process("device", "flash", "emu://prov", str(original), env=env).returncode == 0
    back = tmp_path / "back.json"
    assert cli_process("device", "read", "emu://prov", "-o", str(back), env=env).returncode == 0
    prov = load_profile(back).provenance
    written = datetime.datetime.fromisoformat(prov["created"])
    assert written.tzinfo is not None and abs(written - datetime.datetime.now(datetime.timezone.utc)).total_seconds() < 120
    assert prov["device_url"] == "emu://prov" and prov["panel_serial"] == "EMU-PROV"
    assert prov["lenticalib_version"] == __version__ and prov["record_sequence"] == 1 and prov["read"]
    shown = cli_process("profile", "show", str(back)).stdout
    assert f"made by  read from device on {prov['created']} (lenticalib {__version__})" in shown
    assert "device emu://prov, panel serial EMU-PROV, record #1" in shown and "?" not in shown


def test_flash_refuses_a_profile_for_another_panel_unless_forced(tmp_path, cli_process):
    profile = tmp_path / "4k.json"
    save_profile(profile_a(), profile)
    with emulator_process("--flash", str(tmp_path / "hd.flash"), "--panel", "1920x1080", "--view-counts", "8,32") as (_, url):
        refused = cli_process("device", "flash", url, str(profile))
        assert refused.returncode == 2 and "Traceback" not in refused.stderr
        (line,) = refused.stderr.strip().splitlines()
        assert f"{profile}: made for another panel" in line and "profile 3840x2160 pixels, panel 1920x1080" in line
        assert "--force" in line
        assert "no calibration record" in cli_process("device", "info", url).stdout
        forced = cli_process("device", "flash", url, str(profile), "--force")
        assert forced.returncode == 0, forced.stderr
        (warning,) = forced.stderr.strip().splitlines()
        assert warning.startswith("lenticalib: warning: ") and "3840x2160" in warning and "1920x1080" in warning
        assert "verified by read-back" in forced.stdout
        assert cli_process("device", "verify", url, str(profile)).returncode == 0


def test_emulator_announces_itself_only_in_a_private_folder(tmp_path, cli_process):
    """Without XDG_RUNTIME_DIR the running emulator announces itself under TMP/lenticalib-UID, a
    name anyone may have taken first: a symbolic link or a folder others can write there is
    refused in one line before anything is created, and nothing is written through it."""
    import os
    import stat

    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "keep.txt").write_text("mine")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    root = tmp / f"lenticalib-{os.getuid()}"
    env = {"XDG_RUNTIME_DIR": "", "TMPDIR": str(tmp), "LENTICALIB_EMULATOR_DIR": str(tmp_path / "emu")}
    image = tmp_path / "a.flash"

    def refused(expect: str):
        result = cli_process("emulate", "--flash", str(image), env=env)
        assert result.returncode == 2, result.stdout + result.stderr
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and str(root) in lines[0] and expect in lines[0], result.stderr
        assert not image.exists()  # refused before the flash image was created
        listed = cli_process("device", "list", "--json", env=env)
        assert listed.returncode == 0 and expect in " ".join(json.loads(listed.stdout)["notes"])

    root.symlink_to(victim, target_is_directory=True)
    refused("is a symbolic link")
    root.unlink()
    root.mkdir()
    os.chmod(root, 0o777)
    refused("is writable by others")
    if os.geteuid() == 0:  # only root can give a folder away
        os.chmod(root, 0o700)
        os.chown(root, 65534, 65534)
        refused("belongs to another user")
        os.chown(root, 0, 0)
    os.chmod(root, 0o755)  # ours, as an older lenticalib left it: made private and used
    with emulator_process("--flash", str(image), env=env) as (_, url):
        assert stat.S_IMODE(os.stat(root).st_mode) == 0o700
        assert stat.S_IMODE(os.stat(root / "emulators").st_mode) == 0o700
        listed = cli_process("device", "list", "--json", env=env)
        assert url in [d["url"] for d in json.loads(listed.stdout)["devices"]]
    assert sorted(os.listdir(victim)) == ["keep.txt"] and (victim / "keep.txt").read_text() == "mine"
