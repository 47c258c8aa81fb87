"""Where a command writes: checked before the work starts, folders staged so nothing is left partial.

One rule for every command that writes: nothing the command did not write is ever deleted or
replaced.

- inputs are never outputs: every helper here takes the command's ``inputs`` (a required
  keyword) and refuses an output that is one of them after symbolic links, or the same file by
  device and inode (a hard link), or, for a folder that is replaced, one that holds an input
  (:func:`check_not_an_input`);
- a command creates its own output file or folder, never a missing parent folder (a typo in a
  path must not grow a tree of folders); the parent must exist and be writable (tried, not
  guessed from permission bits: a read-only mount or ``/proc`` is refused as not writable);
- an output *file* must be a new name or an existing regular file.  A symbolic link to a
  regular file is followed (the target file is replaced in its own folder, the link stays, as
  editors do); a folder, a FIFO, a device node, a socket, a dangling link or a link to anything
  but a regular file is refused, and :mod:`lenticalib.core.files.atomic` checks again when it writes;
- an output file gets the umask's mode, or the mode of the file it replaces without its
  set-user/group-id bits;
- an output *folder* must not name an existing file; a link to a folder is followed;
- an existing output folder is replaced (:func:`staged_folder`) only when everything in it, at
  any depth, is something the command itself writes there (``contents``), so a mistyped
  ``--report ~/Documents`` or ``render -o ~/Documents`` is refused, never wiped;
- all checks run before the long work, so a wrong path costs seconds, not a whole fit;
- files are written atomically (:mod:`lenticalib.core.files.atomic`); a folder of results is written into a
  hidden sibling ``.NAME.XXXXXXXX.partial`` and moved into place when complete
  (:func:`staged_folder`), so a failed run leaves an earlier folder intact and no half-written
  one.  What a killed run leaves (``.NAME.*.partial`` folders, ``.NAME.*.tmp`` files) is removed
  by the next run writing the same NAME, unless a running process still holds it.  ``.NAME.*.old``
  copies are kept on purpose: after a crash they may hold the only earlier results;
- results that a library function writes in place (several files and folders at fixed names)
  are guarded by :func:`restored_on_failure`: the earlier ones are copied aside first and put
  back if the run fails, so a failed run leaves the earlier results and nothing of its own.

Every refusal is an :class:`~lenticalib.core.errors.InputError` naming the path and what to do.
"""

from __future__ import annotations

import contextlib
import fnmatch
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from .atomic import current_umask, hold, kind_of, output_target, remove_leftovers
from ..errors import InputError


Inputs = Iterable[str | os.PathLike | None]
"""What a command reads, as the output helpers take it (``inputs=``): files, and folders read whole;
None entries (an optional input not given) are skipped."""


def _identity(path: str | os.PathLike) -> tuple[str, tuple[int, int] | None]:
    """(the path after symbolic links, (st_dev, st_ino) of what it names or None when nothing)."""
    real = os.path.realpath(path)
    try:
        st = os.stat(real)
    except OSError:
        return real, None
    return real, (st.st_dev, st.st_ino)


def _inside(path: str, folder: str) -> bool:
    """Whether the resolved ``path`` lies strictly inside the resolved ``folder``."""
    return path != folder and os.path.commonpath([path, folder]) == folder


def _same_file_below(folder: str, key: tuple[int, int]) -> str | None:
    """A path under ``folder`` (any depth, links not followed) that is the file ``key``, or None."""
    for root, _dirs, files in os.walk(folder):
        for name in files:
            with contextlib.suppress(OSError):
                st = os.lstat(os.path.join(root, name))
                if (st.st_dev, st.st_ino) == key:
                    return os.path.join(root, name)
    return None


