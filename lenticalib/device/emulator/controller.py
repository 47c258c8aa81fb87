"""One emulated panel controller: firmware, flash image and fault injection behind a byte link.

:class:`EmulatedController` is what every emulated transport sits on: the pseudo-terminal and
TCP servers (:mod:`.serve`), the pyserial ``emu://`` handler, the hidapi-style device and the
pyusb backend.  The host side writes request bytes with :meth:`host_write` and reads reply
bytes with :meth:`host_read`; faults (:mod:`.faults`) act per frame on the way in and out.

After a power cut or an injected disconnect the controller is *dead*: every further call
raises :class:`LinkDown` and the flash image keeps exactly what reached it.  Restarting
means constructing a new controller on the same image.
"""

from __future__ import annotations

import bisect
import os
import threading
import time
from pathlib import Path

from ...core.errors import InputError
from ..framing import FrameParser, encode_frame
from ..protocol import MAX_CHUNK, PROTOCOL_MINOR, PanelGeometry
from .faults import FaultPlan
from .firmware import Firmware
from .flash import FlashImage, PowerCut, create_image

DEFAULT_MODEL = "LC-32 (emulated)"
TRANSMIT_BUFFER = 16384  # bytes of replies the controller holds for a host that does not read
FRAME_GAP_S = 0.05  # a partial frame older than this when new bytes arrive is discarded (protocol 2.)
DEFAULT_FIRMWARE = "1.0.0-emu"


class LinkDown(Exception):
    """The emulated link is gone (``reason``: "power cut" or "disconnected")."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


def default_image_dir() -> Path:
    """Where ``emu://NAME`` keeps NAME.flash: $LENTICALIB_EMULATOR_DIR or ~/.local/state/lenticalib/emulators."""
    env = os.environ.get("LENTICALIB_EMULATOR_DIR")
    if env:
        return Path(env)
    state = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(state) / "lenticalib" / "emulators"


def ensure_image(path: str | os.PathLike, *, serial: str | None = None, model: str = DEFAULT_MODEL,
                 firmware_version: str = DEFAULT_FIRMWARE) -> Path:
    """Create the flash image at ``path`` if it does not exist (serial from its name by default)."""
    path = Path(path)
    if not path.exists():
        name = "".join(c for c in path.stem.upper() if c.isascii() and c.isalnum())[:12] or "EMU"
        create_image(path, model=model, serial=serial or f"EMU-{name}", firmware_version=firmware_version)
    return path


def default_panel() -> PanelGeometry:
    """The panel of the default controller family's ``[panel]`` table (``drivers/lc32.toml``)."""
    from ..controller_families import family_for

    family = family_for()
    if family.panel is None:
        raise InputError("the controller description has no [panel] table", source=family.source,
                         hint="add one as in drivers/lc32.toml, or give the emulator `panel`")
    return family.panel


