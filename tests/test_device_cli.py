"""The device CLI end to end against an emulator on a pseudo-terminal: flash, read back,
verify, compare with the original profile; and every user error as one line, exit 2."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from lenticalib.profile import load_profile, save_profile

from .device_support import REPO, emulator_process, profile_a, profile_b, same_constants


def cli(*args, env=None):
    import os

    return subprocess.run([sys.executable, "-m", "lenticalib.cli", *args], capture_output=True, text=True,
                          cwd=REPO, env={**os.environ, **(env or {})}, timeout=120)


def test_emulate_flash_read_verify_compare(tmp_path):
    original = tmp_path / "panel.json"
    save_profile(profile_b(), original)
    image = tmp_path / "panel.flash"
    with emulator_process("--flash", str(image)) as (_, url):
        assert url.startswith("serial:///dev/pts/")
        info = cli("device", "info", url)
        assert info.returncode == 0 and "no calibration record" in info.stdout
        flashed = cli("device", "flash", url, str(original))
        assert flashed.returncode == 0, flashed.stderr
        assert "verified by read-back" in flashed.stdout
        back = tmp_path / "back.json"
        read = cli("device", "read", url, "-o", str(back))
        assert read.returncode == 0, read.stderr
        verify = cli("device", "verify", url, str(original))
        assert verify.returncode == 0 and "holds" in verify.stdout
        compare = cli("profile", "compare", str(back), str(original), "--json")
        assert compare.returncode == 0
        report = json.loads(compare.stdout)
        assert report["rms"] == 0.0 and report["worst"] == 0.0 and report["order_match"]
        assert same_constants(load_profile(back), profile_b())
        info = json.loads(cli("device", "info", url, "--json").stdout)
        assert info["record"]["sequence"] == 1 and info["serial"]
        listed = cli("device", "list", "--json")
        assert url in [d["url"] for d in json.loads(listed.stdout)["devices"]]
        other = tmp_path / "other.json"
        save_profile(profile_a(), other)
        mismatch = cli("device", "verify", url, str(other))
        assert mismatch.returncode == 1 and "slant: device" in mismatch.stdout
    # the flash image persists across emulator restarts
    with emulator_process("--flash", str(image), "--transport", "tcp") as (_, url):
        assert url.startswith("socket://127.0.0.1:")
        assert cli("device", "verify", url, str(original)).returncode == 0


def test_cli_power_cut_then_recover(tmp_path):
    profile = tmp_path / "p.json"
    save_profile(profile_b(), profile)
    image = tmp_path / "x.flash"
    with emulator_process("--flash", str(image), "--power-cut-after", "3") as (proc, url):
        result = cli("device", "flash", url, str(profile))
        assert result.returncode == 2 and "Traceback" not in result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
    with emulator_process("--flash", str(image)) as (_, url):
        assert "no calibration record" in cli("device", "info", url).stdout
        assert cli("device", "flash", url, str(profile)).returncode == 0
        assert cli("device", "verify", url, str(profile)).returncode == 0


@pytest.mark.parametrize("args,expect", [
    (["device", "info", "serial:///dev/does-not-exist"], "/dev/does-not-exist"),
    (["device", "info", "ttyACM0"], "not a device URL"),
    (["device", "info", "hid://12:34"], "VID:PID"),
    (["device", "info", "carrier-pigeon://x"], "unknown transport"),
    (["device", "info", "emu://x?via=bluetooth"], "unknown via"),
    (["device", "info", "emu://x?explode=1"], "unknown option"),
    (["device", "info", "usb://1209:0003"], "usb://1209:0003"),
    (["device", "read", "emu://blank", "-o", "OUT"], "no calibration record"),
    (["device", "flash", "emu://x", "missing.json"], "missing.json"),
    (["emulate", "--drop", "2"], "--drop"),
    (["emulate", "--torn"], "--power-cut-after"),
    (["emulate", "--flash", "DIR"], "cannot open the flash image"),
    (["emulate", "--flash", "DIR/new.flash", "--serial", "\u00c4\u00d6"], "--serial"),
    (["emulate", "--delay-s", "-1"], "--delay-s"),
])
def test_user_errors_are_one_line(tmp_path, args, expect):
    args = [a.replace("OUT", str(tmp_path / "o.json")).replace("DIR", str(tmp_path)) for a in args]
    result = cli(*args, env={"LENTICALIB_EMULATOR_DIR": str(tmp_path / "emu")})
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and expect in lines[0], result.stderr
    assert not (tmp_path / "o.json").exists()


def test_flash_refuses_an_invalid_profile_before_sending(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**profile_a().to_dict(), "slant": 12.0}))
    result = cli("device", "flash", "emu://v", str(bad), env={"LENTICALIB_EMULATOR_DIR": str(tmp_path)})
    assert result.returncode == 2 and "slant" in result.stderr and "Traceback" not in result.stderr


def test_busy_tcp_port_is_a_clear_error(tmp_path):
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        result = cli("emulate", "--transport", "tcp", "--port", str(port), "--flash", str(tmp_path / "b.flash"))
    assert result.returncode == 2 and "--port" in result.stderr and "Traceback" not in result.stderr


def test_emulator_survives_a_client_that_resets_or_never_reads(tmp_path):
    import socket
    import struct

    from lenticalib.device.framing import encode_frame

    with emulator_process("--transport", "tcp", "--flash", str(tmp_path / "r.flash")) as (proc, url):
        host, port = url[len("socket://"):].split(":")
        flood = encode_frame(0x01, 1, b"") * 20000  # IDENTIFY requests whose replies nobody reads
        with socket.create_connection((host, int(port))) as rude:
            rude.sendall(flood)
            rude.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))  # close = reset
        info = cli("device", "info", url)
        assert info.returncode == 0, info.stderr
        assert proc.poll() is None
