"""Reading files of arrays (numpy ``.npy`` and ``.npz``; torch's ``.pt`` zip containers checked
here too) with every header checked before any data is read.

An array's header states its shape and dtype.  :func:`load_npz` and :func:`load_npy` read the
headers first (numpy's ``read_magic`` / ``read_array_header_1_0`` / ``read_array_header_2_0``; in
an ``.npz`` on each zip member), and refuse in one InputError naming the file and the array:

- an array the caller needs that is missing (before anything is inflated);
- a pickled object array;
- an array whose header claims more bytes than the file (or zip member) holds, e.g. a header
  of 10^12 elements over a few bytes of data;
- arrays that together claim more than ``max_bytes`` (a 2 MB deflated member expanding to
  2 GiB), or a caller's ``check`` on the headers (e.g. an image's pixel limit).

Only then are the arrays read, so the memory a bad file can take is bounded by the limits, not
by what its headers claim.  Shapes and dtypes are as stored; sizes are bytes.

ZIP CONTAINERS.  An ``.npz`` and a torch ``.pt`` (``torch.save``) are zip archives; a member
deflated from gigabytes of zeros is a few megabytes on disk.  :func:`open_zip` opens one (a
regular file only: a FIFO, device or socket is refused without blocking) and checks its
structure before anything is inflated: the end-of-central-directory record's member count and
central-directory size (so parsing the directory is bounded too), then every member's
uncompressed size as the central directory states it (which is what both Python's zipfile and
torch's reader allocate and stop at), against :class:`ZipLimits`, the format's own caps.
"""

from __future__ import annotations

import dataclasses
import math
import os
import struct
import zipfile
import zlib
from typing import IO, Callable, Iterable

import numpy as np
from numpy.lib import format as npformat

from ..errors import InputError
from .input_files import UNBOUNDED, open_input, size_text

GIB = 1 << 30
MIB = 1 << 20
NPY_HEADER_ROOM = 16 << 10  # bytes per .npz member for its .npy header (numpy reads headers up to 10000)


@dataclasses.dataclass(frozen=True)
class ArrayHeader:
    """What the header of one stored array says: ``name`` (the array's key; ``""`` for an .npy),
    ``shape``, ``dtype``, ``nbytes`` (bytes the shape and dtype need) and ``stored`` (bytes of
    data the file actually has after the header)."""

    name: str
    shape: tuple[int, ...]
    dtype: np.dtype
    nbytes: int
    stored: int


def _what(name: str) -> str:
    return f"array '{name}'" if name else "the array"


def _read_header(fp: IO[bytes], name: str, data_bytes: int, source: str) -> ArrayHeader:
    """The header at ``fp``'s position; ``data_bytes``: bytes from there to the end of the array."""
    start = fp.tell()
    try:
        version = npformat.read_magic(fp)
        if version == (1, 0):
            shape, _, dtype = npformat.read_array_header_1_0(fp)
        elif version == (2, 0):
            shape, _, dtype = npformat.read_array_header_2_0(fp)
        else:
            raise ValueError(f"unsupported .npy format version {version[0]}.{version[1]}")
    except (ValueError, EOFError, OSError, zipfile.BadZipFile, zlib.error) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"{_what(name)} has no readable .npy header ({reason})", source=source) from None
    if dtype.hasobject:
        raise InputError(f"{_what(name)} is a pickled object array, which is never read", source=source)
    nbytes = math.prod(shape) * dtype.itemsize
    return ArrayHeader(name, tuple(int(n) for n in shape), dtype, nbytes, data_bytes - (fp.tell() - start))


def _check_headers(headers: list[ArrayHeader], source: str, max_bytes: int | None,
                   check: Callable[[ArrayHeader], None] | None) -> None:
    for h in headers:
        if h.nbytes > h.stored:
            raise InputError(f"{_what(h.name)} claims shape {h.shape} of {h.dtype} ({size_text(h.nbytes)}) but "
                             f"holds only {size_text(max(h.stored, 0))} of data (truncated or corrupt)",
                             source=source)
    total = sum(h.nbytes for h in headers)
    if max_bytes is not None and total > max_bytes:
        big = max(headers, key=lambda h: h.nbytes)
        raise InputError(f"arrays of {size_text(total)} in all (the largest, {_what(big.name)}, has shape "
                         f"{big.shape}) exceed the limit of {size_text(max_bytes)}", source=source)
    if check is not None:
        for h in headers:
            check(h)