class EmulatedController:
    """Firmware + flash + faults, thread-safe, reached through host_write / host_read.

    ``panel`` is the panel the controller drives (default: the family's, :func:`default_panel`);
    ``protocol_minor`` 0 emulates protocol 1.0 firmware (see :class:`.firmware.Firmware`);
    ``max_chunk`` the bytes one WRITE_CHUNK may carry (default the protocol's 32; 1 makes a flash
    take 128 chunks, the most requests a controller can ask for).
    """

    def __init__(self, image: str | os.PathLike, faults: FaultPlan | None = None, *,
                 panel: PanelGeometry | None = None, protocol_minor: int = PROTOCOL_MINOR,
                 max_chunk: int | None = None):
        self.faults = faults or FaultPlan()
        panel = panel or default_panel()
        self.flash = FlashImage(image, power_cut_after=self.faults.power_cut_after, torn=self.faults.torn)
        self.firmware = Firmware(self.flash, panel, protocol_minor=protocol_minor,
                                 **({} if max_chunk is None else {"max_chunk": max_chunk}))
        self._inbound = FrameParser()
        self._outbox: list[tuple[float, bytes]] = []  # (ready time, bytes), sorted by time
        self._queued = 0  # bytes in _outbox
        self._last_rx = 0.0
        self._previous_reply: bytes | None = None
        self._earlier: dict[int, bytes] = {}  # reply CMD -> the last reply with that CMD
        self._requests = 0
        self._lock = threading.Condition()
        self.down: str | None = None

    @property
    def identity(self):
        return self.firmware.identity

    def close(self) -> None:
        with self._lock:
            self.flash.close()
            if self.down is None:
                self.down = "disconnected"
            self._lock.notify_all()

    def _die(self, reason: str) -> None:
        self.down = reason
        self.flash.close()
        self._outbox.clear()
        self._queued = 0
        self._lock.notify_all()

    def host_write(self, data: bytes) -> None:
        """Bytes from the host.  Raises LinkDown when the controller is gone."""
        with self._lock:
            if self.down:
                raise LinkDown(self.down)
            faults, now = self.faults, time.monotonic()
            if now - self._last_rx > FRAME_GAP_S:
                self._inbound.reset()  # the line was idle: a partial frame will never complete
            self._last_rx = now
            for frame in self._inbound.feed(data):
                if frame.is_reply:
                    continue
                self._requests += 1
                if faults.hit(faults.drop_rate):
                    continue
                try:
                    if faults.hit(faults.corrupt_rate):  # the firmware's own parser meets the bad bytes
                        replies = self.firmware.receive(faults.corrupt(encode_frame(frame.cmd, frame.seq,
                                                                                      frame.payload)))
                    else:
                        replies = [self.firmware.handle(frame)]
                except PowerCut:
                    self._die("power cut")
                    raise LinkDown("power cut") from None
                for reply in replies:
                    self._send(reply)
                if faults.disconnect_after is not None and self._requests >= faults.disconnect_after:
                    self._die("disconnected")
                    raise LinkDown("disconnected")
            self._lock.notify_all()

    def reset_link(self) -> None:
        """A new connection: drop replies not yet read and any partial request frame."""
        with self._lock:
            self._outbox.clear()
            self._queued = 0
            self._inbound.reset()

    def _send(self, reply: bytes) -> None:
        faults, now = self.faults, time.monotonic()
        if self._queued + len(reply) > TRANSMIT_BUFFER:
            return  # transmit buffer full: the host is not reading, the reply is lost
        command = reply[3]  # the frame's CMD byte (framing.HEADER)
        stale = self._earlier.get(command, self._previous_reply)
        if faults.hit(faults.stale_rate) and stale is not None:
            self._queue(now, stale)  # same CMD and an older SEQ when it can: only the SEQ tells them apart
        self._previous_reply = self._earlier[command] = reply
        if faults.hit(faults.drop_rate):
            return
        ready = now + (faults.delay_s if faults.hit(faults.delay_rate) else 0.0)
        self._queue(ready, faults.corrupt(reply) if faults.hit(faults.corrupt_rate) else reply)
        if faults.hit(faults.duplicate_rate):
            self._queue(ready, reply)

    def _queue(self, ready: float, data: bytes) -> None:
        bisect.insort(self._outbox, (ready, data), key=lambda item: item[0])  # stable: FIFO per time
        self._queued += len(data)

    def next_ready(self) -> float | None:
        """Monotonic time at which the next reply byte becomes readable (None: nothing queued)."""
        with self._lock:
            return self._outbox[0][0] if self._outbox else None

    def host_read(self, max_bytes: int, timeout: float) -> bytes:
        """Up to ``max_bytes`` reply bytes, waiting at most ``timeout`` s; b"" when none came."""
        deadline = time.monotonic() + max(0.0, timeout)
        with self._lock:
            while True:
                if self.down:
                    raise LinkDown(self.down)
                now = time.monotonic()
                out = bytearray()
                while self._outbox and self._outbox[0][0] <= now and len(out) < max_bytes:
                    ready, data = self._outbox.pop(0)
                    take = data[:max_bytes - len(out)]
                    out += take
                    self._queued -= len(take)
                    if len(take) < len(data):
                        self._outbox.insert(0, (ready, data[len(take):]))
                if not out and self.faults.babble and max_bytes > 0:
                    out += self.faults.noise(min(max_bytes, 64))
                if out:
                    return bytes(out)
                if now >= deadline:
                    return b""
                wake = deadline if not self._outbox else min(deadline, self._outbox[0][0])
                self._lock.wait(max(0.0, wake - now))


