"""Live and built-in control sources: the demo motion and JSON control lines from stdin or UDP.

Every source answers ``latest(now)`` with ``(t, controls)`` like the file sources of
:mod:`.files` (:func:`~.sources.open_controls` picks one for a spec):

    :class:`DemoControls`    the built-in motion (:func:`demo_controls`): a slow head turn, talking, blinks
    :class:`StreamControls`  JSON lines (:mod:`.records`) on standard input (:func:`open_text_stream`)
                             or in UDP datagrams, several lines per datagram allowed (:func:`open_udp`;
                             port 0 picks a free port, ``.address``), read by a background thread

Streams take the JSON objects of control files, one a line; ``t`` is optional there (the arrival time since the
stream opened is used) and informative only: ``latest()`` returns the most recently *received*
valid line.  Bad lines (not JSON or not UTF-8, nested too deep, an unknown group, a wrong length,
values that are not finite in float32, lines over :data:`MAX_LINE_BYTES`, read in bounded chunks
and the rest discarded) are counted, the first ones logged, and the last error kept
(:attr:`StreamControls.stats`); they never stop the stream or the loop.  Should the reader thread
die of an unexpected error anyway, ``stats["failed"]`` says so and the next ``latest()`` logs a
warning.  Before the first valid line ``latest()`` returns ``(None, zeros)``, the neutral pose.

EXPOSURE.  UDP has no sender check: whoever can reach the port drives the avatar.  A stream bound
to a loopback address (``udp://127.0.0.1:PORT``) takes only this machine's senders; one bound to
every interface (``0.0.0.0``, ``::``) or to a network address takes any sender on that network,
and says so in a warning (:meth:`StreamControls.take_warnings`, which ``play`` prints as
``lenticalib: warning: ...``), naming the address.
"""

from __future__ import annotations

import logging
import math
import socket
import sys
import threading
import time
from typing import Any

import numpy as np

from ...core.errors import InputError
from .records import parse_control_line
from ..avatar.rig import DEFAULT_LAYOUT, ControlLayout

log = logging.getLogger(__name__)


# ------------------------------------------------------------------ the demo motion

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

    def summary(self) -> None:
        """Nothing to report at the end of a session (streams report their line counts)."""
        return None


# ------------------------------------------------------------------ live streams

MAX_LINE_BYTES = 64 * 1024  # a longer line is read in bounded chunks, discarded and counted bad


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
        self._failed: str | None = None
        self._failure_told = False
        self._t0 = time.monotonic()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._warnings: list[str] = []

    def take_warnings(self) -> list[str]:
        """The warnings not yet taken (the exposure of a UDP port, :func:`exposure_warning`), once each."""
        with self._lock:
            out, self._warnings = self._warnings, []
        return out

    # called by the reader thread (or a test)
    def feed(self, line: str | bytes) -> None:
        """One line without its newline (text, or bytes decoded as UTF-8): the latest pose, or counted bad."""
        self._line_no += 1
        where = f"{self.name} line {self._line_no}"
        if len(line) > MAX_LINE_BYTES:
            self._count_bad(f"{where}: {len(line)} bytes, longer than the limit of {MAX_LINE_BYTES}")
            return
        if isinstance(line, bytes):
            try:
                line = line.decode("utf-8")
            except UnicodeDecodeError:
                self._count_bad(f"{where}: not UTF-8 text")
                return
        text = line.strip()
        if not text:
            return
        try:
            t, vec = parse_control_line(text, self.layout, where, require_t=False)
        except InputError as exc:
            self._count_bad(str(exc))
            return
        except Exception as exc:  # noqa: BLE001  (a line must never stop the stream)
            self._count_bad(f"{where}: cannot be read ({type(exc).__name__})")
            return
        if t is None:
            t = time.monotonic() - self._t0
        with self._lock:
            self._latest = (t, vec)
            self._received += 1

    def _skip_overlong(self, size: int) -> None:
        """Count a line of ``size`` (> MAX_LINE_BYTES) bytes that the reader discarded."""
        self._line_no += 1
        self._count_bad(f"{self.name} line {self._line_no}: {size} bytes, longer than the limit of {MAX_LINE_BYTES}")

    def _count_bad(self, message: str) -> None:
        with self._lock:
            self._bad += 1
            self._last_error = message
            bad = self._bad
        if bad <= self.LOG_FIRST or bad % self.LOG_EVERY == 0:
            log.warning("bad control line (%d so far): %s", bad, message)

    def latest(self, now: float | None = None) -> tuple[float | None, np.ndarray]:
        """The most recently received valid (t, controls), or (None, zeros) before the first one.

        The first call after the reader thread died of an unexpected error logs a warning (the
        pose then stays where it is); :attr:`stats` keeps the reason as ``failed``.
        """
        with self._lock:
            t, vec = self._latest
            tell = self._failed is not None and not self._failure_told
            self._failure_told = self._failure_told or tell
        if tell:
            log.warning("%s; the pose stays at the last valid line", self._failed)
        return t, vec.copy()

    @property
    def stats(self) -> dict[str, Any]:
        """``received`` valid lines, ``bad`` lines, ``last_error`` (one line or None), ``ended`` (EOF),
        ``failed`` (None, or one line: the reader thread stopped on an unexpected error)."""
        with self._lock:
            return {"received": self._received, "bad": self._bad, "last_error": self._last_error,
                    "ended": self._ended, "failed": self._failed}

    def summary(self) -> str:
        """One line for the end of a session: lines received, bad (the last error), whether the reader failed."""
        s = self.stats
        text = f"controls {self.name}: {s['received']} valid line{'' if s['received'] == 1 else 's'}, {s['bad']} bad"
        if s["last_error"]:
            text += f" (last: {s['last_error']})"
        if s["failed"]:
            text += f"; {s['failed']}"
        return text

    def _start(self, target) -> None:
        def guarded() -> None:
            try:
                target()
            except BaseException as exc:  # noqa: BLE001  (never stop silently: stats and latest() tell)
                reason = (str(exc).splitlines() or [""])[0][:200]
                with self._lock:
                    self._failed = f"{self.name}: the reader stopped on {type(exc).__name__}: {reason}"

        self._thread = threading.Thread(target=guarded, name=f"controls {self.name}", daemon=True)
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
                             hint="choose a free port and a local address, e.g. udp://127.0.0.1:9000") from None
        self._sock.settimeout(0.1)
        self.address = self._sock.getsockname()[:2]
        self.name = f"udp://{self.address[0]}:{self.address[1]}"
        warning = exposure_warning(self.address[0], self.address[1])
        if warning:
            self._warnings.append(warning)
        self._start(self._run)

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                try:
                    data, _ = self._sock.recvfrom(65536)
                except (socket.timeout, TimeoutError):
                    continue
                except OSError:
                    break
                for line in data.splitlines():
                    self.feed(line)
        finally:
            self._sock.close()


