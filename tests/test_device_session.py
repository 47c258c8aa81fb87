"""Replay the recorded golden session (fixtures/device-sessions/lc32-flash.json): the firmware
must answer every request byte for byte as recorded, and the host's parsers must decode every
reply to the recorded profile.  Wire-format changes fail here."""

from __future__ import annotations

import json

from lenticalib.device.emulator.firmware import Firmware
from lenticalib.device.emulator.flash import FlashImage, create_image
from lenticalib.device.framing import FrameParser
from lenticalib.device.protocol import SLOT_SEQUENCE, VERIFY_REPLY, Identity, PanelGeometry
from lenticalib.device.record import LEGACY_CRC_RESIDUE, decode_record, record_crc
from lenticalib.core.profile import load_profile

from .device_support import REPO

SESSION = REPO / "fixtures" / "device-sessions" / "lc32-flash.json"


def test_firmware_replays_the_recorded_session(tmp_path):
    session = json.loads(SESSION.read_text())
    ctrl = session["controller"]
    image = tmp_path / "replay.flash"
    create_image(image, model=ctrl["model"], serial=ctrl["serial"], firmware_version=ctrl["firmware_version"])
    flash = FlashImage(image)
    panel = ctrl["panel"]
    firmware = Firmware(flash, PanelGeometry(panel["width"], panel["height"], panel["subpixel_order"],
                                             tuple(panel["view_counts"])), protocol_minor=session["protocol_minor"])
    for exchange in session["exchanges"]:
        replies = firmware.receive(bytes.fromhex(exchange["request"]))
        assert [r.hex() for r in replies] == [exchange["reply"]], exchange["command"]
    flash.close()


def test_host_decodes_the_recorded_replies():
    session = json.loads(SESSION.read_text())
    profile = load_profile(REPO / session["profile"])
    replies = {}
    for exchange in session["exchanges"]:
        (frame,) = FrameParser().feed(bytes.fromhex(exchange["reply"]))
        request = FrameParser().feed(bytes.fromhex(exchange["request"]))[0]
        assert frame.cmd == request.cmd | 0x80 and frame.seq == request.seq
        replies.setdefault(exchange["command"], []).append(frame.payload)
    identity = Identity.unpack(replies["IDENTIFY"][0][1:])
    assert identity.serial == session["controller"]["serial"] and identity.protocol_version == 1
    assert identity.protocol_minor == session["protocol_minor"] == 1
    assert identity.panel == PanelGeometry(3840, 2160, "RGB", (32,))
    assert replies["VERIFY"][0][0] == 0x0A  # NO_RECORD on the blank controller
    assert SLOT_SEQUENCE.unpack(replies["COMMIT"][0][1:]) == (0, 1)
    for payload in replies["READ_RECORD"]:  # before and after the reboot
        assert payload[0] == 0 and payload[1] == 0
        record = decode_record(payload[2:], "session")
        assert record.to_profile().routing_key() == profile.routing_key()
    slot, sequence, crc = VERIFY_REPLY.unpack(replies["VERIFY"][1][1:])
    assert (slot, sequence) == (0, 1)
    # protocol 1.1: VERIFY identifies the record (its stored CRC over bytes 0..123), not the residue
    record_bytes = replies["READ_RECORD"][0][2:]
    assert crc == record_crc(record_bytes) == int.from_bytes(record_bytes[124:], "little") != LEGACY_CRC_RESIDUE