def _open_error(exc: OSError, source: str, what: str = "numpy file") -> InputError:
    if isinstance(exc, FileNotFoundError):
        return InputError("no such file", source=source, hint="check the path")
    if isinstance(exc, IsADirectoryError):
        return InputError(f"is a folder, not a {what}", source=source)
    return InputError(f"cannot read: {exc.strerror or exc}", source=source)


# ------------------------------------------------------------------ zip containers

@dataclasses.dataclass(frozen=True)
class ZipLimits:
    """What one zip format may hold, checked from the central directory before anything is inflated.

    ``total``: bytes all members inflate to together (None: no cap); ``header_room``: bytes more
    allowed per member (an ``.npy`` member's header); ``members``: the most entries; ``pickle``:
    the most bytes of a torch pickle member (``data.pkl``: unpickled, a few bytes can become many
    objects), None for none; ``directory_per_member``: central-directory bytes allowed per entry."""

    total: int | None
    header_room: int = 0
    members: int = 4096
    pickle: int | None = None
    directory_per_member: int = 1024


_EOCD = struct.Struct("<4s4H2LH")             # end of central directory record
_ZIP64_LOCATOR = struct.Struct("<4sLQL")
_ZIP64_EOCD = struct.Struct("<4sQ2H2L4Q")


def _directory(fh: IO[bytes], size: int) -> tuple[int, int] | None:
    """(entries, central-directory bytes) from the end records of the zip in ``fh``, or None when
    there is no end record (not a zip archive)."""
    tail_size = min(size, _EOCD.size + 0xFFFF)
    fh.seek(size - tail_size)
    tail = fh.read(tail_size)
    at = tail.rfind(b"PK\x05\x06")
    if at < 0 or at + _EOCD.size > len(tail):
        return None
    _, _, _, _, entries, cd_size, _, _ = _EOCD.unpack_from(tail, at)
    locator = size - tail_size + at - _ZIP64_LOCATOR.size
    if locator >= 0:
        fh.seek(locator)
        sig, _, offset, _ = _ZIP64_LOCATOR.unpack(fh.read(_ZIP64_LOCATOR.size))
        if sig == b"PK\x06\x07":
            fh.seek(offset)
            record = fh.read(_ZIP64_EOCD.size)
            if len(record) < _ZIP64_EOCD.size or record[:4] != b"PK\x06\x06":
                return None
            _, _, _, _, _, _, _, entries, cd_size, _ = _ZIP64_EOCD.unpack(record)
    return entries, cd_size


def check_zip(fh: IO[bytes], limits: ZipLimits, *, what: str, source: str,
              hint: str | None = None) -> list[zipfile.ZipInfo]:
    """The members of the zip archive in ``fh`` (seekable, binary), once its structure and every
    member's uncompressed size are within ``limits`` (module docstring); one InputError naming
    ``source`` otherwise.  ``what`` names the format ("student driver").  Nothing is inflated."""
    try:
        found = _directory(fh, fh.seek(0, os.SEEK_END))
    except (OSError, struct.error):
        found = None
    if found is None:
        raise InputError(f"not a readable {what} (not a zip archive)", source=source, hint=hint)
    entries, cd_size = found
    if entries > limits.members or cd_size > limits.members * limits.directory_per_member:
        raise InputError(f"its zip directory lists {entries} members in {size_text(cd_size)}, more than a {what} "
                         f"holds (at most {limits.members})", source=source, hint=hint)
    try:
        fh.seek(0)
        members = zipfile.ZipFile(fh).infolist()
    except (zipfile.BadZipFile, ValueError, EOFError, OSError, NotImplementedError, struct.error) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"not a readable {what} ({reason[:80]})", source=source, hint=hint) from None
    if len(members) > limits.members:
        raise InputError(f"holds {len(members)} zip members, more than a {what} has (at most {limits.members})",
                         source=source, hint=hint)
    total = 0
    for info in members:
        name = info.filename
        if limits.pickle is not None and (name == "data.pkl" or name.endswith("/data.pkl")) \
                and info.file_size > limits.pickle:
            raise InputError(f"zip member {name[:60]!r} inflates to {size_text(info.file_size)}, more than a "
                             f"{what}'s pickle holds (at most {size_text(limits.pickle)})", source=source, hint=hint)
        total += info.file_size
    if limits.total is not None and total > limits.total + limits.header_room * len(members):
        big = max(members, key=lambda i: i.file_size)
        raise InputError(f"its zip members inflate to {size_text(total)} in all (the largest, {big.filename[:60]!r}, "
                         f"to {size_text(big.file_size)}), more than a {what} can sensibly hold (at most "
                         f"{size_text(limits.total)})", source=source, hint=hint)
    fh.seek(0)
    return members


