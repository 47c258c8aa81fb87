"""Opening a file the user gave as an input: a regular file of bounded size, or one error line.

Every reader of an input file (JSON documents, camera models, meshes, videos, a visual.json to
emulate) opens it through :func:`open_input` (or checks it with :func:`check_input` when a library
opens the path itself), so that

- a FIFO, a character or block device (``/dev/zero``) or a socket is refused at once: reading one
  would wait for a writer or never end.  The file is opened without blocking (``O_NONBLOCK``:
  opening a FIFO for reading otherwise waits for a writer) and its kind is taken from the opened
  descriptor (``fstat``), so a name swapped for a FIFO after a check is still caught;
- a file larger than the reader's cap (``max_bytes``: what the format can sensibly hold, each
  reader's own; docs/input-limits.md lists them) is refused from its size, before a byte is read,
  and :func:`read_input` never reads more than ``max_bytes + 1`` bytes even if the file grows.

:func:`size_text` writes sizes for people.  Every failure is one ``error`` (an
:class:`~.errors.InputError` class) naming the file:
``no such file``, ``is a folder, not a profile file``, ``is not a regular file (a FIFO, device or
socket), not a mesh file``, ``is 20.0 MiB, more than a profile file holds (at most 1.0 MiB)``.
Sizes are bytes.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from typing import IO, AnyStr, BinaryIO

from ..errors import InputError

KIB = 1 << 10
MIB = 1 << 20
GIB = 1 << 30
UNBOUNDED = 1 << 62  # for a caller that only needs the kind check (it bounds what it reads itself)


def size_text(nbytes: int) -> str:
    """Bytes for people: ``"2.0 GiB"``, ``"3.5 MiB"``, ``"120 bytes"``; absurd sizes in powers of ten."""
    if nbytes >= 1 << 50:
        return f"{nbytes:.3g} bytes"
    for unit, size in (("GiB", GIB), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if nbytes >= size:
            return f"{nbytes / size:.1f} {unit}"
    return f"{nbytes} bytes"


def file_noun(what: str) -> str:
    """``what`` as a kind of file with its article: "profile" -> "a profile file", "image" -> "an
    image file", "crosstalk file" and "visual.json" kept ("a crosstalk file", "a visual.json")."""
    noun = what if what.endswith((" file", ".json")) else f"{what} file"
    return f"{'an' if noun[0] in 'aeiou' else 'a'} {noun}"


def open_input(path: str | os.PathLike, what: str, max_bytes: int, hint: str | None = None,
               error: type[InputError] = InputError, *, source: str | None = None) -> BinaryIO:
    """``path`` opened for binary reading, once it is known to be a regular file of at most
    ``max_bytes`` bytes (module docstring); ``what`` names the kind of file in messages
    ("profile"), ``hint`` says what to give instead, ``source`` names the file (default: ``path``).
    The caller closes it (``with``)."""
    source = os.fspath(path) if source is None else source
    noun = file_noun(what)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise error("no such file", source=source, hint=hint) from None
    except IsADirectoryError:
        raise error(f"is a folder, not {noun}", source=source, hint=hint) from None
    except OSError as exc:  # a socket (ENXIO), no permission, a loop of links ...
        try:
            mode = os.stat(path).st_mode
        except OSError:
            mode = 0
        if stat.S_ISSOCK(mode):
            raise error(f"is not a regular file (a FIFO, device or socket), not {noun}", source=source,
                        hint=hint) from None
        raise error(f"cannot read: {exc.strerror or exc}", source=source, hint=hint) from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise error(f"is a folder, not {noun}", source=source, hint=hint)
        if not stat.S_ISREG(info.st_mode):
            raise error(f"is not a regular file (a FIFO, device or socket), not {noun}", source=source, hint=hint)
        if info.st_size > max_bytes:
            raise error(f"is {size_text(info.st_size)}, more than {noun} can sensibly hold (at most "
                        f"{size_text(max_bytes)})", source=source, hint=hint)
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def check_input(path: str | os.PathLike, what: str, max_bytes: int, hint: str | None = None,
                error: type[InputError] = InputError) -> int:
    """The size in bytes of ``path`` when :func:`open_input` accepts it (for readers that hand the
    path to a library: OpenCV, mrcal, plyfile); else its one ``error``."""
    with open_input(path, what, max_bytes, hint, error) as fh:
        return os.fstat(fh.fileno()).st_size


def read_input(path: str | os.PathLike, what: str, max_bytes: int, hint: str | None = None,
               error: type[InputError] = InputError) -> bytes:
    """The bytes of ``path`` (:func:`open_input`), at most ``max_bytes``: a file that grew past the
    cap while it was read is refused too, without reading more than ``max_bytes + 1`` bytes."""
    with open_input(path, what, max_bytes, hint, error) as fh:
        try:
            raw = fh.read(max_bytes + 1)
        except OSError as exc:
            raise error(f"cannot read: {exc.strerror or exc}", source=os.fspath(path), hint=hint) from None
    if len(raw) > max_bytes:
        raise error(f"grew beyond {size_text(max_bytes)} while it was read, more than {file_noun(what)} can "
                    "sensibly hold", source=os.fspath(path), hint=hint)
    return raw


def bounded_lines(fh: IO[AnyStr], limit: int, source: str, why: str = "",
                  hint: str | None = None) -> Iterator[tuple[int, AnyStr]]:
    """``(line number, line)`` of the open text or binary file ``fh``, numbered from 1, each line
    read with at most ``limit + 1`` characters (bytes for a binary file), so one endless line costs
    no memory; a longer line is one InputError naming ``source``, the line and the limit (``why``
    says what such a line would be, ``hint`` what to do)."""
    number = 0
    while True:
        line = fh.readline(limit + 1)
        if not line:
            return
        number += 1
        if len(line) > limit:
            raise InputError(f"line {number} is longer than {size_text(limit)}" + (f", {why}" if why else ""),
                             source=source, hint=hint)
        yield number, line
