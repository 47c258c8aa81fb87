"""Control sources: where the control vectors that drive an avatar come from, frame by frame.

Every source answers ``latest(now)`` with ``(t, controls)``: a timestamp in seconds and a (D,)
float32 numpy vector laid out as the rig's :class:`~.rig.ControlLayout` says (see :mod:`.rig`).
The render loop asks once per frame; nothing here blocks it.

    spec (open_controls)  source
    "demo"                :class:`DemoControls`, the built-in motion (:func:`demo_controls`): a slow head turn,
                          talking, blinks
    PATH.npz|csv|jsonl    :class:`FileControls` over a :class:`ControlTrack` read by :func:`load_controls`,
                          validated completely before it is returned; played by linear interpolation
                          between samples, looping
    "-" or "stdin"        :class:`StreamControls`: JSON lines on standard input, read by a background thread
    "udp://HOST:PORT"     :class:`StreamControls`: JSON lines in UDP datagrams (several lines per datagram
                          allowed), read by a background thread; port 0 picks a free port (``.address``)

File formats (times in seconds, non-decreasing; every value finite):

    .npz    arrays ``t`` (T,) and ``controls`` (T, D), nothing pickled
    .csv    a header row; the first column is ``t``, the others name control components as
            ``GROUP.I`` (``jaw.0``, ``expression.12``) or by the rig's component names (``jaw.x``,
            ``expression.smile``); components without a column are 0; each row t, values
    .jsonl  (also .ndjson, .json) one JSON object per line, blank lines skipped, either
            ``{"t": 0.0, "controls": [D numbers]}`` or group-keyed
            ``{"t": 0.0, "jaw": [0.1, 0, 0], "head": [0, 0.2, 0]}`` where every group given must have
            its full size (a size-1 group may be a bare number) and groups not given are 0.

Live streams take the same JSON objects; ``t`` is optional there (the arrival time since the
stream opened is used) and informative only: ``latest()`` returns the most recently *received*
valid line.  Bad lines (not JSON, an unknown group, a wrong length, non-finite values) are
counted, the first ones logged, and the last error kept (:attr:`StreamControls.stats`); they
never stop the stream or the loop.  Before the first valid line ``latest()`` returns
``(None, zeros)``, the neutral pose.

In files every error is one InputError naming the file and line (CSV and JSON lines count from 1,
the CSV header being line 1) or the array, with the expected dimension and layout.
"""

from __future__ import annotations

import csv
import json
import logging
import math
import os
import socket
import sys
import threading
import time
import zipfile
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np

from ..errors import InputError
from .rig import DEFAULT_LAYOUT, ControlLayout

log = logging.getLogger(__name__)

_JSONL_SUFFIXES = (".jsonl", ".ndjson", ".json")


# ------------------------------------------------------------------ records

