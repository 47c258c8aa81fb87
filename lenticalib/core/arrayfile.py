"""Reading numpy ``.npy`` and ``.npz`` files with every header checked before any data is read.

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
"""

from __future__ import annotations

import dataclasses
import math
import os
import zipfile
import zlib
from typing import IO, Callable, Iterable

import numpy as np
from numpy.lib import format as npformat

from .errors import InputError

GIB = 1 << 30


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


def size_text(nbytes: int) -> str:
    """Bytes for people: ``"2.0 GiB"``, ``"3.5 MiB"``, ``"120 bytes"``; absurd sizes in powers of ten."""
    if nbytes >= 1 << 50:
        return f"{nbytes:.3g} bytes"
    for unit, size in (("GiB", GIB), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if nbytes >= size:
            return f"{nbytes / size:.1f} {unit}"
    return f"{nbytes} bytes"


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


def _open_error(exc: OSError, source: str) -> InputError:
    if isinstance(exc, FileNotFoundError):
        return InputError("no such file", source=source, hint="check the path")
    if isinstance(exc, IsADirectoryError):
        return InputError("is a folder, not a numpy file", source=source)
    return InputError(f"cannot read: {exc.strerror or exc}", source=source)


def load_npz(path: str | os.PathLike, *, wanted: Iterable[str] | None = None, required: Iterable[str] = (),
             max_bytes: int | None = 2 * GIB, check: Callable[[ArrayHeader], None] | None = None,
             source: str | None = None, hint: str | None = None) -> dict[str, np.ndarray]:
    """The arrays of the ``.npz`` at ``path``, every header checked first (module docstring).

    ARGUMENTS
    ``wanted``: the array names to read (None: all); others are neither checked nor read.
    ``required``: names that must be present ("array 'x' is missing", with ``hint``).
    ``max_bytes``: the most bytes the read arrays may claim together (None: no limit).
    ``check``: called with each :class:`ArrayHeader` before any data is read; raises InputError.
    ``source``: names the file in errors (default ``str(path)``).

    RETURNED VALUE
    dict name -> array, as stored (no pickles).
    """
    source = source or str(path)
    try:
        archive = zipfile.ZipFile(path)
    except OSError as exc:
        raise _open_error(exc, source) from None
    except (zipfile.BadZipFile, ValueError, EOFError):
        raise InputError("not a readable .npz file (not a zip archive)", source=source, hint=hint) from None
    with archive:
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
        with open(path, "rb") as fp:
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

