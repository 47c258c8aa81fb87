"""Live control streams under hostile input: UDP (127.0.0.1 only) and a stdin-like pipe.

Every hostile line -- nested too deep, integers beyond Python's digit limit or float32, float64
values that float32 cannot hold, NaN/Infinity tokens, wrong types and shapes, non-UTF-8 bytes,
lines over the length limit -- is counted bad, and the valid line sent after them is delivered:
the reader thread stays alive.  A reader that dies anyway shows in ``stats["failed"]``.  A port
open to the network (``udp://0.0.0.0``) is a warning naming the exposure, printed by ``play``.
"""

from __future__ import annotations

import io
import json
import logging
import os
import select
import socket
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lenticalib.render.controls.records import FLOAT32_MAX
from lenticalib.render.controls.streams import MAX_LINE_BYTES, open_text_stream, open_udp
from lenticalib.render.avatar.rig import DEFAULT_LAYOUT as L

D = L.dim
JAW = L.slice("jaw").start
EXAMPLES = 25


def _json(obj) -> bytes:
    return json.dumps(obj).encode()


def _clean(data: bytes) -> bytes:
    """No line breaks inside one hostile line."""
    return data.replace(b"\n", b"").replace(b"\r", b"")


_TEXT = st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\n\r"), min_size=1,
                max_size=40).filter(lambda s: s.strip())

# one hostile line each (no newline inside), every one counted as exactly one bad line
HOSTILE = st.one_of(
    st.integers(1000, 60000).map(lambda n: b"[" * n),                                        # nested, unterminated
    st.integers(1000, 20000).map(lambda n: b'{"controls": ' + b"[" * n + b"]" * n + b"}"),   # nested, closed
    st.integers(4301, 9000).map(lambda n: b'{"jaw": [' + b"7" * n + b", 0, 0]}"),            # beyond the digit limit
    st.integers(39, 4200).map(lambda e: b'{"jaw": [1' + b"0" * e + b", 0, 0]}"),             # 10**39 .. 10**4200
    st.floats(3.5e38, 1.7e308).map(lambda v: _json({"jaw": [v, 0, 0]})),                    # inf once float32
    st.floats(3.5e38, 1.7e308).map(lambda v: _json({"controls": [0.0] * (D - 1) + [-v]})),
    st.sampled_from([b'{"jaw": [NaN, 0, 0]}', b'{"jaw": [0, Infinity, 0]}', b'{"controls": [-Infinity]}',
                     b'{"t": NaN, "jaw": [0, 0, 0]}', b'{"t": 1' + b"0" * 400 + b', "jaw": [0, 0, 0]}',
                     b'{"t": 1e999, "jaw": [0, 0, 0]}', b"{}", b'{"t": 1}', b"[]", b"null"]),
    st.one_of(st.none(), st.booleans(), st.integers(), _TEXT, st.dictionaries(_TEXT, st.integers(), max_size=3),
              st.lists(st.integers(), min_size=4, max_size=9)).map(lambda v: _json({"jaw": v})),  # wrong type
    st.integers(0, 2 * D).filter(lambda n: n != D).map(lambda n: _json({"controls": [0.0] * n})),  # wrong shape
    st.dictionaries(_TEXT.filter(lambda k: k not in L and k != "t"), st.integers(), min_size=1,
                    max_size=3).map(_json),                                                  # unknown groups
    st.one_of(st.integers(), _TEXT, st.lists(st.integers(), max_size=5)).map(_json),          # not an object
    st.binary(max_size=100).map(lambda b: b"\xff" + _clean(b)),                               # not UTF-8
    _TEXT.map(lambda s: _clean(s.encode())).filter(lambda b: b.strip()),                      # not JSON
)
# longer than the limit although valid JSON (trailing blanks): only a stream of lines can carry them
OVERLONG = st.integers(MAX_LINE_BYTES - 10, 3 * MAX_LINE_BYTES).map(lambda n: b'{"jaw": [0.5, 0, 0]}' + b" " * n)
VALUE = st.floats(-1.0, 1.0, width=32)


def _wait(pred, timeout=10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.002)
    return pred()


def _delivered(src, value) -> None:
    assert src.stats["failed"] is None, src.stats
    t, c = src.latest()
    assert c[JAW] == np.float32(value) and not c[JAW + 1:JAW + 3].any(), src.stats


def test_udp_stream_counts_hostile_datagrams_and_delivers_the_next_valid_one():
    with open_udp("udp://127.0.0.1:0", L) as src, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        @settings(max_examples=EXAMPLES)
        @given(st.lists(HOSTILE, min_size=1, max_size=4), VALUE)
        def check(hostile, value):
            for datagram in hostile:  # one at a time: nothing is dropped by a full socket buffer
                bad = src.stats["bad"]
                tx.sendto(datagram, src.address)
                assert _wait(lambda: src.stats["bad"] == bad + 1), (datagram[:80], src.stats)
            received = src.stats["received"]
            tx.sendto(_json({"jaw": [value, 0, 0]}), src.address)
            assert _wait(lambda: src.stats["received"] == received + 1), src.stats
            _delivered(src, value)

        check()
        assert src.stats["ended"] is False and src.stats["failed"] is None