def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def parse_control_record(obj: Any, layout: ControlLayout, source: str, *, require_t: bool = True
                         ) -> tuple[float | None, np.ndarray]:
    """One JSON control object (module docstring) -> (t or None, (D,) float32); InputError naming ``source``."""
    hint = f"expected {layout.dim} values: {layout.describe()}"
    if not isinstance(obj, dict):
        raise InputError(f"expected a JSON object, got {type(obj).__name__}", source=source,
                         hint='e.g. {"t": 0.0, "controls": [...]} or {"t": 0.0, "jaw": [0.1, 0, 0]}')
    t = obj.get("t")
    if t is None:
        if require_t:
            raise InputError("no time 't'", source=source, hint="give each line a time in seconds")
    elif not _number(t):
        raise InputError(f"time 't' is {t!r}, expected a finite number of seconds", source=source)
    if "controls" in obj:
        extra = sorted(set(obj) - {"t", "controls"})
        if extra:
            raise InputError(f"mixes 'controls' with other keys {extra}", source=source,
                             hint="give either the whole vector as 'controls' or group keys")
        values = obj["controls"]
        if not isinstance(values, list):
            raise InputError(f"'controls' is {type(values).__name__}, expected a list of numbers", source=source,
                             hint=hint)
        if len(values) != layout.dim:
            raise InputError(f"'controls' has {len(values)} values, expected {layout.dim}", source=source,
                             hint=f"layout: {layout.describe()}")
        bad = [i for i, v in enumerate(values) if not _number(v)]
        if bad:
            raise InputError(f"'controls'[{bad[0]}] is {values[bad[0]]!r}, expected a finite number", source=source)
        return (None if t is None else float(t)), np.asarray(values, dtype=np.float32)
    groups = [k for k in obj if k != "t"]
    if not groups:
        raise InputError("no controls", source=source, hint="give 'controls' or group keys: " + layout.describe())
    vec = np.zeros(layout.dim, dtype=np.float32)
    for name in groups:
        if name not in layout:
            raise InputError(f"unknown control group {name!r}", source=source, hint=f"layout: {layout.describe()}")
        size = layout.size(name)
        values = obj[name]
        if size == 1 and _number(values):
            values = [values]
        if not isinstance(values, list) or len(values) != size:
            got = f"{len(values)} values" if isinstance(values, list) else type(values).__name__
            raise InputError(f"group {name!r} has {got}, expected {size}", source=source,
                             hint=f"layout: {layout.describe()}")
        bad = [i for i, v in enumerate(values) if not _number(v)]
        if bad:
            raise InputError(f"{name}[{bad[0]}] is {values[bad[0]]!r}, expected a finite number", source=source)
        vec[layout.slice(name)] = values
    return (None if t is None else float(t)), vec


def parse_control_line(line: str, layout: ControlLayout, source: str, *, require_t: bool = True
                       ) -> tuple[float | None, np.ndarray]:
    """One JSON line -> (t or None, (D,) float32); InputError naming ``source``."""
    try:
        obj = json.loads(line)
    except json.JSONDecodeError as exc:
        raise InputError(f"not JSON: {exc.msg} at column {exc.colno}", source=source) from None
    return parse_control_record(obj, layout, source, require_t=require_t)


# ------------------------------------------------------------------ files

class ControlTrack:
    """Timed control vectors from a file: ``t`` (T,) float64 seconds, non-decreasing; ``controls`` (T, D) float32."""

    def __init__(self, t: np.ndarray, controls: np.ndarray, layout: ControlLayout, source: str = "controls"):
        self.t = np.asarray(t, dtype=np.float64)
        self.controls = np.asarray(controls, dtype=np.float32)
        self.layout = layout
        self.source = source

    def __len__(self) -> int:
        return len(self.t)

    def __iter__(self) -> Iterator[tuple[float, np.ndarray]]:
        for t, c in zip(self.t, self.controls):
            yield float(t), c

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def at(self, time_s: float, loop: bool = True) -> tuple[float, np.ndarray]:
        """(t, controls) at ``time_s`` seconds from the track's start, linearly interpolated.

        With ``loop`` the track repeats (time modulo its duration); without, it holds its ends.
        """
        t0 = self.t[0]
        if len(self.t) == 1 or self.duration <= 0:
            return float(t0), self.controls[0].copy()
        local = float(time_s) % self.duration if loop else min(max(float(time_s), 0.0), self.duration)
        t = t0 + local
        j = int(np.searchsorted(self.t, t, side="right"))
        if j <= 0:
            return float(t), self.controls[0].copy()
        if j >= len(self.t):
            return float(t), self.controls[-1].copy()
        ta, tb = self.t[j - 1], self.t[j]
        w = 0.0 if tb == ta else (t - ta) / (tb - ta)
        return float(t), ((1 - w) * self.controls[j - 1] + w * self.controls[j]).astype(np.float32)


def _check_times(t: np.ndarray, where) -> None:
    """InputError at the first non-finite or decreasing time; ``where(i)`` names sample i."""
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"time {t[i]} is not finite", source=where(i))
    dec = np.diff(t) < 0
    if dec.any():
        i = int(np.argmax(dec)) + 1
        raise InputError(f"time {t[i]:g} s comes after {t[i - 1]:g} s", source=where(i),
                         hint="times must not decrease")


