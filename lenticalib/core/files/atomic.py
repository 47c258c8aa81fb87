"""Atomic file output: a reader sees the old file or the new one, never a torn one.

What an output path may name (checked before the work by
:func:`lenticalib.core.files.outputs.check_output_file`, and again here when the file is written):

- nothing yet, in an existing writable folder: the file is created with the umask's mode;
- a regular file: it is replaced by the new one, which keeps its mode (set-user/group-id bits
  dropped) and, where the writer may set it, its owner;
- a symbolic link to a regular file: the link is followed, as editors do: the *target* file is
  replaced (in the target's folder) and the link stays as it was;
- anything else -- a folder, a FIFO, a device node, a socket, a dangling link or a link to any
  of these -- is refused with an :class:`~lenticalib.core.errors.InputError`: it is never replaced
  and never written into.

The new content goes to a hidden temporary file ``.NAME.XXXXXXXX.tmp`` beside the target,
locked (``flock``) while it is written, and is moved over the target with ``os.replace``.  A
process killed mid-write leaves that file behind; the next write of the same NAME removes such
leftovers (:func:`remove_leftovers`: only names of that exact pattern that no process holds).
"""

from __future__ import annotations

import fcntl
import os
import re
import shutil
import stat
import tempfile
from pathlib import Path

from ..errors import InputError

_KINDS = {stat.S_IFIFO: "a named pipe (FIFO)", stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
          stat.S_IFSOCK: "a socket", stat.S_IFDIR: "a folder"}


def _kind(mode: int) -> str:
    return _KINDS.get(stat.S_IFMT(mode), "not a regular file")


def kind_of(path: str | os.PathLike) -> str:
    """What ``path`` is, in words ("a file", "a named pipe (FIFO)", "a folder", ...), for messages."""
    mode = os.stat(path).st_mode
    return "a file" if stat.S_ISREG(mode) else _kind(mode)


def output_target(path: str | os.PathLike, what: str = "output file", follow_links: bool = True) -> Path:
    """The regular file that writing ``path`` creates or replaces: ``path`` itself, or the regular
    file a symbolic link ``path`` points to (with ``follow_links=False``: the link itself, which
    the write then replaces, whatever it points to -- for files in the program's own folders).

    Raises InputError when ``path`` is (or links to) anything but a regular file, or is a dangling
    link.  A path whose folder is missing is returned as is (the write or the folder check says so).
    """
    target = Path(path)
    try:
        st = os.lstat(target)
    except OSError:
        return target
    if stat.S_ISLNK(st.st_mode) and not follow_links:
        return target
    if stat.S_ISLNK(st.st_mode):
        real = Path(os.path.realpath(target))
        try:
            st = os.stat(real)
        except OSError:
            raise InputError(f"is a symbolic link to {real}, which does not exist, so the {what} will not be "
                             "written through it", source=str(target),
                             hint="remove the link or choose another path") from None
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"is a symbolic link to {real}, which is {_kind(st.st_mode)}, not a regular file, so the "
                             f"{what} will not replace it", source=str(target), hint="choose another path")
        return real
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"is {_kind(st.st_mode)}, not a regular file, so the {what} will not replace it",
                         source=str(target), hint=f"choose a file path for the {what}")
    return target