def _check_parent(target: Path, what: str) -> None:
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.exists():
        raise InputError(f"the folder for the {what} does not exist", source=str(parent),
                         hint=f"create it first, or choose another path for the {what}")
    if not parent.is_dir():
        raise InputError(f"is not a folder, so the {what} cannot go in it", source=str(parent),
                         hint=f"choose another path for the {what}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"folder is not writable, so the {what} cannot be written", source=str(parent),
                         hint=f"choose a writable folder for the {what}")
    try:  # permission bits do not tell about read-only mounts, /proc, or root
        fd, probe = tempfile.mkstemp(prefix=".lenticalib-probe.", dir=parent)  # no output's leftover name
    except OSError as exc:
        raise InputError(f"folder is not writable ({exc.strerror}), so the {what} cannot be written",
                         source=str(parent), hint=f"choose a writable folder for the {what}") from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)


def check_output_file(path: str | os.PathLike, what: str = "output file", example: str = "out", *,
                      inputs: Inputs) -> Path:
    """Refuse, before any work, an output file path that cannot be written; return it as a Path.

    ``inputs``: everything the command reads (:data:`Inputs`, ``()`` for nothing); an output that
    is one of them is refused first (:func:`check_not_an_input`).

    A new name or an existing regular file is fine (it is replaced atomically at the end), as is
    a symbolic link to a regular file (the target is replaced); a folder, a FIFO, a device node,
    a socket, a dangling link, a read-only file or a missing or unwritable parent folder (the
    link target's folder for a link) is not (module docstring).  ``example``: a file name the
    hint suggests inside a folder given by mistake, with a suffix the command takes (the default,
    ``"out"``, suggests none).
    """
    check_not_an_input(path, inputs, what, example)
    target = Path(path)
    if target.is_dir():
        raise InputError(f"is a folder, not a file name for the {what}", source=str(target),
                         hint=f"give a file name for the {what}"
                         + ("" if example == "out" else f", e.g. {target / example}"))
    real = output_target(target, what)
    if real.exists() and not os.access(real, os.W_OK):
        raise InputError(f"exists and is read-only, so the {what} cannot replace it", source=str(target),
                         hint="choose another path or make the file writable")
    _check_parent(real, what)
    return target


def check_not_an_input(path: str | os.PathLike, inputs: Inputs, what: str, example: str = "out", *,
                       folder: bool = False, replaced: bool = True) -> None:
    """Refuse, before any work, an output ``path`` that would replace or delete one of the
    command's own ``inputs`` (:data:`Inputs`): writing it would destroy what the command reads.

    The output is refused when it is an input after symbolic links, or the same file by
    (st_dev, st_ino) (a hard link, a bind mount), or it exists inside an input folder (a folder
    input is read whole).  An output *folder* (``folder``) that is ``replaced`` as a whole
    (:func:`staged_folder`) is also refused when an input lies inside it, at any depth (by path
    or, for a hard-linked input, by inode); one written in place at fixed names
    (:func:`restored_on_failure`) only when it is an input.  The output helpers
    (:func:`check_output_file`, :func:`check_output_folder`, :func:`staged_folder`,
    :func:`lenticalib.core.files.imageio.check_image_output`) call this with their required
    ``inputs``.  ``example``: a name the hint suggests.
    """
    real, key = _identity(path)
    exists = key is not None
    suggested = "" if example == "out" else f", e.g. {example}"  # no placeholder name in a hint
    own = f"give the {what} a path of its own{suggested}"
    for item in inputs:
        if item is None:
            continue
        item_real, item_key = _identity(item)
        named = "" if os.path.abspath(item) == os.path.abspath(path) else f" ({item})"
        if item_real == real or (exists and item_key == key):
            raise InputError(f"is one of this command's inputs{named}: the {what} would replace it",
                             source=str(path), hint=own)
        if exists and os.path.isdir(item_real) and (_inside(real, item_real) or (
                not folder and os.path.isfile(real) and os.stat(real).st_nlink > 1
                and _same_file_below(item_real, key))):
            raise InputError(f"is one of this command's inputs (in {item}, which it reads whole): the {what} would "
                             "replace it", source=str(path), hint=f"give the {what} a path outside {item}")
        if not (folder and replaced and exists):
            continue
        if _inside(item_real, real) or (item_key is not None and os.path.isfile(item_real)
                                        and os.stat(item_real).st_nlink > 1 and _same_file_below(real, item_key)):
            raise InputError(f"holds {item}, one of this command's inputs (or a hard link to it): replacing the "
                             f"{what} would delete it", source=str(path),
                             hint=f"give the {what} a folder of its own{suggested}")


