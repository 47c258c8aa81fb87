"""What ``lenticalib show --profile`` plays: quilt images and quilt videos, their grids, and a
bounded reader that decodes the next video frame while one is shown.

A *quilt item* is one file: a quilt image or a quilt video, with its :class:`~.views.QuiltGrid`
(from the file name's ``_qsCOLSxROWSaASPECT`` suffix, :func:`~.views.parse_quilt_name`, or given).
:class:`QuiltMapping` turns one quilt frame ``(H, W, 3)`` into the profile's ``N`` views
``(N, H // rows, W // cols, 3)`` with :func:`~.views.split_quilt` (left-over pixels of sides the
grid does not divide unused, as Looking Glass leaves them); a quilt of another tile count is
sampled as Looking Glass samples it: profile view ``i`` (of ``N``) shows tile
``floor((i + 0.5) * T / N)`` (of ``T``), the tile at the same fraction of the view cone
(:func:`tile_for_views`).  A quilt made for another aspect ratio than the panel's is refused in
one line unless ``allow_stretch``.

:class:`FrameReader` reads a video (opened by :func:`lenticalib.core.files.video.open_video`) on a
thread into a queue of at most two frames, already split into views, and seeks on request.
"""

from __future__ import annotations

import dataclasses
import math
import os
import queue
import threading
from pathlib import Path

import numpy as np

from ...core.errors import ImageError, InputError
from ...core.files.imageio import IMAGE_SUFFIXES, cv2_quiet, read_image
from ...core.profile import PanelProfile
from ...core.files.video import open_video
from ..compose.views import QuiltGrid, natural_key, parse_quilt_name, split_quilt

VIDEO_SUFFIXES = (".mp4", ".mkv", ".avi", ".mov", ".webm", ".m4v", ".mpg", ".mpeg")  # as render.offline's
ASPECT_TOLERANCE = 0.01  # as the encoders' check_views
QUEUE_FRAMES = 2  # decoded frames waiting to be shown (a 4K quilt's views are 25 MB each)
GRID_HINT = "name the file with a _qsCOLSxROWSaASPECT suffix or give the `grid`"


def tile_for_views(tiles: int, views: int) -> np.ndarray:
    """int ``(views,)``: the quilt tile (of ``tiles``, view 0 bottom-left) each profile view shows:
    the tile at the view's fraction of the cone, ``floor((i + 0.5) * tiles / views)``; the
    identity when the counts agree."""
    return np.minimum(((np.arange(views) + 0.5) * tiles / views).astype(np.int64), tiles - 1)


@dataclasses.dataclass(frozen=True)
class QuiltItem:
    """One file to play: ``path``, ``video`` (True: a video) and its ``grid``."""

    path: Path
    video: bool
    grid: QuiltGrid

    @property
    def source(self) -> str:
        return str(self.path)


@dataclasses.dataclass(frozen=True)
class QuiltMapping:
    """Quilt frames of ``grid`` -> the views of ``profile`` (module docstring)."""

    profile: PanelProfile
    grid: QuiltGrid
    allow_stretch: bool = False

    def check_aspect(self, tile_aspect: float | None, source: str) -> None:
        """ImageError naming ``source`` when the quilt's aspect (the grid's, else ``tile_aspect``,
        width / height of a tile) is not the panel's within 1 %, unless ``allow_stretch``."""
        aspect = self.grid.aspect or tile_aspect
        panel = self.profile.width / self.profile.height
        if aspect is None or self.allow_stretch or abs(aspect / panel - 1.0) <= ASPECT_TOLERANCE:
            return
        raise ImageError(f"quilt was made for aspect {aspect:.4g}, the profile's panel is "
                         f"{self.profile.width}x{self.profile.height} (aspect {panel:.4f})", source=source,
                         hint="use the profile of the panel the quilt was made for, or allow_stretch")

    def views(self, quilt: np.ndarray, source: str) -> np.ndarray:
        """``(N, H // rows, W // cols, 3)`` views of the quilt frame ``(H, W, 3)`` (view 0
        bottom-left).  A quilt whose sides do not divide by the grid (Looking Glass's 4096x4096 8x6
        quilts: tiles of 512x682) is read as Looking Glass reads it: tiles of the whole pixels from
        the bottom-left, the left-over rows at the top and columns at the right unused."""
        height, width = quilt.shape[:2]
        th, tw = height // self.grid.rows, width // self.grid.cols
        if not th or not tw:
            raise ImageError(f"a {width}x{height} quilt has no pixel per tile in a {self.grid.cols}x{self.grid.rows} "
                             "grid", source=source, hint="check the grid (file-name suffix _qsCOLSxROWS or `grid`)")
        tiles = split_quilt(quilt[height - th * self.grid.rows:, :tw * self.grid.cols], self.grid, source=source)
        self.check_aspect(tiles.shape[2] / tiles.shape[1], source)
        if self.grid.tiles == self.profile.views:
            return tiles
        return tiles[tile_for_views(self.grid.tiles, self.profile.views)]