class _TextControls(StreamControls):
    def __init__(self, layout: ControlLayout, fileobj, name: str):
        super().__init__(layout, name)
        self._file = fileobj
        self._start(self._run)

    def _run(self) -> None:
        limit = MAX_LINE_BYTES
        try:
            while not self._stop.is_set():
                line = self._file.readline(limit + 1)  # bounded: never more than limit + 1 at once
                if not line:
                    break
                newline = "\n" if isinstance(line, str) else b"\n"
                if line.endswith(newline):
                    self.feed(line[:-1])
                    continue
                if len(line) <= limit:  # the last line, without a newline
                    self.feed(line)
                    continue
                size = len(line)
                while line and not line.endswith(newline):  # discard the rest of an overlong line
                    line = self._file.readline(limit + 1)
                    size += len(line)
                self._skip_overlong(size - (1 if line else 0))
        except (OSError, ValueError) as exc:  # closed or broken pipe
            self._count_bad(f"{self.name}: read failed: {exc}")
        with self._lock:
            self._ended = True


def exposure_warning(host: str, port: int) -> str | None:
    """The warning for a UDP control port bound to ``host`` (numeric, as bound), or None for a
    loopback address, which only this machine can reach (module docstring)."""
    import ipaddress

    try:
        ip = ipaddress.ip_address(host.split("%")[0])
    except ValueError:
        ip = None
    if ip is not None and (ip.is_loopback or getattr(ip, "ipv4_mapped", None) and ip.ipv4_mapped.is_loopback):
        return None
    where = (f"every network interface ({host})" if ip is not None and ip.is_unspecified
             else f"the network address {host}")
    return (f"udp://{host}:{port} listens on {where}: any sender on the network can drive the avatar, "
            f"unchecked (listen on udp://127.0.0.1:{port} to take this machine's senders only)")


def open_udp(address: str, layout: ControlLayout = DEFAULT_LAYOUT) -> StreamControls:
    """Listen for JSON control lines on ``udp://HOST:PORT`` (or ``HOST:PORT``); InputError for a bad address."""
    spec = address[len("udp://"):] if address.startswith("udp://") else address
    host, sep, port = spec.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or int(port) > 65535:
        raise InputError(f"bad UDP address {address!r}", source="controls",
                         hint="use udp://HOST:PORT, e.g. udp://127.0.0.1:9000 (this machine only)")
    return _UdpControls(layout, host, int(port))


def open_text_stream(fileobj=None, layout: ControlLayout = DEFAULT_LAYOUT, name: str = "stdin") -> StreamControls:
    """Read JSON control lines from ``fileobj`` on a background thread: a binary or text file object
    with ``readline(size)`` (default standard input, read as bytes and decoded line by line)."""
    if fileobj is None:
        fileobj = getattr(sys.stdin, "buffer", sys.stdin)
    return _TextControls(layout, fileobj, name)


# ------------------------------------------------------------------ openers by scheme (controls.sources)

def open_demo_source(spec: str, layout: ControlLayout, names=None) -> DemoControls:
    """The ``demo`` control source: the built-in motion for ``layout``."""
    return DemoControls(layout)


def open_stdin_source(spec: str, layout: ControlLayout, names=None) -> StreamControls:
    """The ``stdin`` control source: JSON control lines on standard input."""
    return open_text_stream(None, layout)


def open_udp_source(spec: str, layout: ControlLayout, names=None) -> StreamControls:
    """The ``udp`` control source: JSON control lines in datagrams to ``udp://HOST:PORT``."""
    return open_udp(spec, layout)