def _write_all(fd: int, data: bytes, timeout: float = 10.0) -> None:
    """Write ``data`` into the pipe ``fd`` (non-blocking) as the reader drains it; fail if it stops reading."""
    end = time.monotonic() + timeout
    while data:
        _, ready, _ = select.select([], [fd], [], max(0.0, end - time.monotonic()))
        assert ready, f"the reader stopped reading with {len(data)} bytes left"
        data = data[os.write(fd, data):]


def test_stdin_stream_counts_hostile_lines_and_delivers_the_next_valid_one():
    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)
    with os.fdopen(read_end, "rb") as reader:
        src = open_text_stream(reader, L, name="stdin")
        try:
            @settings(max_examples=EXAMPLES)
            @given(st.lists(HOSTILE, max_size=3), OVERLONG, st.integers(0, 3), VALUE)
            def check(hostile, overlong, where, value):
                hostile = hostile[:where] + [overlong] + hostile[where:]
                bad, received = src.stats["bad"], src.stats["received"]
                _write_all(write_end, b"".join(line + b"\n" for line in hostile))
                _write_all(write_end, _json({"jaw": [value, 0, 0]}) + b"\n")
                assert _wait(lambda: src.stats["received"] == received + 1), src.stats
                assert src.stats["bad"] == bad + len(hostile), src.stats
                _delivered(src, value)

            check()
            assert src.stats["ended"] is False
        finally:
            os.close(write_end)
        assert _wait(lambda: src.stats["ended"])
        src.close()


class _Recording(io.BytesIO):
    """A stdin-like pipe that remembers the longest piece the reader took at once."""

    longest = 0

    def readline(self, size=-1):
        line = super().readline(size)
        self.longest = max(self.longest, len(line))
        return line


def test_an_overlong_line_is_read_in_bounded_pieces_discarded_and_counted():
    valid_but_long = b'{"jaw": [0.25, 0, 0]}' + b" " * (4 * MAX_LINE_BYTES)
    stream = _Recording(valid_but_long + b"\n" + b"x" * (MAX_LINE_BYTES + 1) + b"\n" + b'{"jaw": [0.5, 0, 0]}\n'
                        + b"y" * (2 * MAX_LINE_BYTES))  # the last line has no newline
    src = open_text_stream(stream, L, name="stdin")
    assert _wait(lambda: src.stats["ended"])
    assert src.stats["received"] == 1 and src.stats["bad"] == 3, src.stats
    assert src.latest()[1][JAW] == 0.5
    assert stream.longest == MAX_LINE_BYTES + 1  # never more than the limit (and one byte) in memory
    assert src.stats["last_error"] == f"stdin line 4: {2 * MAX_LINE_BYTES} bytes, longer than the limit of " \
                                      f"{MAX_LINE_BYTES}"
    src.close()


def test_a_line_exactly_at_the_limit_is_read():
    line = b'{"jaw": [0.125, 0, 0]}'
    src = open_text_stream(io.BytesIO(line + b" " * (MAX_LINE_BYTES - len(line)) + b"\n"), L, name="stdin")
    assert _wait(lambda: src.stats["ended"])
    assert src.stats["received"] == 1 and src.stats["bad"] == 0 and src.latest()[1][JAW] == 0.125


def test_values_are_checked_as_float32():
    largest = float(np.float32(FLOAT32_MAX))
    src = open_text_stream(io.StringIO(_json({"jaw": [largest, 0, 0]}).decode() + "\n"
                                       + _json({"jaw": [1e39, 0, 0]}).decode() + "\n"), L, name="stdin")
    assert _wait(lambda: src.stats["ended"])
    assert src.stats["received"] == 1 and src.stats["bad"] == 1, src.stats
    assert "jaw[0] is 1e+39, out of range: float32" in src.stats["last_error"]
    assert np.isfinite(src.latest()[1]).all()


class _BreaksAfterOneLine:
    """A file object whose second read fails in a way no reader expects."""

    def __init__(self):
        self.calls = 0

    def readline(self, size=-1):
        self.calls += 1
        if self.calls == 1:
            return b'{"jaw": [0.3, 0, 0]}\n'
        raise RuntimeError("the device vanished\nwith a second line")


def test_a_reader_that_dies_does_not_look_healthy(caplog):
    src = open_text_stream(_BreaksAfterOneLine(), L, name="stdin")
    assert _wait(lambda: src.stats["failed"] is not None)
    stats = src.stats
    assert stats["received"] == 1 and stats["ended"] is False
    assert stats["failed"] == "stdin: the reader stopped on RuntimeError: the device vanished"
    with caplog.at_level(logging.WARNING, logger="lenticalib.render.controls.streams"):
        t, c = src.latest()
        src.latest()
    assert c[JAW] == np.float32(0.3)  # the last valid pose stays
    warnings = [r.getMessage() for r in caplog.records]
    assert warnings == ["stdin: the reader stopped on RuntimeError: the device vanished; the pose stays at the "
                        "last valid line"]  # once, not every frame
    assert "the reader stopped" in src.summary()
    src.close()


