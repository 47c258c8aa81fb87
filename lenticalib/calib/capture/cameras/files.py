"""Putting a photo in place: the destination's suffix, and atomic moves, copies and writes.

A photo for pattern NAME lands at ``destination + suffix`` (``destination`` = ``DIR/captures/NAME``)
through a temporary file in the same folder and ``os.replace``, so the fit never sees half a
photo.  Temporary names start with a dot, which the fit skips (:mod:`lenticalib.calib.patterns.capture_sets`),
so even a file left behind by a killed process does not break the capture set.  After the new
photo is in place, a photo of the same pattern with *another* suffix (``NAME.png`` when
``NAME.jpg`` was just taken) is removed: the fit takes one photo per pattern.
"""

from __future__ import annotations

import os
from pathlib import Path

from ....core.files.atomic import output_target, write_bytes_atomic
from ....core.errors import CameraError, InputError
from ....core.files.imageio import MAX_IMAGE_FILE_BYTES
from ....core.files.input_files import read_input
from ...patterns.capture_sets import PHOTO_SUFFIXES

__all__ = ["PHOTO_SUFFIXES", "copy_photo", "existing_photos", "photo_path", "place_photo", "write_photo"]


def photo_path(destination: Path, suffix: str) -> Path:
    """``destination`` with ``suffix`` appended (lower-cased), e.g. ``captures/x0-0`` + ``.JPG`` ->
    ``captures/x0-0.jpg``.  Appended, not substituted: a name like ``f16.5-0`` keeps its dot."""
    return destination.with_name(destination.name + suffix.lower())


def existing_photos(destination: Path) -> list[Path]:
    """The files ``destination`` + any photo suffix (any case) that exist now, sorted by name."""
    folder = destination.parent
    try:
        entries = list(folder.iterdir())
    except OSError:
        return []
    return sorted(p for p in entries if p.is_file() and p.name[: len(destination.name)] == destination.name
                  and p.name[len(destination.name):].lower() in PHOTO_SUFFIXES)


def _drop_other_suffixes(final: Path, destination: Path) -> None:
    for other in existing_photos(destination):
        if other.name != final.name:
            try:
                other.unlink()
            except FileNotFoundError:
                pass


def place_photo(temporary: Path, destination: Path, suffix: str) -> Path:
    """Move ``temporary`` (a file in the destination's folder or below it) to ``destination`` +
    ``suffix`` with ``os.replace``; returns the final path."""
    final = photo_path(destination, suffix)
    try:
        os.replace(temporary, output_target(final, "photo"))  # never over a FIFO, device or folder
    except InputError:
        temporary.unlink(missing_ok=True)
        raise
    except OSError as exc:
        raise CameraError(f"cannot store the photo: {exc.strerror}", source=str(final),
                          hint="check free space and permissions of the capture folder") from None
    _drop_other_suffixes(final, destination)
    return final


def write_photo(data: bytes, destination: Path, suffix: str) -> Path:
    """Write the encoded photo ``data`` to ``destination`` + ``suffix`` atomically; returns the path."""
    final = write_bytes_atomic(photo_path(destination, suffix), data)
    _drop_other_suffixes(final, destination)
    return final


def copy_photo(source: Path, destination: Path) -> Path:
    """Copy ``source`` (left where it is) to ``destination`` + its own suffix atomically; returns the path."""
    try:
        data = read_input(source, "photo", MAX_IMAGE_FILE_BYTES, "check that the file is readable")
    except InputError as exc:  # a FIFO or device is refused at once
        raise CameraError(f"cannot read the photo: {exc.message}", source=str(source),
                          hint="check that the file is readable") from None
    return write_photo(data, destination, Path(source).suffix)
