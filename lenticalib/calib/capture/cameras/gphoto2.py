"""USB-tethered still cameras through the ``gphoto2`` command-line program (Debian package ``gphoto2``).

Spec: ``gphoto2`` (the one camera connected) or ``gphoto2:PORT`` with PORT as
``gphoto2 --auto-detect`` lists it (``gphoto2:usb:001,005``).  Option ``timeout``: seconds for
each gphoto2 command (default 60).

``open()`` finds the program, lists the cameras, and tries to lock each setting the fit needs
stable from photo to photo (:data:`LOCKS`: manual exposure, manual focus, a fixed white balance,
JPEG files) with ``--set-config``, reading each back with ``--get-config``.  Config names differ
between makers; a camera that knows none of the candidates, or refuses them (a mode dial or a
lens switch decides), is reported in :meth:`~.base.CaptureCamera.settings` as "could not lock",
with what to set by hand, and is not an error.

``capture()`` runs ``gphoto2 --capture-image-and-download --filename photo.%C`` in a hidden
temporary folder inside the capture folder (gphoto2 also puts its own download temp file in its
working folder), keeps the camera's format when it is JPEG, PNG or TIFF, and moves the file
into place with ``os.replace``.  Every command is an argument list; no shell is involved.
"""

from __future__ import annotations

import dataclasses
import shutil
import subprocess
import tempfile
from pathlib import Path

from ....core.errors import CameraError, InputError
from .base import CaptureCamera, positive_seconds
from .files import PHOTO_SUFFIXES, place_photo

DEFAULT_TIMEOUT = 60.0  # seconds per gphoto2 command
CONNECT_HINT = ("connect the camera over USB, switch it on, and close programs that hold it "
                "(e.g. gvfs-gphoto2-volume-monitor, a photo importer)")


@dataclasses.dataclass(frozen=True)
class Lock:
    """One setting to lock: its label, the (config name, value) candidates tried in order, and
    what the user should do when none takes."""

    label: str
    candidates: tuple[tuple[str, str], ...]
    by_hand: str


LOCKS = (
    Lock("exposure", (("/main/capturesettings/autoexposuremode", "Manual"),
                      ("/main/capturesettings/expprogram", "M")),
         "set the mode dial to M (manual exposure)"),
    Lock("focus", (("/main/capturesettings/focusmode", "Manual"),
                   ("/main/capturesettings/focusmode2", "MF")),
         "focus on the panel, then switch the lens or camera to MF"),
    Lock("white balance", (("/main/imgsettings/whitebalance", "Daylight"),),
         "set a fixed white balance (e.g. daylight) on the camera"),
    Lock("image format", (("/main/imgsettings/imageformat", "Large Fine JPEG"),
                          ("/main/capturesettings/imagequality", "JPEG Fine")),
         "set the camera to save JPEG (raw files are not read)"),
)


def last_line(result: subprocess.CompletedProcess) -> str:
    """The last non-empty line gphoto2 wrote to stderr (else stdout), or its exit status."""
    for stream in (result.stderr, result.stdout):
        lines = [line.strip() for line in (stream or "").splitlines() if line.strip()]
        if lines:
            return lines[-1]
    return f"exit status {result.returncode}"


def parse_auto_detect(text: str) -> list[tuple[str, str]]:
    """``gphoto2 --auto-detect`` output -> [(model, port)], the rows below the dashed rule."""
    rows, table = [], False
    for line in text.splitlines():
        if line.startswith("---"):
            table = True
            continue
        if table and line.strip():
            parts = line.rstrip().rsplit(None, 1)
            if len(parts) == 2:
                rows.append((parts[0].strip(), parts[1]))
    return rows


def parse_current(text: str) -> str | None:
    """The ``Current:`` value of ``gphoto2 --get-config`` output, or None."""
    for line in text.splitlines():
        if line.startswith("Current:"):
            return line[len("Current:"):].strip()
    return None


