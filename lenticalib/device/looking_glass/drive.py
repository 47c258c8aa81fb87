"""Later Looking Glass units (Portrait and others): the calibration on the unit's USB drive.

Such a unit shows a small USB drive holding ``LKG_calibration/visual.json``.
``lkg-drive:///media/USER/LKG-DRIVE`` names the drive's mount point (or any folder holding
``LKG_calibration/visual.json``, or ``visual.json`` itself: a copy of the drive).
:func:`find_drives` looks for mounted drives that hold the file: the mount points in
``/proc/mounts`` of file systems a USB drive carries (FAT, exFAT, NTFS, HFS+, ...; never network
or virtual ones, which could hang or are not drives), and the folders in ``/media/$USER`` and
``/run/media/$USER`` where desktops mount them.
"""

from __future__ import annotations

import getpass
import os
from pathlib import Path
from typing import Iterable

from ...core.errors import DeviceNotFoundError, InputError, LenticalibError
from ...core.files.input_files import UNBOUNDED, open_input
from ..transports.base import FoundDevice
from ..url import parse_device_url
from .unit import FAMILY, MAX_CALIBRATION_BYTES, LookingGlassUnit

CALIBRATION_FOLDER = "LKG_calibration"
CALIBRATION_FILE = "visual.json"
MOUNTS = "/proc/mounts"
DRIVE_FILESYSTEMS = frozenset({"vfat", "msdos", "exfat", "ntfs", "ntfs3", "fuseblk", "hfsplus", "apfs", "udf",
                               "iso9660"})


def calibration_file(folder: str | os.PathLike) -> Path | None:
    """The visual.json a folder holds: ``FOLDER/LKG_calibration/visual.json``, else
    ``FOLDER/visual.json``; None when it holds neither (or cannot be looked into)."""
    folder = Path(folder)
    for candidate in (folder / CALIBRATION_FOLDER / CALIBRATION_FILE, folder / CALIBRATION_FILE):
        try:
            if candidate.is_file():
                return candidate
        except OSError:
            return None
    return None


def _unescape(field: str) -> str:
    """A /proc/mounts field: spaces, tabs, newlines and backslashes are written as octal escapes."""
    for code, char in (("\\040", " "), ("\\011", "\t"), ("\\012", "\n"), ("\\134", "\\")):
        field = field.replace(code, char)
    return field


def mount_points(mounts: str | os.PathLike = MOUNTS) -> list[Path]:
    """Mount points of drive file systems (:data:`DRIVE_FILESYSTEMS`) in the mount table ``mounts``."""
    try:
        text = Path(mounts).read_text(encoding="utf-8", errors="replace")
    except OSError:
        return []
    points = []
    for line in text.splitlines():
        fields = line.split()
        if len(fields) >= 3 and fields[2] in DRIVE_FILESYSTEMS:
            points.append(Path(_unescape(fields[1])))
    return points


def media_roots() -> list[Path]:
    """Where desktops mount drives for this user: ``/media/USER`` and ``/run/media/USER``."""
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        return []
    return [Path("/media") / user, Path("/run/media") / user]


def find_drives(mounts: str | os.PathLike = MOUNTS, roots: Iterable[str | os.PathLike] | None = None) -> list[Path]:
    """Mounted folders that hold a Looking Glass calibration (sorted, each once)."""
    candidates = list(mount_points(mounts))
    for root in media_roots() if roots is None else roots:
        try:
            candidates.extend(sorted(p for p in Path(root).iterdir() if p.is_dir()))
        except OSError:
            continue
    found: dict[str, Path] = {}
    for folder in candidates:
        if calibration_file(folder) is not None:
            found.setdefault(os.path.realpath(folder), folder)
    return sorted(found.values())


def drive_url(folder: str | os.PathLike) -> str:
    """``lkg-drive://`` + the folder's absolute path."""
    return "lkg-drive://" + os.path.abspath(folder)


class DriveUnit(LookingGlassUnit):
    """A unit whose calibration is a file on its drive, ``lkg-drive:///MOUNT/POINT``."""

    kind = "drive"

    def __init__(self, url):
        super().__init__(url)
        if url.options:
            raise InputError(f"unknown URL parameter '{url.options[0][0]}'", source=str(url),
                             hint="lkg-drive:// takes no parameters")
        self.file: Path | None = None

    @classmethod
    def list_devices(cls) -> tuple[list[FoundDevice], list[str]]:
        """The mounted Looking Glass drives (``device list``)."""
        found, notes = [], []
        for folder in find_drives():
            url = drive_url(folder)
            try:
                with cls(parse_device_url(url)) as unit:
                    serial = unit.read_calibration().serial
            except LenticalibError as exc:  # listed all the same: reading it says what is wrong
                serial = None
                notes.append(f"{url}: {exc.message}")
            found.append(FoundDevice(url, "lkg-drive", FAMILY,
                                     f"Looking Glass drive ({CALIBRATION_FOLDER}/{CALIBRATION_FILE})", serial))
        return found, notes

    def open_hint(self) -> str:
        return (f"give the mount point of the unit's drive (it holds {CALIBRATION_FOLDER}/{CALIBRATION_FILE}); "
                "'lenticalib device list' prints the URL of each drive it finds")

    def retry_hint(self) -> str:
        return f"check {CALIBRATION_FOLDER}/{CALIBRATION_FILE} on the unit's drive; copy it again from a backup"

    def _open(self) -> None:
        folder = Path(self.url.target)
        if not folder.is_absolute():
            raise DeviceNotFoundError("the drive's folder must be an absolute path", source=str(self.url),
                                      hint="write it like lkg-drive:///media/USER/LKG-DRIVE")
        if not folder.is_dir():
            raise DeviceNotFoundError("no such folder (is the unit's drive mounted?)", source=str(self.url),
                                      hint=self.open_hint())
        self.file = calibration_file(folder)
        if self.file is None:
            raise DeviceNotFoundError(f"the folder holds no {CALIBRATION_FOLDER}/{CALIBRATION_FILE}",
                                      source=str(self.url), hint=self.open_hint())

    def _close(self) -> None:
        self.file = None

    def _read_text(self) -> tuple[bytes, Path]:
        # a regular file (a FIFO in its place is refused at once); its length is judged by the unit
        with open_input(self.file, "visual.json", UNBOUNDED) as fh:
            return fh.read(MAX_CALIBRATION_BYTES + 1), self.file  # one byte more: too long is refused
