"""Parser robustness: random and mutated frames and reports into the firmware's and the host's
parsers, well over 100,000 inputs: no crash, no hang, no write outside the calibration slots."""

from __future__ import annotations

import random
import signal
import struct

import pytest
from hypothesis import given, strategies as st

from lenticalib.device.emulator.controller import EmulatedController, ensure_image
from lenticalib.device.emulator.flash import FACTORY_SIZE, IMAGE_SIZE
from lenticalib.device.emulator.hid_device import EmulatedHidDevice
from lenticalib.device.framing import MAX_FRAME, MAX_PAYLOAD, SOF, Frame, FrameParser, encode_frame
from lenticalib.device.protocol import BEGIN_WRITE, CHUNK_HEADER, VERIFY_REPLY, Command, Identity
from lenticalib.device.record import (RECORD_SIZE, RecordFormatError, encode_record, parse_record, record_crc,
                                      record_from_profile)
from lenticalib.device.controller_families import family_for
from lenticalib.device.url import parse_device_url

from .device_support import profile_a

INPUTS = 60_000  # per side; two sides plus HID reports: > 100,000 inputs in all


@pytest.fixture
def alarm():
    """Fail instead of hanging: the whole fuzz run must finish in bounded time."""
    def timeout(signum, frame):
        raise AssertionError("fuzzing hung")

    old = signal.signal(signal.SIGALRM, timeout)
    signal.alarm(240)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def valid_requests(rng: random.Random) -> list[bytes]:
    record = encode_record(record_from_profile(profile_a(), serial="FUZZ", sequence=rng.randrange(1, 9)))
    payloads = {
        Command.IDENTIFY: b"", Command.READ_RECORD: b"", Command.VERIFY: b"", Command.COMMIT: b"",
        Command.REBOOT: b"",
        Command.BEGIN_WRITE: BEGIN_WRITE.pack(1, RECORD_SIZE, record_crc(record), rng.randrange(1, 12)),
        Command.WRITE_CHUNK: CHUNK_HEADER.pack(rng.randrange(0, 160, 32)) + record[:32],
    }
    return [encode_frame(cmd, rng.randrange(256), payload) for cmd, payload in payloads.items()]


def mutate(rng: random.Random, data: bytes) -> bytes:
    out = bytearray(data)
    for _ in range(rng.randrange(1, 4)):
        kind = rng.randrange(6)
        if kind == 0 and out:
            out[rng.randrange(len(out))] ^= 1 << rng.randrange(8)
        elif kind == 1 and out:
            del out[rng.randrange(len(out)):]
        elif kind == 2:
            out[rng.randrange(len(out) + 1):0] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 9)))
        elif kind == 3 and len(out) > 3:
            out[1:3] = struct.pack("<H", rng.randrange(65536))  # a lying LEN field
        elif kind == 4:
            out += bytes([0xA5]) * rng.randrange(1, 4)
        else:
            out = bytearray(rng.randbytes(rng.randrange(0, 64))) + out
    return bytes(out)


def flash_session(rng: random.Random, sequence: int) -> bytes:
    """A complete, valid BEGIN_WRITE, 4 x WRITE_CHUNK, COMMIT exchange for record ``sequence``."""
    record = encode_record(record_from_profile(profile_a(), serial="FUZZ", sequence=sequence))
    out = encode_frame(Command.BEGIN_WRITE, rng.randrange(256), BEGIN_WRITE.pack(1, RECORD_SIZE, record_crc(record),
                                                                                  sequence))
    for offset in range(0, RECORD_SIZE, 32):
        out += encode_frame(Command.WRITE_CHUNK, rng.randrange(256), CHUNK_HEADER.pack(offset) + record[offset:offset + 32])
    return out + encode_frame(Command.COMMIT, rng.randrange(256))