def test_a_udp_port_open_to_the_network_says_so():
    """UDP has no sender check: a port bound to every interface (or a network address) is a warning
    naming the exposure; a loopback port is not."""
    from lenticalib.render.controls.streams import exposure_warning

    with open_udp("udp://0.0.0.0:0", L) as src:
        port = src.address[1]
        told = src.take_warnings()
        assert told == [f"udp://0.0.0.0:{port} listens on every network interface (0.0.0.0): any sender on the "
                        f"network can drive the avatar, unchecked (listen on udp://127.0.0.1:{port} to take this "
                        "machine's senders only)"]
        assert src.take_warnings() == []  # said once
    with open_udp("udp://127.0.0.1:0", L) as src:
        assert src.take_warnings() == []
    assert "every network interface (::)" in exposure_warning("::", 9000)
    assert "the network address 192.168.1.5" in exposure_warning("192.168.1.5", 9000)
    assert exposure_warning("::1", 9000) is None and exposure_warning("::ffff:127.0.0.1", 9000) is None


def test_play_prints_the_exposure_of_a_udp_port(cli, tmp_path):
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig

    from .cli_support import REPO

    save_rig(tmp_path / "demo.npz", make_demo_avatar(seed=2, count=2000))
    code, out, err = cli("play", tmp_path / "demo.npz", "--profile", REPO / "fixtures" / "panel-4k-32.json",
                         "--headless", "--frames", "1", "--view-size", "96x54", "--controls", "udp://0.0.0.0:0")
    assert code == 0, err
    told = [line for line in err.splitlines() if "udp://" in line]
    assert len(told) == 1 and told[0].startswith("lenticalib: warning: udp://0.0.0.0:"), err
    assert "listens on every network interface" in told[0] and "any sender on the network can drive" in told[0]


# ------------------------------------------------------------------ control files: bounded reading

def test_a_control_file_past_the_track_cap_is_refused_as_it_is_read(tmp_path, monkeypatch):
    """Rows are stored as float32 as they are read and counted against MAX_TRACK_BYTES (256 MiB,
    made small here), in every format; the line that passes it is named."""
    from lenticalib.core.errors import InputError
    from lenticalib.render.controls import files as controls

    monkeypatch.setattr(controls, "MAX_TRACK_BYTES", 64 * 1024)
    most = 64 * 1024 // (8 + 4 * D + 4)  # 224 samples of the 70 default controls
    (tmp_path / "ok.csv").write_text("t,jaw.0\n" + "".join(f"{k / 30},0.5\n" for k in range(most)))
    track = controls.load_controls(tmp_path / "ok.csv")
    assert len(track) == most and track.controls.dtype == np.float32 and track.controls[-1, JAW] == 0.5
    (tmp_path / "long.csv").write_text("t,jaw.0\n" + "".join(f"{k / 30},0\n" for k in range(most + 1)))
    (tmp_path / "long.jsonl").write_text("".join(f'{{"t": {k / 30}, "jaw": [0, 0, 0]}}\n' for k in range(most + 1)))
    for name, line in (("long.csv", most + 2), ("long.jsonl", most + 1)):
        with pytest.raises(InputError) as err:
            controls.load_controls(tmp_path / name)
        assert str(err.value).startswith(f"{tmp_path / name}:{line}: holds more than {most} samples of {D} controls")
    np.savez(tmp_path / "long.npz", t=np.arange(2.0 * most), controls=np.zeros((2 * most, D), np.float32))
    with pytest.raises(InputError, match="exceed the limit of 64.0 KiB|more than a .npz file can sensibly hold"):
        controls.load_controls(tmp_path / "long.npz")


def test_overlong_lines_and_huge_text_control_files_are_one_line(tmp_path):
    from lenticalib.core.errors import InputError
    from lenticalib.render.controls.files import MAX_TEXT_BYTES, MAX_TEXT_LINE, load_controls

    (tmp_path / "wide.csv").write_text("t,jaw.0\n0," + "7" * (MAX_TEXT_LINE + 10) + "\n")
    (tmp_path / "wide.jsonl").write_text('{"t": 0, "jaw": [' + " " * (MAX_TEXT_LINE + 10) + "0, 0, 0]}\n")
    (tmp_path / "field.csv").write_text("t,jaw.0\n0," + "7" * 200_000 + "\n")  # over csv's field limit
    for name, words in (("wide.csv", ": line 2 is longer than 1.0 MiB"), ("wide.jsonl", ": line 1 is longer than"),
                        ("field.csv", ":2: is not a CSV row (field larger than field limit")):
        with pytest.raises(InputError) as err:
            load_controls(tmp_path / name)
        assert words in str(err.value) and "\n" not in str(err.value), str(err.value)[:200]
    with open(tmp_path / "huge.csv", "wb") as fh:  # sparse: no disk taken
        fh.truncate(MAX_TEXT_BYTES + 1)
    with pytest.raises(InputError, match="more than a control file can sensibly hold"):
        load_controls(tmp_path / "huge.csv")