def grid_for(path: str | os.PathLike, grid: QuiltGrid | None = None, aspect: float | None = None,
             default: QuiltGrid | None = None) -> QuiltGrid:
    """The grid of the quilt file ``path``: ``grid`` (cols, rows) if given, else its name's, else
    ``default`` (the quilt of the panel's Looking Glass model); its aspect ``aspect`` if given, else
    the chosen grid's, else its name's.  ImageError when none says."""
    named = parse_quilt_name(os.fspath(path))
    chosen = grid or named or default
    if chosen is None:
        raise ImageError("quilt grid unknown", source=os.fspath(path), hint=GRID_HINT)
    aspect = aspect or chosen.aspect or (named.aspect if named is not None else None)
    return QuiltGrid(chosen.cols, chosen.rows, aspect)


def quilt_items(path: str | os.PathLike, grid: QuiltGrid | None = None, aspect: float | None = None,
                default: QuiltGrid | None = None) -> list[QuiltItem]:
    """The quilt images and videos of ``path`` (one file, or a folder's, in natural name order),
    each with its grid (:func:`grid_for`); ImageError naming the path for anything else."""
    p = Path(path)
    if not p.exists():
        raise ImageError("no such file or folder", source=str(p), hint="give a quilt image, a quilt video or a folder")
    suffixes = tuple(IMAGE_SUFFIXES) + VIDEO_SUFFIXES
    if p.is_dir():
        files = sorted((f for f in p.iterdir() if f.is_file() and f.suffix.lower() in suffixes
                        and not f.name.startswith(".")), key=natural_key)
        if not files:
            raise ImageError("holds no quilt images or videos", source=str(p),
                             hint=f"give a folder of {', '.join(suffixes)} files")
    else:
        if p.suffix.lower() not in suffixes:
            raise ImageError(f"is not a quilt image or video ({p.suffix or 'no suffix'})", source=str(p),
                             hint=f"give a {', '.join(suffixes)} file")
        files = [p]
    return [QuiltItem(f, f.suffix.lower() in VIDEO_SUFFIXES, grid_for(f, grid, aspect, default)) for f in files]