def fuzz_inputs(rng: random.Random, count: int):
    frames = valid_requests(rng)
    for i in range(count):
        kind = i % 4
        if i % 97 == 0:
            session = flash_session(rng, 1 + i // 97)  # commits move the current slot between fuzzing
            yield session if i % 2 else mutate(rng, session)
        elif kind == 0:
            yield rng.randbytes(rng.randrange(0, 300))
        elif kind == 1:
            yield mutate(rng, rng.choice(frames))
        elif kind == 2:
            yield rng.choice(frames)  # valid frames keep the firmware's state machine moving
        else:
            yield encode_frame(rng.randrange(256), rng.randrange(256), rng.randbytes(rng.randrange(0, 200)))
        if i % 500 == 0:
            frames = valid_requests(rng)


def test_firmware_parser_survives_random_and_mutated_frames(tmp_path, alarm):
    image = ensure_image(tmp_path / "fuzz.flash")
    factory = image.read_bytes()[:FACTORY_SIZE]
    controller = EmulatedController(image)
    firmware = controller.firmware
    rng = random.Random(20261122)
    replies = 0
    for data in fuzz_inputs(rng, INPUTS):
        for reply in firmware.receive(data):  # raises nothing; every reply is a well-formed frame
            frames = FrameParser().feed(reply)
            assert len(frames) == 1 and frames[0].is_reply and len(frames[0].payload) >= 1
            replies += 1
        assert len(firmware.parser._buffer) <= MAX_FRAME
    assert replies > INPUTS // 4
    assert all(FACTORY_SIZE <= addr and addr + n <= IMAGE_SIZE for _, addr, n in controller.flash.log)
    assert sum(kind == "erase" for kind, _, _ in controller.flash.log) > 100, "the fuzzing rarely reached the flash"
    assert firmware.current_sequence > 100, "few commits: the fuzzing exercised too little of the state machine"
    controller.close()
    data = image.read_bytes()
    assert len(data) == IMAGE_SIZE and data[:FACTORY_SIZE] == factory  # the factory block is untouched


def test_host_parsers_survive_random_and_mutated_replies(alarm):
    rng = random.Random(7)
    record = encode_record(record_from_profile(profile_a(), serial="FUZZ", sequence=3))
    identity = Identity(1, 1, 3, 32, 128, "LC-32", "1.0", "SER").pack()
    good = [encode_frame(0x81, 1, b"\0" + identity), encode_frame(0x82, 2, b"\0\1" + record),
            encode_frame(0x86, 3, b"\0" + VERIFY_REPLY.pack(1, 3, 77))]
    parser = FrameParser()
    decoded = 0
    for i in range(INPUTS):
        data = rng.randbytes(rng.randrange(0, 300)) if i % 2 else mutate(rng, rng.choice(good))
        for frame in parser.feed(data):
            body = frame.payload[1:]
            for decode in (Identity.unpack, lambda b: parse_record(b[1:]), VERIFY_REPLY.unpack):
                try:
                    decode(body)
                    decoded += 1
                except (ValueError, struct.error, RecordFormatError):
                    pass
        assert len(parser._buffer) <= MAX_FRAME
    assert decoded > 0


def test_hid_reports_fuzzed_into_the_emulated_device(tmp_path, monkeypatch, alarm):
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path))
    family = family_for()
    device = EmulatedHidDevice(parse_device_url("emu://hidfuzz?via=hid"), family.transport("hid"))
    device.open(0x1209, 0x0002)
    rng = random.Random(3)
    frames = valid_requests(rng)
    for i in range(20_000):
        if i % 2:
            report = rng.randbytes(rng.choice([64, rng.randrange(0, 80)]))
        else:
            piece = mutate(rng, rng.choice(frames))[:62]
            report = bytes([1, len(piece)]) + piece + bytes(62 - len(piece))
        assert device.write(report) in (64, -1)
        device.read(64, 0)
    flash = device.controller.flash
    assert all(FACTORY_SIZE <= addr and addr + n <= IMAGE_SIZE for _, addr, n in flash.log)
    device.close()


@given(st.binary(max_size=400))
def test_any_bytes_parse_without_error(data):
    parser = FrameParser()
    for frame in parser.feed(data):  # a CRC-valid frame in random bytes is rare; the next test builds them
        assert encode_frame(frame.cmd, frame.seq, frame.payload) in data
    assert len(parser._buffer) <= MAX_FRAME


built_frames = st.builds(Frame, st.integers(0, 255), st.integers(0, 255), st.binary(max_size=MAX_PAYLOAD))
# noise without SOF: a SOF in noise may announce a longer frame, and the parser rightly waits for it
noise = st.binary(max_size=24).map(lambda b: b.replace(bytes([SOF]), b""))


@given(st.lists(st.tuples(noise, built_frames), min_size=1, max_size=4), st.binary(max_size=24), st.data())
def test_built_frames_round_trip_through_noise_in_any_pieces(pieces, tail, data):
    """CRC-valid frames built on purpose, noise between them, the stream cut anywhere: the
    parser returns exactly those frames, in order, with their CMD, SEQ and payload."""
    stream = b"".join(junk + encode_frame(f.cmd, f.seq, f.payload) for junk, f in pieces) + tail
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=6)))
    parser = FrameParser()
    got = []
    for a, b in zip([0, *cuts], [*cuts, len(stream)]):
        got += parser.feed(stream[a:b])
        assert len(parser._buffer) <= MAX_FRAME
    want = [f for _, f in pieces]
    assert got[:len(want)] == want  # the tail may hold more (random) frames, never fewer before it


@given(st.binary(min_size=RECORD_SIZE, max_size=RECORD_SIZE))
def test_any_record_bytes_decode_or_raise_record_format_error(data):
    try:
        record = parse_record(data)
    except RecordFormatError:
        return
    assert encode_record(record) == data