def load_controls(path: str | os.PathLike, layout: ControlLayout = DEFAULT_LAYOUT,
                  names: Sequence[str] | None = None) -> ControlTrack:
    """Read and fully validate a control file (.npz, .csv, .jsonl/.ndjson/.json; module docstring).

    ``names`` (the rig's ``control_names``) are accepted as CSV column names besides ``GROUP.I``.
    Every problem is one InputError naming the file and the line or array.
    """
    p = Path(path)
    source = str(p)
    if not p.is_file():
        raise InputError("no such control file" if not p.exists() else "not a file", source=source)
    suffix = p.suffix.lower()
    if suffix == ".npz":
        return _load_npz(p, layout)
    if suffix == ".csv":
        return _load_csv(p, layout, names)
    if suffix in _JSONL_SUFFIXES:
        return _load_jsonl(p, layout)
    raise InputError(f"unknown control file type {suffix or '(none)'!r}", source=source,
                     hint="use .npz, .csv or .jsonl")


def _load_npz(p: Path, layout: ControlLayout) -> ControlTrack:
    source = str(p)
    try:
        with np.load(p, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except ValueError as exc:
        what = "holds a pickled object array" if "pickle" in str(exc).lower() else "is not a readable .npz file"
        raise InputError(what, source=source) from None
    except (OSError, EOFError, zipfile.BadZipFile):
        raise InputError("is not a readable .npz file", source=source) from None
    for name in ("t", "controls"):
        if name not in arrays:
            raise InputError(f"array {name!r} is missing", source=source,
                             hint="a control .npz holds t (T,) and controls (T, D)")
    t, c = arrays["t"], arrays["controls"]
    if t.ndim != 1 or len(t) < 1 or t.dtype.kind not in "fiu":
        raise InputError(f"array 't' has shape {t.shape} dtype {t.dtype}, expected (T,) numbers with T >= 1",
                         source=source)
    if c.ndim != 2 or c.shape != (len(t), layout.dim) or c.dtype.kind not in "fiu":
        raise InputError(f"array 'controls' has shape {c.shape}, expected ({len(t)}, {layout.dim})", source=source,
                         hint=f"layout: {layout.describe()}")
    t = t.astype(np.float64)
    c = c.astype(np.float32)
    _check_times(t, lambda i: f"{source} row {i}")
    bad = ~np.isfinite(c)
    if bad.any():
        i, j = (int(v) for v in np.argwhere(bad)[0])
        raise InputError(f"controls[{j}] is {c[i, j]}, expected a finite number", source=f"{source} row {i}")
    return ControlTrack(t, c, layout, source)


def _column_index(name: str, layout: ControlLayout, names: Sequence[str] | None) -> int | None:
    if names is not None and name in names:
        return list(names).index(name)
    group, dot, index = name.rpartition(".")
    if dot and group in layout and index.isdigit() and int(index) < layout.size(group):
        return layout.slice(group).start + int(index)
    return None


def _load_csv(p: Path, layout: ControlLayout, names: Sequence[str] | None) -> ControlTrack:
    source = str(p)
    try:
        with open(p, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except UnicodeDecodeError:
        raise InputError("is not UTF-8 text", source=source) from None
    if not rows or not rows[0]:
        raise InputError("no header row", source=f"{source}:1", hint="the first row names the columns: t, jaw.0, ...")
    header = [h.strip() for h in rows[0]]
    if header[0] != "t":
        raise InputError(f"first column is {header[0]!r}, expected 't'", source=f"{source}:1")
    columns = []
    for name in header[1:]:
        k = _column_index(name, layout, names)
        if k is None:
            raise InputError(f"unknown control column {name!r}", source=f"{source}:1",
                             hint=f"name columns GROUP.I with groups {layout.describe()}")
        if k in columns:
            raise InputError(f"column {name!r} repeats control {k}", source=f"{source}:1")
        columns.append(k)
    t, c, lines = [], [], []
    for line_no, row in enumerate(rows[1:], start=2):
        if not row or all(not f.strip() for f in row):
            continue
        where = f"{source}:{line_no}"
        if len(row) != len(header):
            raise InputError(f"{len(row)} fields, expected {len(header)} (t and {len(header) - 1} controls)",
                             source=where)
        try:
            values = [float(f) for f in row]
        except ValueError:
            col = next(i for i, f in enumerate(row) if not _is_float(f))
            raise InputError(f"column {header[col]!r} is {row[col]!r}, expected a number", source=where) from None
        if not all(math.isfinite(v) for v in values):
            col = next(i for i, v in enumerate(values) if not math.isfinite(v))
            raise InputError(f"column {header[col]!r} is {row[col].strip()}, expected a finite number", source=where)
        vec = np.zeros(layout.dim, dtype=np.float32)
        vec[columns] = values[1:]
        t.append(values[0])
        c.append(vec)
        lines.append(line_no)
    if not t:
        raise InputError("no rows after the header", source=source)
    t = np.asarray(t, dtype=np.float64)
    _check_times(t, lambda i: f"{source}:{lines[i]}")
    return ControlTrack(t, np.stack(c), layout, source)


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _load_jsonl(p: Path, layout: ControlLayout) -> ControlTrack:
    source = str(p)
    t, c, lines = [], [], []
    try:
        with open(p, encoding="utf-8") as fh:
            for line_no, line in enumerate(fh, start=1):
                if not line.strip():
                    continue
                ti, vec = parse_control_line(line, layout, f"{source}:{line_no}", require_t=True)
                t.append(ti)
                c.append(vec)
                lines.append(line_no)
    except UnicodeDecodeError:
        raise InputError("is not UTF-8 text", source=source) from None
    if not t:
        raise InputError("no control lines", source=source,
                         hint='one JSON object a line: {"t": 0.0, "controls": [...]}')
    t = np.asarray(t, dtype=np.float64)
    _check_times(t, lambda i: f"{source}:{lines[i]}")
    return ControlTrack(t, np.stack(c), layout, source)


# ------------------------------------------------------------------ sources

class FileControls:
    """A :class:`ControlTrack` played back: ``latest(now)`` interpolates at ``now`` seconds (looping)."""

    def __init__(self, track: ControlTrack, loop: bool = True):
        self.track = track
        self.loop = loop
        self.layout = track.layout

    def latest(self, now: float = 0.0) -> tuple[float, np.ndarray]:
        return self.track.at(now, self.loop)

    def close(self) -> None:
        pass


# the demo motion
DEMO_YAW_DEG = 20.0        # head turn amplitude
DEMO_YAW_PERIOD_S = 6.0
DEMO_JAW_RAD = 0.16        # widest jaw opening while talking
DEMO_SYLLABLE_HZ = 4.0
DEMO_PHRASE_S, DEMO_PAUSE_S = 2.4, 0.9
DEMO_BLINK_PERIOD_S = 3.7


def demo_controls(t: float, layout: ControlLayout = DEFAULT_LAYOUT) -> np.ndarray:
    """The built-in demo motion at time ``t`` seconds: (D,) float32, a pure function of ``t``.

    head      yaw DEMO_YAW_DEG sin(2 pi t / 6 s) (+-20 degrees), a 3 degree nod over 9.3 s
    jaw       talking: phrases of 2.4 s with 0.9 s pauses (a smooth envelope), syllables at 4 Hz,
              opening 0 .. DEMO_JAW_RAD (0.16 rad) about +x
    eyelids   a blink (a bump to 1, about 0.1 s wide at half height) every 3.7 s, both eyes
    eyes      gaze counter-rotates half the head yaw
    expression[0] (the demo avatar's smile) 0.15 .. 0.45 over 11 s; expression[2] (brows up) up to
              0.35 with the talking envelope
    translation  a 5 mm sway along x over 5 s
    Groups the layout lacks are skipped; every value is bounded as listed.
    """
    c = np.zeros(layout.dim, dtype=np.float64)
    yaw = math.radians(DEMO_YAW_DEG) * math.sin(2 * math.pi * t / DEMO_YAW_PERIOD_S)
    cycle = DEMO_PHRASE_S + DEMO_PAUSE_S
    tc = t % cycle
    env = _smooth(tc / 0.25) * _smooth((DEMO_PHRASE_S - tc) / 0.25)
    syllable = 0.5 - 0.5 * math.cos(2 * math.pi * DEMO_SYLLABLE_HZ * t)
    tb = t % DEMO_BLINK_PERIOD_S
    blink = math.exp(-(((tb - 0.3) / 0.06) ** 2))
    if "head" in layout and layout.size("head") >= 3:
        s = layout.slice("head").start
        c[s] = math.radians(3.0) * math.sin(2 * math.pi * t / 9.3)
        c[s + 1] = yaw
    if "jaw" in layout:
        c[layout.slice("jaw").start] = DEMO_JAW_RAD * env * syllable * (0.75 + 0.25 * math.sin(2 * math.pi * 1.3 * t))
    if "eyelids" in layout:
        c[layout.slice("eyelids")] = blink
    if "eyes" in layout and layout.size("eyes") >= 6:
        s = layout.slice("eyes").start
        c[s + 1] = c[s + 4] = -0.5 * yaw
    if "expression" in layout:
        s = layout.slice("expression")
        c[s.start] = 0.3 + 0.15 * math.sin(2 * math.pi * t / 11.0)
        if layout.size("expression") >= 3:
            c[s.start + 2] = 0.35 * env * (0.5 + 0.5 * math.sin(2 * math.pi * t / 1.65))
    if "translation" in layout:
        c[layout.slice("translation").start] = 0.005 * math.sin(2 * math.pi * t / 5.0)
    return c.astype(np.float32)


def _smooth(x: float) -> float:
    x = min(max(x, 0.0), 1.0)
    return x * x * (3 - 2 * x)


class DemoControls:
    """The built-in demo motion as a source: ``latest(now)`` = (now, demo_controls(now))."""

    def __init__(self, layout: ControlLayout = DEFAULT_LAYOUT):
        self.layout = layout

    def latest(self, now: float = 0.0) -> tuple[float, np.ndarray]:
        return float(now), demo_controls(now, self.layout)

    def close(self) -> None:
        pass


class StreamControls:
    """JSON control lines arriving on a background thread; ``latest()`` never blocks (module docstring).

    Build one with :func:`open_udp` or :func:`open_text_stream` (stdin); :meth:`feed` takes one
    line directly.  Use as a context manager or call :meth:`close`.
    """

    LOG_FIRST = 5      # bad lines logged one by one, then every LOG_EVERY-th
    LOG_EVERY = 100

    def __init__(self, layout: ControlLayout, name: str):
        self.layout = layout
        self.name = name
        self._lock = threading.Lock()
        self._latest: tuple[float | None, np.ndarray] = (None, np.zeros(layout.dim, dtype=np.float32))
        self._received = 0
        self._bad = 0
        self._last_error: str | None = None
        self._line_no = 0
        self._ended = False
        self._t0 = time.monotonic()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # called by the reader thread (or a test)
    def feed(self, line: str) -> None:
        self._line_no += 1
        text = line.strip()
        if not text:
            return
        try:
            t, vec = parse_control_line(text, self.layout, f"{self.name} line {self._line_no}", require_t=False)
        except InputError as exc:
            self._count_bad(str(exc))
            return
        if t is None:
            t = time.monotonic() - self._t0
        with self._lock:
            self._latest = (t, vec)
            self._received += 1

    def _count_bad(self, message: str) -> None:
        with self._lock:
            self._bad += 1
            self._last_error = message
            bad = self._bad
        if bad <= self.LOG_FIRST or bad % self.LOG_EVERY == 0:
            log.warning("bad control line (%d so far): %s", bad, message)

    def latest(self, now: float | None = None) -> tuple[float | None, np.ndarray]:
        """The most recently received valid (t, controls), or (None, zeros) before the first one."""
        with self._lock:
            t, vec = self._latest
        return t, vec.copy()

    @property
    def stats(self) -> dict[str, Any]:
        """``received`` valid lines, ``bad`` lines, ``last_error`` (one line or None), ``ended`` (EOF)."""
        with self._lock:
            return {"received": self._received, "bad": self._bad, "last_error": self._last_error,
                    "ended": self._ended}

    def _start(self, target) -> None:
        self._thread = threading.Thread(target=target, name=f"controls {self.name}", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=0.5)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class _UdpControls(StreamControls):
    def __init__(self, layout: ControlLayout, host: str, port: int):
        super().__init__(layout, f"udp://{host}:{port}")
        try:
            self._sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
            self._sock.bind((host, port))
        except OSError as exc:
            raise InputError(f"cannot listen: {exc.strerror or exc}", source=self.name,
                             hint="choose a free port and a local address") from None
        self._sock.settimeout(0.1)
        self.address = self._sock.getsockname()[:2]
        self.name = f"udp://{self.address[0]}:{self.address[1]}"
        self._start(self._run)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, _ = self._sock.recvfrom(65536)
            except (socket.timeout, TimeoutError):
                continue
            except OSError:
                break
            try:
                text = data.decode("utf-8")
            except UnicodeDecodeError:
                self._line_no += 1
                self._count_bad(f"{self.name} line {self._line_no}: not UTF-8 text")
                continue
            for line in text.splitlines():
                self.feed(line)
        self._sock.close()

    def close(self) -> None:
        super().close()


class _TextControls(StreamControls):
    def __init__(self, layout: ControlLayout, fileobj, name: str):
        super().__init__(layout, name)
        self._file = fileobj
        self._start(self._run)

    def _run(self) -> None:
        try:
            for line in self._file:
                if self._stop.is_set():
                    break
                if isinstance(line, bytes):
                    try:
                        line = line.decode("utf-8")
                    except UnicodeDecodeError:
                        self._line_no += 1
                        self._count_bad(f"{self.name} line {self._line_no}: not UTF-8 text")
                        continue
                self.feed(line)
        except (OSError, ValueError) as exc:  # closed or broken pipe
            self._count_bad(f"{self.name}: read failed: {exc}")
        with self._lock:
            self._ended = True


def open_udp(address: str, layout: ControlLayout = DEFAULT_LAYOUT) -> StreamControls:
    """Listen for JSON control lines on ``udp://HOST:PORT`` (or ``HOST:PORT``); InputError for a bad address."""
    spec = address[len("udp://"):] if address.startswith("udp://") else address
    host, sep, port = spec.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or int(port) > 65535:
        raise InputError(f"bad UDP address {address!r}", source="controls",
                         hint="use udp://HOST:PORT, e.g. udp://0.0.0.0:9000")
    return _UdpControls(layout, host, int(port))


def open_text_stream(fileobj=None, layout: ControlLayout = DEFAULT_LAYOUT, name: str = "stdin") -> StreamControls:
    """Read JSON control lines from ``fileobj`` (default standard input) on a background thread."""
    return _TextControls(layout, sys.stdin if fileobj is None else fileobj, name)


def open_controls(spec: str, layout: ControlLayout = DEFAULT_LAYOUT, names: Sequence[str] | None = None):
    """A control source for ``spec``: "demo", "-"/"stdin", "udp://HOST:PORT", or a file path (module docstring)."""
    if spec == "demo":
        return DemoControls(layout)
    if spec in ("-", "stdin"):
        return open_text_stream(None, layout)
    if spec.startswith("udp://"):
        return open_udp(spec, layout)
    return FileControls(load_controls(spec, layout, names))