def check_video(item: QuiltItem, mapping: QuiltMapping) -> None:
    """Open the video ``item`` and check its frame size against its grid and the panel's aspect
    (header only, nothing decoded); one error naming the file otherwise."""
    cap = open_video(item.path, "quilt video")
    try:
        cv2 = cv2_quiet()
        width, height = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    finally:
        cap.release()
    grid = item.grid
    if width < grid.cols or height < grid.rows:
        raise ImageError(f"its {width}x{height} frames have no pixel per tile in a {grid.cols}x{grid.rows} grid",
                         source=item.source, hint="check the grid (file-name suffix _qsCOLSxROWS or `grid`)")
    mapping.check_aspect((width // grid.cols) / (height // grid.rows), item.source)


def read_quilt_image(item: QuiltItem, mapping: QuiltMapping) -> np.ndarray:
    """The views of the quilt image ``item`` (read through :func:`lenticalib.core.files.imageio.read_image`)."""
    return mapping.views(read_image(item.path), item.source)


@dataclasses.dataclass(frozen=True)
class Frame:
    """A decoded video frame: ``generation`` (the reader's seek count when read), ``index`` (frame
    number in the video), ``views`` ``(N, H_v, W_v, 3)`` uint8; None marks the video's end."""

    generation: int
    index: int
    views: np.ndarray | None


class FrameReader:
    """Decodes the video ``item`` on a thread into :attr:`frames` (a queue of at most
    :data:`QUEUE_FRAMES`), each split into views by ``mapping``.  :meth:`seek` restarts reading at
    a frame (frames read before carry an older generation); after the last frame a
    :class:`Frame` with ``views`` None is queued and the reader waits for a seek or :meth:`close`.
    A decoding error is kept in :attr:`error` (re-raised by :meth:`check`)."""

    def __init__(self, item: QuiltItem, mapping: QuiltMapping):
        self.item, self.mapping = item, mapping
        self.cap = open_video(item.path, "quilt video")
        cv2 = cv2_quiet()
        fps = self.cap.get(cv2.CAP_PROP_FPS)
        self.fps = float(fps) if math.isfinite(fps) and 0 < fps <= 1000 else None  # None: the file does not say
        count = self.cap.get(cv2.CAP_PROP_FRAME_COUNT)
        self.frame_count = int(count) if math.isfinite(count) and count > 0 else None
        self.frames: queue.Queue[Frame] = queue.Queue(maxsize=QUEUE_FRAMES)
        self.error: BaseException | None = None
        self.decoded = 0
        self._seek: tuple[int, int] | None = None
        self._generation = 0
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="quilt-reader", daemon=True)
        self._thread.start()

    @property
    def generation(self) -> int:
        return self._generation

    def seek(self, index: int) -> int:
        """Read from frame ``index`` on (clamped to the video); returns the new generation."""
        top = (self.frame_count - 1) if self.frame_count else index
        with self._lock:
            self._generation += 1
            self._seek = (self._generation, max(0, min(int(index), top)))
        self._wake.set()
        return self._generation

    def ready(self) -> bool:
        """Whether a frame of the current generation (not the end) waits in :attr:`frames`."""
        with self.frames.mutex:
            return any(f.views is not None and f.generation == self._generation for f in self.frames.queue)

    def check(self) -> None:
        if self.error is not None:
            raise self.error

    def _run(self) -> None:
        cv2 = cv2_quiet()
        generation, index = 0, 0
        try:
            while not self._stop.is_set():
                with self._lock:
                    request, self._seek = self._seek, None
                if request is not None:
                    generation, index = request
                    self.cap.set(cv2.CAP_PROP_POS_FRAMES, index)
                ok, frame = self.cap.read()
                if not ok:
                    if index == 0 and generation == 0:
                        raise InputError("no frame of this quilt video decodes", source=self.item.source,
                                         hint="convert it (e.g. to H.264 .mp4 or FFV1 .avi)")
                    self._put(Frame(generation, index, None))
                    self._wake.wait()  # a seek (or close) wakes the reader
                    self._wake.clear()
                    continue
                if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
                    raise ImageError(f"decodes to frames of shape {frame.shape} {frame.dtype}, not 8-bit colour",
                                     source=self.item.source)
                self.decoded += 1
                views = self.mapping.views(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB), self.item.source)
                self._put(Frame(generation, index, views))
                index += 1
        except BaseException as exc:  # noqa: BLE001 -- handed to the player's thread
            self.error = exc
            self._put(Frame(generation, index, None))

    def _put(self, frame: Frame) -> None:
        while not self._stop.is_set():
            if frame.generation != self._generation:
                return  # a seek came: this frame will not be shown
            try:
                self.frames.put(frame, timeout=0.05)
                return
            except queue.Full:
                continue

    def close(self) -> None:
        self._stop.set()
        self._wake.set()
        self._thread.join(timeout=5)
        self.cap.release()

    def __enter__(self) -> "FrameReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