def open_zip(path: str | os.PathLike, limits: ZipLimits, *, what: str, source: str | None = None,
             hint: str | None = None) -> IO[bytes]:
    """``path`` opened for binary reading once :func:`check_zip` accepts it: a regular file (a
    FIFO, device or socket is refused without waiting for a writer), a zip within ``limits``.
    The caller reads it (``zipfile.ZipFile(fh)``, ``torch.load(fh)``) and closes it (``with``)."""
    source = source or str(path)
    fh = open_input(path, what, UNBOUNDED, hint, source=source)  # the zip's own limits come next
    try:
        check_zip(fh, limits, what=what, source=source, hint=hint)
    except BaseException:
        fh.close()
        raise
    return fh



def load_npz(path: str | os.PathLike, *, wanted: Iterable[str] | None = None, required: Iterable[str] = (),
             max_bytes: int | None = 2 * GIB, check: Callable[[ArrayHeader], None] | None = None,
             source: str | None = None, hint: str | None = None) -> dict[str, np.ndarray]:
    """The arrays of the ``.npz`` at ``path``, every header checked first (module docstring).

    ARGUMENTS
    ``wanted``: the array names to read (None: all); others are neither checked nor read.
    ``required``: names that must be present ("array 'x' is missing", with ``hint``).
    ``max_bytes``: the most bytes the read arrays may claim together (None: no limit); every
    member's uncompressed size, from the zip's central directory, counts against it too (plus
    :data:`NPY_HEADER_ROOM` each) before anything is inflated (:func:`open_zip`).
    ``check``: called with each :class:`ArrayHeader` before any data is read; raises InputError.
    ``source``: names the file in errors (default ``str(path)``).

    RETURNED VALUE
    dict name -> array, as stored (no pickles).
    """
    source = source or str(path)
    limits = ZipLimits(total=max_bytes, header_room=NPY_HEADER_ROOM)
    with open_zip(path, limits, what=".npz file", source=source, hint=hint) as fh:
        try:
            archive = zipfile.ZipFile(fh)
        except (zipfile.BadZipFile, ValueError, EOFError, OSError):
            raise InputError("not a readable .npz file (not a zip archive)", source=source, hint=hint) from None
        with archive:
            return _read_npz(archive, wanted, required, max_bytes, check, source, hint)


def _read_npz(archive: zipfile.ZipFile, wanted, required, max_bytes, check, source, hint) -> dict[str, np.ndarray]:
    """:func:`load_npz`'s work on the opened, checked ``archive``."""
    members = {info.filename[:-4]: info for info in archive.infolist() if info.filename.endswith(".npy")}
    for name in required:
        if name not in members:
            raise InputError(f"array {name!r} is missing", source=source, hint=hint)
    keep = None if wanted is None else set(wanted)
    names = [n for n in members if keep is None or n in keep]
    try:
        headers = []
        for name in names:
            with archive.open(members[name]) as fp:
                headers.append(_read_header(fp, name, members[name].file_size, source))
        _check_headers(headers, source, max_bytes, check)
        arrays = {}
        for name in names:
            with archive.open(members[name]) as fp:
                arrays[name] = npformat.read_array(fp, allow_pickle=False)
    except InputError:
        raise
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError, RuntimeError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"not a readable .npz file ({reason})", source=source, hint=hint) from None
    return arrays


def load_npy(path: str | os.PathLike, *, max_bytes: int | None = None,
             check: Callable[[ArrayHeader], None] | None = None, source: str | None = None) -> np.ndarray:
    """The array of the ``.npy`` at ``path``, its header checked first (see :func:`load_npz`)."""
    source = source or str(path)
    try:
        with open_input(path, "numpy file", UNBOUNDED, source=source) as fp:  # a FIFO: refused at once
            size = os.fstat(fp.fileno()).st_size
            header = _read_header(fp, "", size, source)
            _check_headers([header], source, max_bytes, check)
            fp.seek(0)
            return npformat.read_array(fp, allow_pickle=False)
    except InputError:
        raise
    except OSError as exc:
        raise _open_error(exc, source) from None
    except (ValueError, EOFError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"not a readable .npy file ({reason})", source=source) from None

