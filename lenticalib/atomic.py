"""Atomic file output: a reader sees the old file or the new one, never a torn one."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import InputError


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` via a temporary file in the same folder and ``os.replace``.

    On any failure the temporary file is removed and an existing ``path`` is left as it was.
    Raises InputError when the folder does not exist or is not writable.
    """
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise InputError("output folder does not exist", source=str(folder),
                         hint="create it or choose another output path")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise InputError(f"cannot write here: {exc.strerror}", source=str(folder),
                         hint="choose a writable output folder") from None
    try:
        try:
            mode = target.stat().st_mode & 0o7777  # keep an existing file's permissions
        except FileNotFoundError:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.chmod(tmp, mode)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError):
            raise InputError(f"cannot write output: {exc.strerror}", source=str(target),
                             hint="check free space and permissions") from None
        raise
    return target


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """UTF-8 text flavour of :func:`write_bytes_atomic`."""
    return write_bytes_atomic(path, text.encode("utf-8"))
