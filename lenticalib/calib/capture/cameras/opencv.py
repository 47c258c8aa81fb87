"""UVC webcams (and other video sources) through OpenCV's ``cv2.VideoCapture``.

Spec: ``opencv:INDEX`` (``opencv`` alone is index 0), or ``opencv:/dev/video2`` (a V4L2 device
path, stable when indices shift) or ``opencv:http://...`` (a network stream, e.g. a phone's
webcam app).  Options: ``resolution`` (w, h) to ask for, default 3840x2160 (the camera gives its
largest mode up to that); ``discard``, frames dropped before each photo (default 5: drivers queue
stale frames taken before the pattern changed); ``timeout``, seconds a frame read may block (default
10), asked of the back end as ``CAP_PROP_READ_TIMEOUT_MSEC`` (not every back end takes it; then
OpenCV's own limit applies, and :meth:`~.base.CaptureCamera.settings` says so).

``open()`` asks for the resolution, manual exposure (``CAP_PROP_AUTO_EXPOSURE``: V4L2 takes 1,
some other back ends 0.25), autofocus off and automatic white balance off, and reads every
property back: :meth:`~.base.CaptureCamera.settings` says what held.  Photos are written as JPEG
quality 95.
"""

from __future__ import annotations

from pathlib import Path

from ....core.errors import CameraError, InputError
from ....core.files.imageio import cv2_quiet
from .base import CaptureCamera, positive_seconds
from .files import write_photo

DEFAULT_RESOLUTION = (3840, 2160)  # asked for; the camera answers with what it can do
DEFAULT_DISCARD = 5  # frames
DEFAULT_TIMEOUT = 10.0  # seconds per frame read
JPEG_QUALITY = 95
MANUAL_EXPOSURE_VALUES = (1.0, 0.25)  # V4L2_EXPOSURE_MANUAL; the 0.25 convention of other back ends


def parse_device(target: str | None) -> int | str:
    """The VideoCapture argument for a spec target: an index, a device path or a stream URL."""
    if target is None:
        return 0
    text = target.strip()
    if text.isdigit():
        return int(text)
    if text.startswith(("/", "./")) or "://" in text:
        return text
    raise InputError(f"bad webcam {target!r}", source="camera",
                     hint="give an index (opencv:0), a device path (opencv:/dev/video2) or a stream URL")


class OpenCVCamera(CaptureCamera):
    """A webcam read through OpenCV (see the module docstring)."""

    kind = "opencv"
    OPTIONS = ("resolution", "discard")

    def __init__(self, target: str | None = None, **options):
        super().__init__(target, **options)
        self.device = parse_device(target)
        resolution = self.options.get("resolution", DEFAULT_RESOLUTION)
        try:
            width, height = (int(v) for v in resolution)
        except (TypeError, ValueError):
            width = height = 0
        if not (width > 0 and height > 0):
            raise InputError(f"option 'resolution' must be (width, height) in pixels, got {resolution!r}",
                             source="camera opencv")
        self.resolution = (width, height)
        discard = self.options.get("discard", DEFAULT_DISCARD)
        if not isinstance(discard, int) or isinstance(discard, bool) or not 0 <= discard <= 100:
            raise InputError(f"option 'discard' must be a whole number of frames 0..100, got {discard!r}",
                             source="camera opencv")
        self.discard = discard
        self.timeout = positive_seconds(self.options.get("timeout", DEFAULT_TIMEOUT), "timeout", self.kind)
        self._capture_device = None

    def _open(self) -> list[str]:
        cv2 = cv2_quiet()
        device = cv2.VideoCapture(self.device)
        if not device.isOpened():
            device.release()
            raise CameraError(f"cannot open webcam {self.device}", source=self.spec,
                              hint="check the index (ls /dev/video*), the cable, and that no other program uses it")
        self._capture_device = device
        return [self._ask_resolution(cv2), self._ask_exposure(cv2),
                self._ask_off(cv2, cv2.CAP_PROP_AUTOFOCUS, "focus", "autofocus",
                              "a fixed-focus webcam needs nothing; otherwise focus may hunt between photos"),
                self._ask_off(cv2, cv2.CAP_PROP_AUTO_WB, "white balance", "automatic white balance",
                              "colours may drift between photos"),
                self._ask_timeout(cv2)]

    def _set(self, prop: int, value: float) -> tuple[bool, float]:
        accepted = bool(self._capture_device.set(prop, value))
        return accepted, float(self._capture_device.get(prop))

    def _ask_resolution(self, cv2) -> str:
        width, height = self.resolution
        self._capture_device.set(cv2.CAP_PROP_FRAME_WIDTH, width)
        self._capture_device.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
        got = (int(self._capture_device.get(cv2.CAP_PROP_FRAME_WIDTH)),
               int(self._capture_device.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        if got[0] <= 0 or got[1] <= 0:
            return f"resolution: asked for {width}x{height}; the driver does not report what it gave"
        return f"resolution: {got[0]}x{got[1]} (asked for {width}x{height})"

    def _ask_exposure(self, cv2) -> str:
        answers = []
        for value in MANUAL_EXPOSURE_VALUES:
            accepted, back = self._set(cv2.CAP_PROP_AUTO_EXPOSURE, value)
            if accepted and abs(back - value) < 1e-6:
                exposure = self._capture_device.get(cv2.CAP_PROP_EXPOSURE)
                return f"exposure: manual (auto exposure mode {value:g}; exposure value {exposure:g} in driver units)"
            answers.append(f"{value:g} {'accepted' if accepted else 'refused'}, reads {back:g}")
        return (f"exposure: could not lock ({'; '.join(answers)}); brightness may change between photos - "
                "set manual exposure with the webcam's own tool (e.g. v4l2-ctl)")

    def _ask_off(self, cv2, prop: int, label: str, what: str, consequence: str) -> str:
        accepted, back = self._set(prop, 0)
        if accepted and back == 0:
            return f"{label}: {what} off"
        return (f"{label}: could not turn {what} off ({'accepted' if accepted else 'refused'}, reads {back:g}); "
                f"{consequence}")

    def _ask_timeout(self, cv2) -> str:
        milliseconds = round(self.timeout * 1000)
        accepted, back = self._set(cv2.CAP_PROP_READ_TIMEOUT_MSEC, milliseconds)
        if accepted and round(back) == milliseconds:
            return f"read timeout: {self.timeout:g} s"
        return (f"read timeout: this back end does not take one ({'accepted' if accepted else 'refused'}, "
                f"reads {back:g}); OpenCV's own limit applies")

    def _capture(self, name, shown, destination: Path) -> Path:
        cv2 = cv2_quiet()
        for _ in range(self.discard):
            self._capture_device.grab()
        ok, frame = self._capture_device.read()
        if not ok or frame is None or frame.size == 0:
            raise CameraError(f"the webcam returned no frame for {name}", source=self.spec,
                              hint="check the cable; another program may have taken the camera")
        ok, data = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        if not ok:
            raise CameraError(f"the frame for {name} could not be encoded as JPEG", source=self.spec)
        return write_photo(data.tobytes(), destination, ".jpg")

    def _close(self) -> None:
        if self._capture_device is not None:
            self._capture_device.release()
            self._capture_device = None