class Gphoto2Camera(CaptureCamera):
    """A still camera tethered over USB, driven by the gphoto2 program (see the module docstring)."""

    kind = "gphoto2"
    OPTIONS = ()

    def __init__(self, target: str | None = None, **options):
        super().__init__(target, **options)
        if target is not None and (":" not in target or not target.strip()):
            raise InputError(f"bad gphoto2 port {target!r}", source="camera",
                             hint="give the port as 'gphoto2 --auto-detect' lists it, e.g. gphoto2:usb:001,005")
        self.timeout = positive_seconds(self.options.get("timeout", DEFAULT_TIMEOUT), "timeout", self.kind)
        self.executable: str | None = None
        self.model: str | None = None
        self.port: str | None = target

    def _run(self, args: list[str], what: str, cwd: Path | None = None,
             port: bool = True) -> subprocess.CompletedProcess:
        command = [self.executable] + (["--port", self.port] if port and self.port else []) + args
        try:
            return subprocess.run(command, cwd=cwd, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                                  errors="replace", timeout=self.timeout, check=False)
        except subprocess.TimeoutExpired:
            raise CameraError(f"gphoto2 {what} got no answer within {self.timeout:g} s", source=self.spec,
                              hint="check the cable and that the camera is awake (turn auto power-off off)") from None
        except OSError as exc:
            raise CameraError(f"cannot run gphoto2: {exc.strerror}", source=str(self.executable),
                              hint="apt install gphoto2") from None

    def _open(self) -> list[str]:
        self.executable = shutil.which("gphoto2")
        if self.executable is None:
            raise CameraError("gphoto2 is not installed", source="gphoto2", hint="apt install gphoto2")
        result = self._run(["--auto-detect"], "--auto-detect", port=False)
        if result.returncode != 0:
            raise CameraError(f"gphoto2 --auto-detect failed: {last_line(result)}", source=self.spec,
                              hint=CONNECT_HINT)
        cameras = parse_auto_detect(result.stdout)
        if self.target is not None:
            cameras = [c for c in cameras if c[1] == self.target]
        if not cameras:
            where = f" on port {self.target}" if self.target else ""
            raise CameraError(f"no camera detected{where}", source=self.spec, hint=CONNECT_HINT)
        if len(cameras) > 1:
            listed = ", ".join(f"{model} ({port})" for model, port in cameras)
            raise CameraError(f"{len(cameras)} cameras detected: {listed}", source=self.spec,
                              hint=f"choose one with `camera` gphoto2:PORT, e.g. gphoto2:{cameras[0][1]}")
        self.model, self.port = cameras[0]
        lines = [f"camera: {self.model} on {self.port} (through {self.executable})"]
        lines += [self._lock(lock) for lock in LOCKS]
        return lines

    def _lock(self, lock: Lock) -> str:
        """Try each candidate of ``lock``; the settings line saying what held (or why nothing did)."""
        reasons = []
        for name, value in lock.candidates:
            short = name.rsplit("/", 1)[-1]
            result = self._run(["--set-config", f"{name}={value}"], "--set-config")
            if result.returncode != 0:
                reasons.append(f"{short}: {last_line(result)}")
                continue
            readback = self._run(["--get-config", name], "--get-config")
            current = parse_current(readback.stdout) if readback.returncode == 0 else None
            if current is None:
                return f"{lock.label}: set {short}={value} (the camera did not report it back)"
            if current == value:
                return f"{lock.label}: locked ({short}={value})"
            reasons.append(f"{short}: set to {value!r} but the camera kept {current!r}")
        return f"{lock.label}: could not lock on this camera ({'; '.join(reasons)}); {lock.by_hand}"

    def _capture(self, name, shown, destination: Path) -> Path:
        try:
            workdir = Path(tempfile.mkdtemp(prefix=f".{destination.name}.gphoto2-", dir=destination.parent))
        except OSError as exc:
            raise CameraError(f"cannot write here: {exc.strerror}", source=str(destination.parent),
                              hint="choose a writable capture folder") from None
        try:
            result = self._run(["--capture-image-and-download", "--filename", "photo.%C", "--force-overwrite"],
                               "capture", cwd=workdir)
            if result.returncode != 0:
                message = last_line(result)
                hint = (CONNECT_HINT if "claim" in message.lower() else
                        "check that the camera is awake, can focus (or is in MF) and has a memory card")
                raise CameraError(f"capture of {name} failed: {message}", source=self.spec, hint=hint)
            files = sorted(p for p in workdir.iterdir() if p.is_file() and not p.name.startswith("tmpfile"))
            photos = sorted((p for p in files if p.suffix.lower() in PHOTO_SUFFIXES),
                            key=lambda p: (p.suffix.lower() not in (".jpg", ".jpeg"), p.name))
            if not photos:
                got = ", ".join(sorted({p.suffix.lower() or "(no suffix)" for p in files})) or "nothing"
                raise CameraError(f"capture of {name} downloaded {got}, no JPEG, PNG or TIFF", source=self.spec,
                                  hint="set the camera to save JPEG (raw files are not read)")
            return place_photo(photos[0], destination, photos[0].suffix)
        finally:
            shutil.rmtree(workdir, ignore_errors=True)
