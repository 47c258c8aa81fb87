#!/usr/bin/env python3
"""Record a protocol-v1 session with the emulated LC-32 firmware as a golden fixture.

The session is a complete flash of ``fixtures/panel-4k-32.json`` on a blank controller, then a
reboot and a read: every request frame and the controller's reply, in hex.  Sequence numbers
and the record's timestamp are fixed, so the file is reproducible byte for byte.
``tests/test_device_session.py`` replays it against the firmware (replies must be identical)
and decodes every reply with the host's parsers: a change that breaks wire compatibility
fails there.  A session recorded from real hardware in the same format can be replayed the
same way.

    python tools/record_device_session.py [--out fixtures/device-sessions/lc32-flash.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
from pathlib import Path

from lenticalib.core.files.atomic import write_text_atomic
from lenticalib.device.emulator.controller import DEFAULT_FIRMWARE, DEFAULT_MODEL, default_panel
from lenticalib.device.emulator.firmware import Firmware
from lenticalib.device.emulator.flash import FlashImage, create_image
from lenticalib.device.framing import encode_frame
from lenticalib.device.protocol import BEGIN_WRITE, CHUNK_HEADER, PROTOCOL_MINOR, PROTOCOL_VERSION, Command
from lenticalib.device.record import RECORD_SIZE, encode_record, record_crc, record_from_profile
from lenticalib.core.profile import load_profile

REPO = Path(__file__).resolve().parents[1]
SERIAL = "LC32-GOLDEN"
WRITTEN = 1795300000  # fixed record timestamp (2026-11-22)


def session_requests(profile_path: Path) -> list[tuple[Command, bytes]]:
    record = encode_record(record_from_profile(load_profile(profile_path), serial=SERIAL, sequence=1,
                                               written=WRITTEN))
    requests = [(Command.IDENTIFY, b""), (Command.VERIFY, b""),
                (Command.BEGIN_WRITE, BEGIN_WRITE.pack(1, RECORD_SIZE, record_crc(record), 1))]
    requests += [(Command.WRITE_CHUNK, CHUNK_HEADER.pack(o) + record[o:o + 32]) for o in range(0, RECORD_SIZE, 32)]
    requests += [(Command.COMMIT, b""), (Command.READ_RECORD, b""), (Command.VERIFY, b""), (Command.REBOOT, b""),
                 (Command.READ_RECORD, b"")]
    return requests


def record_session(profile_path: Path) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        image = Path(tmp) / "golden.flash"
        create_image(image, model=DEFAULT_MODEL, serial=SERIAL, firmware_version=DEFAULT_FIRMWARE)
        flash = FlashImage(image)
        firmware = Firmware(flash, default_panel())
        exchanges = []
        for seq, (command, payload) in enumerate(session_requests(profile_path), start=1):
            request = encode_frame(command, seq, payload)
            (reply,) = firmware.receive(request)
            exchanges.append({"command": command.name, "request": request.hex(), "reply": reply.hex()})
        flash.close()
    return {"format": "lenticalib.device-session", "format_version": 1, "protocol_version": PROTOCOL_VERSION,
            "protocol_minor": PROTOCOL_MINOR,
            "controller": {"model": DEFAULT_MODEL, "serial": SERIAL, "firmware_version": DEFAULT_FIRMWARE,
                           "panel": dataclasses.asdict(default_panel())},
            "profile": str(profile_path.relative_to(REPO)), "exchanges": exchanges}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO / "fixtures" / "device-sessions" / "lc32-flash.json")
    args = parser.parse_args()
    session = record_session(REPO / "fixtures" / "panel-4k-32.json")
    write_text_atomic(args.out, json.dumps(session, indent=1) + "\n")
    print(f"wrote {args.out} ({len(session['exchanges'])} exchanges)")


if __name__ == "__main__":
    main()
