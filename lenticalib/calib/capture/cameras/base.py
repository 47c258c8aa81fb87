"""The capture-camera contract: open, report what was locked, take one photo into place, close.

:class:`CaptureCamera` is a template: the public methods own the checks every backend shares
(the camera is open, the name and the shown raster are usable, the destination has no suffix and
its folder exists) and the bookkeeping; a backend implements only ``_open``, ``_capture`` and
``_close``.
"""

from __future__ import annotations

import abc
import math
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ....core.errors import CameraError, InputError
from ....core.sizes import check_raster
from .files import PHOTO_SUFFIXES


class CaptureCamera(abc.ABC):
    """A camera that photographs the panel for ``lenticalib capture``.

    ``kind`` is the registry name ("gphoto2", "opencv", "manual", "sim"); ``target`` the part of
    the ``--camera`` spec after the colon (a port, an index, a folder, a seed; ``None`` if absent).
    Keyword options: ``timeout`` (seconds, every kind: the longest the camera may take for one
    step; each module says what that is for it) and the kind's own ``OPTIONS``; any other is an
    InputError.  An option given as None takes its default, so a caller can pass the same
    options to every kind.

    Use it as a context manager (``__enter__`` opens, ``__exit__`` closes) or call :meth:`open`
    and :meth:`close` yourself.  Nothing is printed: results are return values, failures
    :class:`~lenticalib.core.errors.CameraError` (the camera) or InputError (the arguments).
    """

    kind: ClassVar[str] = ""
    OPTIONS: ClassVar[tuple[str, ...]] = ()  # besides "timeout"

    def __init__(self, target: str | None = None, **options: Any):
        options = {key: value for key, value in options.items() if value is not None}
        known = ("timeout",) + tuple(self.OPTIONS)
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise InputError(f"camera kind {self.kind!r} takes no option {', '.join(map(repr, unknown))}",
                             source="camera", hint="its options: " + ", ".join(known))
        self.target = target
        self.options = dict(options)
        self.is_open = False
        self._settings: list[str] = []

    @property
    def spec(self) -> str:
        """The ``--camera`` spec this camera answers to, e.g. ``"opencv:0"``."""
        return self.kind if self.target is None else f"{self.kind}:{self.target}"

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.spec} {'open' if self.is_open else 'closed'}>"

    # -- public template ------------------------------------------------------------------------
    def open(self) -> None:
        """Connect and lock what can be locked; CameraError (one line) if the camera cannot be used.

        Opening an open camera does nothing.
        """
        if self.is_open:
            return
        self._settings = list(self._open())
        self.is_open = True

    def settings(self) -> list[str]:
        """Human-readable lines: what was locked (exposure, focus, white balance, format) and what
        could not be, with the reason.  Empty before :meth:`open`."""
        return list(self._settings)

    def capture(self, name: str, shown: np.ndarray | None, destination: str | Path) -> Path:
        """Photograph what the panel shows now and put the photo in place atomically.

        ARGUMENTS
        name          the pattern's name (e.g. ``"x0-0"``)
        shown         uint8 ``(H, W, 3)`` RGB raster on the panel, or None (only "sim" needs it)
        destination   the photo's path *without* suffix, e.g. ``DIR/captures/x0-0``; its folder is
                      created if missing

        RETURNED VALUE
        The photo's path: ``destination`` + the backend's suffix (``.jpg``, or the camera's own
        ``.jpeg``/``.png``/``.tif``/``.tiff``).  The file appears complete or not at all (temporary
        file in the same folder + ``os.replace``).

        Raises CameraError when the camera is not open or the trigger / transfer fails, InputError
        for an unusable name, raster or destination.
        """
        if not self.is_open:
            raise CameraError("the camera is not open", source=self.spec,
                              hint="call open() first, or use the camera in a 'with' block")
        if not isinstance(name, str) or not name.strip():
            raise InputError(f"the pattern name must be a non-empty string, got {name!r}", source="name")
        if shown is not None:
            shown = check_raster(shown, None, None, "shown", error=InputError)
        destination = Path(destination)
        if destination.suffix.lower() in PHOTO_SUFFIXES:
            raise InputError(f"has the suffix {destination.suffix}; give the path without one (the camera "
                             "picks it)", source=str(destination), hint=f"e.g. {destination.with_suffix('')}")
        try:
            destination.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"cannot create the folder: {exc.strerror}", source=str(destination.parent),
                             hint="choose a writable capture folder") from None
        return Path(self._capture(name, shown, destination))

    def close(self) -> None:
        """Release the camera (and finish what the backend writes on close).  Idempotent."""
        if not self.is_open:
            return
        try:
            self._close()
        finally:
            self.is_open = False

    def __enter__(self) -> "CaptureCamera":
        self.open()
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    # -- backend hooks ----------------------------------------------------------------------------
    @abc.abstractmethod
    def _open(self) -> list[str]:
        """Connect; return the settings lines.  CameraError if the camera cannot be used."""

    @abc.abstractmethod
    def _capture(self, name: str, shown: np.ndarray | None, destination: Path) -> Path:
        """Take the photo and put it at ``destination`` + suffix (see :mod:`.files`); return that path."""

    def _close(self) -> None:
        """Release what :meth:`_open` acquired."""


def positive_seconds(value: Any, option: str, kind: str) -> float:
    """A timeout or interval option as a positive finite number of seconds; InputError otherwise."""
    try:
        seconds = float(value)
    except (TypeError, ValueError):
        seconds = float("nan")
    if isinstance(value, bool) or not (math.isfinite(seconds) and seconds > 0):
        raise InputError(f"option {option!r} must be a positive number of seconds, got {value!r}",
                         source=f"camera {kind}")
    return seconds