def check_output_folder(path: str | os.PathLike, what: str = "output folder",
                        contents: Iterable[str] | None = None, *, inputs: Inputs) -> Path:
    """Refuse, before any work, an output folder that cannot be written; return it as a Path.

    ``inputs``: everything the command reads (:data:`Inputs`, ``()`` for nothing): the folder may
    not be one of them, nor, when it is replaced as a whole (``contents`` given, as for
    :func:`staged_folder`), hold one (:func:`check_not_an_input`).

    The folder may exist (it must then be a writable folder) or not (its parent must exist and
    be writable); a symbolic link to a folder is followed (the folder it names is returned), a
    dangling one refused.  ``contents``: when given, what an existing folder may hold for the
    command to replace it (what the command writes there), as patterns matched one path part
    at a time (``fnmatch``: ``"frame-[0-9]*.png"``, ``"print/board.json"``; a subfolder's
    entries need patterns of their own); a folder holding anything else, at any depth, is
    refused, naming the first such entry.
    """
    check_not_an_input(path, inputs, what, folder=True, replaced=contents is not None)
    target = Path(path)
    if target.is_symlink():
        real = Path(os.path.realpath(target))
        if not real.exists():
            raise InputError(f"is a symbolic link to {real}, which does not exist", source=str(target),
                             hint=f"remove the link or choose another folder for the {what}")
        target = real
    if target.exists():
        if not target.is_dir():
            kind = kind_of(target)
            raise InputError(f"is {kind}, not a folder for the {what}", source=str(target),
                             hint=f"choose a folder path for the {what}: a new name or an existing folder")
        if not os.access(target, os.W_OK | os.X_OK):
            raise InputError(f"is not writable, so the {what} cannot be written", source=str(target),
                             hint=f"choose a writable folder for the {what}")
        if contents is not None:
            _refuse_foreign(target, what, tuple(contents))
    _check_parent(target, what)
    return target


def _owned(parts: tuple[str, ...], patterns: tuple[str, ...]) -> bool:
    """Whether the relative path ``parts`` matches one of ``patterns``, part by part."""
    for pattern in patterns:
        pattern_parts = pattern.split("/")
        if len(pattern_parts) == len(parts) and all(fnmatch.fnmatchcase(name, p)
                                                    for name, p in zip(parts, pattern_parts)):
            return True
    return False


def _refuse_foreign(folder: Path, what: str, contents: tuple[str, ...]) -> None:
    """InputError naming the first entry under ``folder`` (any depth) not matched by ``contents``."""
    for root, dirs, files in os.walk(folder):
        base = Path(root).relative_to(folder).parts
        for name in sorted(dirs + files):
            if not _owned(base + (name,), contents):
                entry = "/".join(base + (name,))
                raise InputError(f"holds {entry!r}, which is not part of a {what}, so the folder will not be "
                                 "replaced", source=str(folder),
                                 hint=f"choose a new or empty folder for the {what}")


