"""Frames for the student driver: a video file, a folder of images, or a camera, through OpenCV.

Every frame is RGB uint8 (H, W, 3) with its time in seconds: a video's own timestamps (its
frame rate), a folder's images at :data:`FOLDER_FPS` in natural name order (``frame-2.png``
before ``frame-10.png``), a camera's wall-clock time.  :func:`open_frames` checks its input in
full before anything else runs: a missing path, a folder without images, a video OpenCV cannot
open or decode, a camera that does not deliver a frame, each one InputError naming it.  A video
must be a regular file (a FIFO, device or socket is refused: OpenCV would wait on it for ever),
and a camera an index 0..:data:`MAX_CAMERA_INDEX`, checked before OpenCV sees either.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Iterator

import numpy as np

from ...core.errors import InputError
from ...core.files.imageio import IMAGE_SUFFIXES, read_image
from ...core.files.video import open_video
from ..compose.views import natural_key

FOLDER_FPS = 30.0  # a folder of images is taken as frames at this rate
CAMERA_OPEN_S = 5.0  # a camera must deliver its first frame within this time
# OpenCV's camera indices: 100 and above choose a backend (CAP_V4L2 + K = 200 + K), negative ones
# "any camera"; some backends crash on such an index, so only 0..99 ever reach it
MAX_CAMERA_INDEX = 99


def check_camera_index(index) -> int:
    """``index`` once it is a whole number 0..MAX_CAMERA_INDEX; InputError naming ``camera`` otherwise."""
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index <= MAX_CAMERA_INDEX:
        raise InputError(f"camera {index!r} is not a camera index 0..{MAX_CAMERA_INDEX}", source="camera")
    return index


class FrameSource:
    """Frames of a video or a folder: ``len()``, ``fps``, iteration as (index, t seconds, rgb),
    ``size`` (W, H) of the first frame and ``source`` (the path)."""

    def __init__(self, source: str, files: list[Path] | None, fps: float, count: int, size: tuple[int, int]):
        self.source = source
        self._files = files
        self.fps = fps
        self._count = count
        self.size = size

    def __len__(self) -> int:
        return self._count

    def __iter__(self) -> Iterator[tuple[int, float, np.ndarray]]:
        if self._files is not None:
            for k, f in enumerate(self._files):
                yield k, k / self.fps, read_image(f)
            return
        import cv2

        cap = open_video(self.source)
        try:
            k = 0
            while True:
                ok, bgr = cap.read()
                if not ok:
                    break
                yield k, k / self.fps, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
                k += 1
        finally:
            cap.release()


def open_frames(spec: str | os.PathLike) -> FrameSource:
    """The frames of ``spec``: a folder of images or a video file (module docstring)."""
    p = Path(spec)
    source = str(p)
    if p.is_dir():
        files = sorted((f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES and not f.name.startswith(".")),
                       key=natural_key)
        if not files:
            raise InputError("the folder holds no images", source=source,
                             hint=f"give a video or a folder of frames ({', '.join(sorted(IMAGE_SUFFIXES))})")
        first = read_image(files[0])
        return FrameSource(source, files, FOLDER_FPS, len(files), (first.shape[1], first.shape[0]))
    if not os.path.lexists(p):
        raise InputError("no such video or folder of frames", source=source)
    import cv2

    cap = open_video(p)  # a regular file within the caps; its stated frame size and count checked before a read
    try:
        ok, bgr = cap.read()
        if not ok:
            raise InputError("OpenCV cannot open or decode this video", source=source,
                             hint="convert it (e.g. to H.264 .mp4 or MJPEG .avi), or give a folder of frames")
        fps = cap.get(cv2.CAP_PROP_FPS)
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()
    if not (np.isfinite(fps) and fps > 0):
        fps = FOLDER_FPS
    if count <= 0:  # some containers do not say: count by reading
        count = sum(1 for _ in FrameSource(source, None, fps, 0, (0, 0)))
    return FrameSource(source, None, float(fps), count, (bgr.shape[1], bgr.shape[0]))


class CameraFrames:
    """The latest frame of a live source (a camera index or a video file played in real time),
    grabbed by a background thread so that :meth:`latest` never waits for the device.

    ``latest()`` -> (frame number, rgb) of the newest frame, or (the same number, the same frame)
    when none came since; ``failures`` counts reads that delivered nothing.
    """

    def __init__(self, spec: int | str, loop: bool = True):
        import threading

        import cv2

        self.is_video = isinstance(spec, str)
        self.spec = spec if self.is_video else check_camera_index(spec)  # a video: open_video checks it
        self._cap = open_video(spec) if self.is_video else cv2.VideoCapture(spec)
        self._loop = loop and self.is_video
        self._fps = self._cap.get(cv2.CAP_PROP_FPS) if self.is_video else 0.0
        self._lock = threading.Lock()
        self._frame = None
        self._number = -1
        self.failures = 0
        self._stop = threading.Event()
        start = time.monotonic()
        ok, bgr = self._cap.read() if self._cap.isOpened() else (False, None)
        while not ok and self._cap.isOpened() and time.monotonic() - start < CAMERA_OPEN_S and not self.is_video:
            time.sleep(0.05)
            ok, bgr = self._cap.read()
        if not ok:
            self._cap.release()
            what = "video" if self.is_video else "camera"
            raise InputError(f"OpenCV cannot open this {what} or read a frame from it", source=str(spec),
                             hint="check the camera index (0, 1 ...) and that no other program holds it"
                             if not self.is_video else "convert the video, or give another file")
        self._set(bgr)
        self._thread = threading.Thread(target=self._grab, name="student-frames", daemon=True)
        self._thread.start()

    def _set(self, bgr) -> None:
        import cv2

        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        with self._lock:
            self._frame = rgb
            self._number += 1

    def _grab(self) -> None:
        import cv2

        period = 1.0 / self._fps if self.is_video and self._fps and self._fps > 0 else 0.0
        while not self._stop.is_set():
            ok, bgr = self._cap.read()
            if not ok:
                if self._loop:
                    self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
                    ok, bgr = self._cap.read()
                if not ok:
                    self.failures += 1
                    time.sleep(0.02)
                    continue
            self._set(bgr)
            if period:
                time.sleep(period)

    def latest(self) -> tuple[int, np.ndarray]:
        with self._lock:
            return self._number, self._frame

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)
        self._cap.release()
