"""Quilt playback on the panel: quilt images, quilt videos and folders of them, paced, with keys.

    report = play_quilts(presenter, items, profile)   # an opened presenter; items from quilt_sources

Each frame goes the OpenGL way: decoded on the host (a reader thread,
:class:`~.quilt_sources.FrameReader`, one frame ahead), its views uploaded into the
:class:`~.encoders.gl_encoder.GLEncoder` living in the presenter's own context, the raster drawn
straight into the presenter's framebuffer (:meth:`~.present.Presenter.show_drawn`).  Where that
cannot run (no OpenGL context: the ``none`` display; a driver refusing the textures; 16-bit
quilts), and with ``encoder="auto"`` where OpenGL renders in software (llvmpipe: the CPU encoder
is 2-4x faster there, ``tools/bench_show_quilt.py``), a CPU encoder (``fast``) makes the raster
and :meth:`~.present.Presenter.show` sends it, said once in :attr:`PlaybackReport.notes`.

Pacing: frame ``k`` after the first one shown after a start (or a seek, a pause, a loop) is due
``k / fps`` seconds after that one was (``fps``: the video's, or given), and shown then (the
buffer swap then waits for the display's refresh when vsync is on).  A frame still not shown when
the next one is due, with a later one decoded already, is dropped and counted
(:attr:`PlaybackReport.dropped`); none is dropped silently, and a late frame with none decoded
after it yet is shown late (decoding is then the limit).  ``fps`` None:
every frame as fast as possible (benchmarks), none dropped.

Keys (:data:`PAUSE_KEYS` ...): space pauses and resumes; right / left step to the next / previous
item, or seek +-5 s in a video; down, page down, enter and up, page up, backspace step items in a
video too; q or escape quit.  Images advance after ``interval`` seconds (None: on a key); the
next image of a show is read on a thread while the current item plays.
"""

from __future__ import annotations

import collections
import dataclasses
import queue
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numpy as np

from ...core.errors import DisplayError
from ...core.profile import PanelProfile
from ...core.slides import QUIT_KEYS
from ..present.base import MAX_TIMINGS
from .quilt_sources import FrameReader, QuiltItem, QuiltMapping, read_quilt_image

PAUSE_KEYS = {"space"}
SEEK_KEYS = {"right": 1, "left": -1}  # in a video: seek by SEEK_SECONDS; on an image: next / previous
ITEM_KEYS = {"down": 1, "page_down": 1, "enter": 1, "up": -1, "page_up": -1, "backspace": -1}
SEEK_SECONDS = 5.0
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "software")  # GL_RENDERER names of CPU rendering
DEFAULT_FPS = 30.0  # a video whose file states no frame rate


@dataclasses.dataclass
class PlaybackReport:
    """What :func:`play_quilts` did: ``items`` shown, frames ``presented``, ``dropped`` (due but not
    shown in time), ``decoded`` (video frames), ``seconds`` of playback, the ``encoder`` ("gl" or
    the CPU one), ``present_ms`` (encode + present, one per frame: the latest
    :data:`~.present.MAX_TIMINGS`) and ``notes``."""

    items: int = 0
    presented: int = 0
    dropped: int = 0
    decoded: int = 0
    seconds: float = 0.0
    encoder: str = "gl"
    present_ms: collections.deque = dataclasses.field(default_factory=lambda: collections.deque(maxlen=MAX_TIMINGS))
    notes: list = dataclasses.field(default_factory=list)

    @property
    def fps(self) -> float:
        """Frames presented per second of playback."""
        return self.presented / self.seconds if self.seconds > 0 else 0.0

    def summary(self) -> dict:
        """The JSON summary ``lenticalib show --profile ... --json`` prints."""
        median = float(np.median(list(self.present_ms))) if self.present_ms else None
        return {"items": self.items, "presented": self.presented, "dropped": self.dropped, "decoded": self.decoded,
                "seconds": round(self.seconds, 3), "fps": round(self.fps, 2), "encoder": self.encoder,
                "median_frame_ms": None if median is None else round(median, 2), "notes": list(self.notes)}