@contextlib.contextmanager
def staged_folder(path: str | os.PathLike, what: str, contents: Iterable[str], *, inputs: Inputs) -> Iterator[Path]:
    """Yield a fresh hidden sibling of ``path`` to write into; on success it replaces ``path``.

    ``inputs``: everything the command reads (:data:`Inputs`): ``path`` may neither be nor hold
    one of them (:func:`check_not_an_input`), checked before the body runs and before the swap.

    ``contents``: what the command writes into the folder (patterns, :func:`check_output_folder`);
    an existing ``path`` holding anything else is refused before the body runs, and again
    before it is replaced (a file put there meanwhile is never deleted).  The staging folder
    ``.NAME.XXXXXXXX.partial`` is locked while written; those of killed earlier runs are removed
    first (:func:`lenticalib.core.files.atomic.remove_leftovers`).  On an exception the staging folder is
    removed and ``path`` (if it existed) is untouched.  On success an existing ``path`` is
    renamed aside, the staged folder renamed into place, and the old one removed, so at every
    moment ``path`` is either the old folder or the complete new one (a crash between the two
    renames leaves the old folder under ``.NAME.*.old``, never a partial one at ``path``).
    """
    contents, inputs = tuple(contents), tuple(inputs)
    target = check_output_folder(path, what, contents, inputs=inputs)
    parent = target.parent if str(target.parent) else Path(".")
    remove_leftovers(target)
    stage = None
    try:
        stage = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".partial", dir=parent))
        lock = hold(stage)
    except OSError as exc:
        if stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
        raise InputError(f"folder is not writable ({exc.strerror}), so the {what} cannot be written",
                         source=str(parent), hint=f"choose a writable folder for the {what}") from None
    try:
        yield stage
        os.chmod(stage, 0o777 & ~current_umask())
        old = None
        if target.exists():
            check_output_folder(target, what, contents, inputs=inputs)
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=parent))
            os.rmdir(old)
            os.replace(target, old)
        try:
            os.replace(stage, target)
        except OSError:
            if old is not None:
                os.replace(old, target)  # the earlier folder back in place
            raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        os.close(lock)
    except BaseException as exc:
        shutil.rmtree(stage, ignore_errors=True)
        os.close(lock)
        if isinstance(exc, OSError):
            raise InputError(f"cannot write the {what}: {exc.strerror}", source=str(target),
                             hint="check free space and permissions") from None
        raise


def _in_place_target(path: Path, what: str) -> Path:
    """What writing in place at ``path`` changes: the path, or the folder or regular file a link
    names; InputError for anything else (a FIFO or device is never copied, replaced or removed)."""
    if path.is_dir():
        return Path(os.path.realpath(path)) if path.is_symlink() else path
    return output_target(path, what)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    elif os.path.lexists(path):
        path.unlink()


@contextlib.contextmanager
def restored_on_failure(paths: Iterable[str | os.PathLike], what: str = "results") -> Iterator[None]:
    """Guard results that a library function writes in place at ``paths`` (files or folders).

    Every existing path is first copied to a hidden sibling ``.NAME.*.old`` (the body still sees
    and may check or rewrite the original).  On success the copies are removed.  On any
    exception (Ctrl-C included) each path is put back as it was, from its copy, or removed when
    it did not exist, so the caller sees the earlier results and nothing of the failed run.  (A
    process killed outright leaves the earlier results in the ``.NAME.*.old`` copies.)  The
    paths' parent folders must exist; check them first (:func:`check_output_folder`).
    """
    targets = [_in_place_target(Path(p), what) for p in paths]
    copies: dict[Path, Path] = {}
    try:
        for target in targets:
            if os.path.lexists(target):
                parent = target.parent if str(target.parent) else Path(".")
                copy = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=parent))
                copies[target] = copy
                os.rmdir(copy)
                if target.is_dir():
                    shutil.copytree(target, copy, symlinks=True)
                else:
                    shutil.copy2(target, copy, follow_symlinks=False)
    except OSError as exc:
        for copy in copies.values():
            _remove(copy)
        raise InputError(f"cannot keep a copy of the earlier {what}: {exc.strerror}",
                         source=str(exc.filename or targets[0]),
                         hint="check free space and the folder's permissions") from None
    try:
        yield
    except BaseException:
        for target in targets:
            _remove(target)
            if target in copies:
                os.replace(copies[target], target)
        raise
    for copy in copies.values():
        _remove(copy)
