"""The user presses the shutter: photos arrive in a watched folder, or are put in place by hand.

``manual:/path`` (watched folder): the camera, its tethering app or a phone's sync app saves
photos into ``/path``.  :meth:`capture` notes the image files there when it is called (the caller
calls it right after the pattern appears), then polls every ``poll`` seconds (default 0.2) for the
next *new* ``.jpg .jpeg .png .tif .tiff`` file (any case; names starting with "." or "~" are
skipped), waits until its size is the same in two polls in a row (a file still being written or
synced is not taken), and copies it (the original stays) to ``destination`` + its own suffix.
No new photo within ``timeout`` seconds (default 600) is a CameraError.

``manual`` (key mode): :meth:`capture` calls ``wait_for_user(name)`` (an option: the caller's
"press a key when done" prompt) and then expects the user to have copied the photo to
``destination`` + one of the suffixes *themselves*; the photo is taken as it is found (a file
already there before the key press counts too).  Nothing there, or two files for one pattern,
is a CameraError.

Either way lenticalib cannot lock anything: the user must set manual exposure, manual focus
and a fixed white balance on the camera (:meth:`settings` says so).
"""

from __future__ import annotations

import time
from pathlib import Path

from ....core.errors import CameraError, InputError
from .base import CaptureCamera, positive_seconds
from .files import PHOTO_SUFFIXES, copy_photo, existing_photos

DEFAULT_TIMEOUT = 600.0  # seconds to wait for a new photo in the watched folder
DEFAULT_POLL = 0.2  # seconds between two looks at the watched folder
SUFFIX_LIST = "/".join(PHOTO_SUFFIXES)
NOTHING_LOCKED = ("exposure, focus, white balance: not controlled by lenticalib - set manual exposure, manual "
                  "focus and a fixed white balance on the camera yourself")


class ManualCamera(CaptureCamera):
    """A camera whose shutter the user presses (see the module docstring)."""

    kind = "manual"
    OPTIONS = ("wait_for_user", "poll")

    def __init__(self, target: str | None = None, **options):
        super().__init__(target, **options)
        self.folder = Path(target).expanduser() if target is not None else None
        self.timeout = positive_seconds(self.options.get("timeout", DEFAULT_TIMEOUT), "timeout", self.kind)
        self.poll = positive_seconds(self.options.get("poll", DEFAULT_POLL), "poll", self.kind)
        self.wait_for_user = self.options.get("wait_for_user")

    def _open(self) -> list[str]:
        if self.folder is None:
            if not callable(self.wait_for_user):
                raise InputError("key mode needs a wait_for_user callable", source="camera manual",
                                 hint="give a watched folder instead: `camera` manual:/path/the/photos/arrive/in")
            return [NOTHING_LOCKED, f"key mode: copy each photo to the capture folder as PATTERN ({SUFFIX_LIST}) "
                                    "yourself, then press the key"]
        if not self.folder.is_dir():
            state = "is not a folder" if self.folder.exists() else "does not exist"
            raise CameraError(f"the watched folder {state}", source=str(self.folder),
                              hint="create it, or point `camera` manual: at the folder the camera or its app saves to")
        return [NOTHING_LOCKED, f"watched folder: {self.folder} (the next new {SUFFIX_LIST} file is copied, "
                                f"waiting up to {self.timeout:g} s)"]

    def _capture(self, name, shown, destination: Path) -> Path:
        if self.folder is None:
            return self._placed_by_user(name, destination)
        if self.folder.resolve() == destination.parent.resolve():
            raise InputError("the watched folder is the capture folder", source=str(self.folder),
                             hint="let the camera save into another folder; lenticalib copies each photo over")
        return copy_photo(self._next_new_photo(), destination)

    def _images(self) -> dict[str, tuple[int, int]]:
        """Image files in the watched folder now: name -> (size in bytes, mtime in ns)."""
        found = {}
        try:
            entries = list(self.folder.iterdir())
        except OSError as exc:
            raise CameraError(f"cannot read the watched folder: {exc.strerror}", source=str(self.folder),
                              hint="check that it is still there (a card or share may have been unmounted)") from None
        for path in entries:
            if path.name.startswith((".", "~")) or path.suffix.lower() not in PHOTO_SUFFIXES:
                continue
            try:
                stat = path.stat()
            except OSError:  # vanished between the listing and the stat
                continue
            if path.is_file():
                found[path.name] = (stat.st_size, stat.st_mtime_ns)
        return found

    def _next_new_photo(self) -> Path:
        before = set(self._images())
        deadline = time.monotonic() + self.timeout
        previous: dict[str, int] = {}
        while True:
            fresh = {n: info for n, info in self._images().items() if n not in before}
            stable = [n for n, (size, _) in fresh.items() if size > 0 and previous.get(n) == size]
            if stable:  # the earliest, should two have arrived
                return self.folder / min(stable, key=lambda n: (fresh[n][1], n))
            previous = {n: size for n, (size, _) in fresh.items()}
            if time.monotonic() >= deadline:
                raise CameraError(f"no new photo appeared in the watched folder within {self.timeout:g} s",
                                  source=str(self.folder),
                                  hint=f"take the photo; check that the camera or its app saves {SUFFIX_LIST} "
                                       "files into this folder")
            time.sleep(self.poll)

    def _placed_by_user(self, name: str, destination: Path) -> Path:
        self.wait_for_user(name)
        found = existing_photos(destination)
        if not found:
            raise CameraError(f"no photo of pattern {name} was put in place", source=str(destination.parent),
                              hint=f"copy the photo there as {destination.name}.jpg (or {SUFFIX_LIST}) before "
                                   "pressing the key")
        if len(found) > 1:
            raise CameraError(f"{len(found)} photos of pattern {name}: {', '.join(p.name for p in found)}",
                              source=str(destination.parent), hint="keep one of them")
        return found[0]