class _Drawer:
    """Views -> the panel: a GLEncoder in the presenter's context per view size, or ``cpu``."""

    def __init__(self, presenter, profile: PanelProfile, encoder: str, report: PlaybackReport):
        self.presenter, self.profile, self.report = presenter, profile, report
        self.cpu = encoder if encoder not in ("gl", "auto") else "fast"
        self.use_gl = encoder in ("gl", "auto")
        self.report.encoder = "gl" if self.use_gl else encoder
        if self.use_gl and getattr(presenter, "ctx", None) is None:
            self._fall_back(f"the {presenter.kind} display has no OpenGL context")
        elif self.use_gl and any(name in str(presenter.ctx.info.get("GL_RENDERER", "")).lower()
                                 for name in SOFTWARE_RENDERERS):
            if encoder == "auto":
                self._fall_back("OpenGL renders on the CPU here (a software renderer), where the fast encoder is "
                                "2-4x faster (`encoder` gl to use OpenGL anyway)")
            else:
                self.report.notes.append("OpenGL renders on the CPU here (a software renderer): the fast encoder "
                                         "plays faster on this machine (`encoder` fast)")
        self._encoders: dict = {}

    def _fall_back(self, why: str) -> None:
        self.use_gl = False
        self.report.encoder = self.cpu
        self.report.notes.append(f"encoding on the CPU ({self.cpu} encoder): {why}")

    def show(self, views: np.ndarray, source: str) -> None:
        if self.use_gl and views.dtype != np.uint8:
            self._fall_back(f"{source} has {views.dtype} views; the gl encoder takes 8-bit ones")
        if self.use_gl:
            from ..encoders.gl_encoder import GLEncoder

            size = views.shape[1:3]
            encoder = self._encoders.get(size)
            if encoder is None:
                while len(self._encoders) >= 2:  # quilts of many tile sizes: the panel tables are 4 bytes a subpixel
                    self._encoders.pop(next(iter(self._encoders))).release()
                try:
                    encoder = self._encoders[size] = GLEncoder(self.profile, size, ctx=self.presenter.ctx)
                except DisplayError as exc:
                    self._fall_back(str(exc))
            if encoder is not None:
                encoder.upload_views(views)
                self.presenter.show_drawn(encoder.draw)
                return
        from ..encoders import encode

        self.presenter.show(encode(views, self.profile, self.cpu, allow_stretch=True), source=source)

    def release(self) -> None:
        for encoder in self._encoders.values():
            encoder.release()
        self._encoders.clear()


def play_quilts(presenter, items: list[QuiltItem], profile: PanelProfile, *, encoder: str = "gl",
                allow_stretch: bool = False, fps: float | None | str = "video", interval: float | None = None,
                loop: bool = False, on_present: Callable[[int, int], None] | None = None,
                clock=time.monotonic) -> PlaybackReport:
    """Play ``items`` on the opened ``presenter`` (whose size is the panel's) for ``profile``.

    ``encoder``: "gl" (the GPU way, CPU fallback), "auto" (as "gl", but the CPU's ``fast`` where
    OpenGL renders in software: Mesa's llvmpipe) or a CPU encoder's name; ``fps``: "video" (each
    video's own rate), a number, or None (unpaced); ``interval``: seconds an image stays (None:
    until a key); ``loop``: start again after the last item (a single video loops); ``on_present(item,
    frame)`` after each frame shown (frame 0 for an image).  Returns :class:`PlaybackReport`.
    """
    report = PlaybackReport()
    drawer = _Drawer(presenter, profile, encoder, report)
    images = _ImagesAhead(items, profile, allow_stretch, loop)
    start = clock()
    index = 0
    try:
        while 0 <= index < len(items):
            item = items[index]
            mapping = QuiltMapping(profile, item.grid, allow_stretch)
            report.items += 1
            if item.video:
                images.read_ahead(index)
                step = _play_video(presenter, drawer, item, mapping, index, report, fps, on_present, clock)
            else:
                views = images.views(index)
                images.read_ahead(index)
                step = _play_image(presenter, drawer, item, views, index, report, interval, on_present, clock)
            if step == 0:
                break
            index += step
            if loop:
                index %= len(items)
            elif index < 0:
                index = 0
    finally:
        images.close()
        drawer.release()
        report.seconds = clock() - start
    return report


class _ImagesAhead:
    """The next quilt image of the show read (and split into views) on a thread while this item
    plays: at most one ahead."""

    def __init__(self, items: list[QuiltItem], profile: PanelProfile, allow_stretch: bool, loop: bool):
        self.items, self.profile, self.allow_stretch, self.loop = items, profile, allow_stretch, loop
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="quilt-image")
        self.ahead: dict = {}  # item index -> Future of its views

    def _read(self, index: int) -> np.ndarray:
        item = self.items[index]
        return read_quilt_image(item, QuiltMapping(self.profile, item.grid, self.allow_stretch))

    def views(self, index: int) -> np.ndarray:
        future = self.ahead.pop(index, None)
        return self._read(index) if future is None else future.result()

    def read_ahead(self, index: int) -> None:
        following = (index + 1) % len(self.items) if self.loop else index + 1
        if following >= len(self.items) or following == index or self.items[following].video \
                or following in self.ahead:
            return
        for future in self.ahead.values():
            future.cancel()
        self.ahead = {following: self.pool.submit(self._read, following)}

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)
        self.ahead.clear()