def current_umask() -> int:
    """The process's umask (read by setting it and setting it back)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def leftover_pattern(name: str) -> re.Pattern:
    """What an interrupted write of ``name`` leaves beside it: ``.NAME.XXXXXXXX.tmp`` (with an
    optional extension, e.g. ``.tmp.mkv``) files and ``.NAME.XXXXXXXX.partial`` staged folders."""
    return re.compile(rf"\.{re.escape(name)}\.[a-z0-9_]{{8}}\.(tmp(\.[A-Za-z0-9]+)?|partial)")


_STAGING = re.compile(r"\..+\.[a-z0-9_]{8}\.partial")


def remove_leftovers(path: str | os.PathLike) -> list[Path]:
    """Remove what killed earlier writes of ``path`` left in its folder; return what was removed.

    Only entries whose name fits :func:`leftover_pattern` for ``path``'s name, that are plain
    files or folders (never links, FIFOs or devices) and that no process holds locked (a write
    in progress does) are removed; nothing else is ever touched.  Inside a staging folder
    (``.NAME.XXXXXXXX.partial``, fresh, and removed whole if its run is killed) nothing is looked
    for, so writing many files there does not read the folder again for each.
    """
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    if _STAGING.fullmatch(Path(os.path.abspath(folder)).name):
        return []
    pattern = leftover_pattern(target.name)
    removed = []
    try:
        entries = [e for e in os.scandir(folder) if pattern.fullmatch(e.name)]
    except OSError:
        return removed
    for entry in entries:
        try:
            st = os.lstat(entry.path)
        except OSError:
            continue
        is_dir = stat.S_ISDIR(st.st_mode)
        if not (is_dir or stat.S_ISREG(st.st_mode)):
            continue
        try:
            fd = os.open(entry.path, os.O_RDONLY | os.O_NOFOLLOW | (os.O_DIRECTORY if is_dir else 0))
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue  # in use by a running write
        try:
            if is_dir:
                shutil.rmtree(entry.path, ignore_errors=True)
            else:
                os.unlink(entry.path)
            removed.append(Path(entry.path))
        except OSError:
            pass
        finally:
            os.close(fd)
    return removed


def hold(path: str | os.PathLike) -> int:
    """Open ``path`` (a file or a folder) and lock it, marking it in use; return the descriptor
    (closing it releases the lock, as does the end of the process)."""
    flags = os.O_RDONLY | (os.O_DIRECTORY if os.path.isdir(path) else 0)
    fd = os.open(path, flags)
    fcntl.flock(fd, fcntl.LOCK_EX)
    return fd


class PendingFile:
    """A temporary file beside an output, moved over it atomically by :meth:`commit`.

    ``PendingFile(path, what, suffix)``: checks ``path`` (:func:`output_target`), removes the
    leftovers of earlier killed writes, creates ``.NAME.XXXXXXXX.tmp`` + ``suffix`` (``suffix``
    for writers that go by the extension, e.g. ``".mkv"``) in the target's folder with the
    mode the output will have, and locks it.  ``.path`` is the temporary file to write,
    ``.target`` the file it will replace.  :meth:`commit` makes the data durable, checks the
    target again and replaces it; :meth:`discard` removes the temporary file.  As a context
    manager: commit on success, discard on an exception.
    """

    def __init__(self, path: str | os.PathLike, what: str = "output file", suffix: str = "",
                 follow_links: bool = True):
        self.what = what
        self.follow_links = follow_links
        self.target = output_target(path, what, follow_links)
        folder = self.target.parent if str(self.target.parent) else Path(".")
        if not folder.is_dir():
            raise InputError("output folder does not exist", source=str(folder),
                             hint="create it or choose another output path")
        remove_leftovers(self.target)
        try:
            self._fd, tmp = tempfile.mkstemp(prefix=f".{self.target.name}.", suffix=f".tmp{suffix}", dir=folder)
        except OSError as exc:
            raise InputError(f"folder is not writable ({exc.strerror}), so the {what} cannot be written",
                             source=str(folder), hint=f"choose a writable folder for the {what}") from None
        self.path = Path(tmp)
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX)
            try:
                st = os.stat(self.target)
                if os.path.islink(self.target):  # a link replaced, not followed: nothing to keep of it
                    raise FileNotFoundError
            except FileNotFoundError:
                os.fchmod(self._fd, 0o666 & ~current_umask())
            else:
                if (st.st_uid, st.st_gid) != (os.geteuid(), os.getegid()):
                    try:
                        os.fchown(self._fd, st.st_uid, st.st_gid)
                    except OSError:
                        pass  # only root may give a file away: the new file is the writer's
                os.fchmod(self._fd, stat.S_IMODE(st.st_mode) & 0o777)  # never set-id bits
        except BaseException:
            self.discard()
            raise

    def write(self, data: bytes) -> None:
        """Append ``data`` to the temporary file."""
        view = memoryview(data)
        while view:
            view = view[os.write(self._fd, view):]

    def commit(self) -> Path:
        """Flush the data to disk and move it over the target; return the target."""
        try:
            os.fsync(self._fd)
            try:
                st = os.lstat(self.target)
            except FileNotFoundError:
                pass
            else:
                replaceable = stat.S_ISREG(st.st_mode) or (stat.S_ISLNK(st.st_mode) and not self.follow_links)
                if not replaceable:  # changed since the check: never replaced
                    raise InputError(f"is now {_kind(st.st_mode)}, not a regular file, so the {self.what} will "
                                     "not replace it", source=str(self.target),
                                     hint=f"choose a file path for the {self.what}")
            os.replace(self.path, self.target)
        except BaseException as exc:
            self.discard()
            if isinstance(exc, OSError):
                raise InputError(f"cannot write the {self.what}: {exc.strerror}", source=str(self.target),
                                 hint="check free space and permissions") from None
            raise
        os.close(self._fd)
        self._fd = -1
        return self.target

    def discard(self) -> None:
        """Remove the temporary file (nothing is replaced)."""
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def __enter__(self) -> PendingFile:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()


def write_bytes_atomic(path: str | os.PathLike, data: bytes, what: str = "output file",
                       follow_links: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically (:class:`PendingFile`); return the file written.

    On any failure the temporary file is removed and an existing ``path`` is left as it was.
    Raises InputError when the folder does not exist or is not writable, or ``path`` is not a
    regular file (module docstring).  Returns ``path`` as given (a link's target is written).
    """
    with PendingFile(path, what, follow_links=follow_links) as pending:
        try:
            pending.write(data)
        except OSError as exc:
            raise InputError(f"cannot write the {what}: {exc.strerror}", source=str(pending.target),
                             hint="check free space and permissions") from None
    return Path(path)


def write_text_atomic(path: str | os.PathLike, text: str, what: str = "output file",
                      follow_links: bool = True) -> Path:
    """UTF-8 text flavour of :func:`write_bytes_atomic`."""
    return write_bytes_atomic(path, text.encode("utf-8"), what, follow_links)