_URL_FAULTS = {"drop": "drop_rate", "corrupt": "corrupt_rate", "duplicate": "duplicate_rate",
               "delay": "delay_rate", "delay-s": "delay_s", "stale": "stale_rate",
               "disconnect-after": "disconnect_after", "power-cut-after": "power_cut_after",
               "torn": "torn", "babble": "babble", "seed": "seed"}
_URL_SETUP = ("panel", "order", "views", "protocol", "chunk")
URL_OPTIONS = ("via", *_URL_SETUP, *_URL_FAULTS)


def controller_for_url(url) -> EmulatedController:
    """The in-process controller an ``emu://NAME[?options]`` URL names (a DeviceURL).

    The flash image is NAME.flash in :func:`default_image_dir` (created blank on first use);
    ``panel=WxH``, ``order=RGB|BGR``, ``views=N[,N...]`` set the panel it drives (default: the
    family's), ``protocol=1.0|1.1`` the firmware generation and ``chunk=N`` (1..32) the largest
    WRITE_CHUNK it takes; fault options (``drop=0.1``,
    ``power-cut-after=3``, ``torn=1``, ``babble=1``, ``seed=7``, ...) map onto :class:`FaultPlan` fields.
    Raises InputError naming the URL and the bad parameter.
    """
    from . import config

    def bad(key: str, message: str):
        return InputError(f"URL parameter '{key}' {message}", source=str(url),
                          hint=f"emu:// parameters: {', '.join(URL_OPTIONS)}")

    values, setup = {}, {}
    for key, text in url.options:
        if key not in URL_OPTIONS:
            raise InputError(f"unknown URL parameter '{key}'", source=str(url),
                             hint=f"emu:// parameters: {', '.join(URL_OPTIONS)}")
        if key == "via":
            continue
        if key in _URL_SETUP:
            setup[key] = text
            continue
        field = _URL_FAULTS[key]
        try:
            if field in ("torn", "babble"):
                values[field] = text.lower() in ("1", "true", "yes")
            elif field in ("disconnect_after", "power_cut_after", "seed"):
                values[field] = int(text)
            else:
                values[field] = float(text)
        except ValueError:
            raise bad(key, f"must be a number, got '{text}'") from None
    try:
        faults = FaultPlan(**values)
    except InputError as exc:  # FaultPlan names its field (drop_rate); here it is a URL parameter
        raise bad(next((k for k, f in _URL_FAULTS.items() if f == exc.source), exc.source), exc.message) from None
    try:
        minor = config.parse_protocol(setup.get("protocol", config.CURRENT_PROTOCOL))
    except ValueError as exc:
        raise bad("protocol", str(exc)) from None
    panel = default_panel()
    for key, argument in (("panel", "size"), ("order", "order"), ("views", "views")):
        if key in setup:
            try:
                panel = config.panel_geometry(panel, **{argument: setup[key]})
            except ValueError as exc:
                raise bad(key, str(exc)) from None
    chunk = None
    if "chunk" in setup:
        chunk = int(setup["chunk"]) if setup["chunk"].isdigit() else 0
        if not 1 <= chunk <= MAX_CHUNK:
            raise bad("chunk", f"must be 1..{MAX_CHUNK} bytes, got '{setup['chunk']}'")
    folder = default_image_dir()
    folder.mkdir(parents=True, exist_ok=True)  # the emulators' own state folder, not a user's output path
    image = ensure_image(folder / f"{url.target}.flash")
    return EmulatedController(image, faults, panel=panel, protocol_minor=minor, max_chunk=chunk)