def _present(drawer: _Drawer, views, source, report, on_present, item_index, frame_index, clock) -> None:
    begun = clock()
    drawer.show(views, source)
    report.present_ms.append(1e3 * (clock() - begun))
    report.presented += 1
    if on_present is not None:
        on_present(item_index, frame_index)


def _play_image(presenter, drawer, item, views, item_index, report, interval, on_present, clock) -> int:
    """Show one quilt image's ``views``; +1 / -1 (next / previous) or 0 (quit)."""
    _present(drawer, views, item.source, report, on_present, item_index, 0, clock)
    deadline = None if interval is None else clock() + interval
    paused_left = None
    while True:
        wait = 0.25 if deadline is None else max(0.0, min(0.25, deadline - clock()))
        for key in presenter.keys(timeout=wait):
            if key in QUIT_KEYS:
                return 0
            if key in SEEK_KEYS or key in ITEM_KEYS:
                return SEEK_KEYS.get(key) or ITEM_KEYS[key]
            if key in PAUSE_KEYS and interval is not None:  # the interval stops, and goes on
                if paused_left is None:
                    paused_left, deadline = deadline - clock(), None
                else:
                    deadline, paused_left = clock() + paused_left, None
        if deadline is not None and clock() >= deadline:
            return 1


def _play_video(presenter, drawer, item, mapping, item_index, report, fps, on_present, clock) -> int:
    """Play one quilt video to its end (0 quit, +1 / -1 an item key, +1 at the end)."""
    with FrameReader(item, mapping) as reader:
        rate = (reader.fps or DEFAULT_FPS) if fps == "video" else fps
        if fps == "video" and reader.fps is None:
            report.notes.append(f"{item.path.name} states no frame rate: played at {DEFAULT_FPS:g} fps")
        refresh = getattr(getattr(presenter, "monitor", None), "refresh_hz", None)
        if rate and refresh and presenter.vsync and rate > refresh * 1.01:
            report.notes.append(f"{item.path.name} runs at {rate:g} fps, the display refreshes at {refresh:g} Hz: "
                                f"some {100 * (1 - refresh / rate):.0f} % of its frames will be dropped (counted)")
        generation, origin, last = 0, None, 0  # origin: (clock, frame index) the pacing counts from
        paused, held, pending = False, None, []
        try:
            while True:
                reader.check()
                keys, pending = pending + presenter.keys(timeout=0.0), []
                for key in keys:
                    if key in QUIT_KEYS:
                        return 0
                    if key in ITEM_KEYS:
                        return ITEM_KEYS[key]
                    if key in PAUSE_KEYS:
                        paused, origin = not paused, None  # pacing starts again from the next frame shown
                    elif key in SEEK_KEYS:
                        step = SEEK_KEYS[key] * SEEK_SECONDS * (reader.fps or rate or DEFAULT_FPS)
                        generation, origin, held = reader.seek(round(last + step)), None, None
                if paused:
                    pending = presenter.keys(timeout=0.05)
                    continue
                if held is None:
                    try:
                        held = reader.frames.get(timeout=0.05)
                    except queue.Empty:
                        continue
                    if held.generation != generation:
                        held = None
                        continue
                    if held.views is None:  # the end of the video
                        reader.check()
                        return 1
                if rate is not None and origin is not None:
                    now = clock()
                    due = origin[0] + (held.index - origin[1]) / rate
                    if now >= due + 1.0 / rate and reader.ready():  # a later frame is due and decoded
                        report.dropped += 1
                        last, held = held.index, None
                        continue
                    if now < due:
                        pending = presenter.keys(timeout=due - now)  # keys first, then this frame
                        continue
                frame, held = held, None
                last = frame.index
                _present(drawer, frame.views, item.source, report, on_present, item_index, frame.index, clock)
                if origin is None:  # pacing counts from the first frame on the panel (a first encode compiles)
                    origin = (clock(), frame.index)
        finally:
            report.decoded += reader.decoded
