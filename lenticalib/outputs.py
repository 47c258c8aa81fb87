"""Where a command writes: checked before the work starts, folders staged so nothing is left partial.

One rule for every command that writes:

- a command creates its own output file or folder, never a missing parent folder (a typo in a
  path must not grow a tree of folders); the parent must exist and be writable;
- an output *file* must not name an existing folder, an output *folder* must not name an
  existing file;
- an existing output folder is replaced only when it holds nothing but what the command itself
  writes there (``contents``), so a mistyped ``--report ~/Documents`` cannot wipe a folder;
- all checks run before the long work, so a wrong path costs seconds, not a whole fit;
- files are written atomically (:mod:`lenticalib.atomic`); a folder of results is written into a
  hidden sibling and moved into place when complete (:func:`staged_folder`), so a failed run
  leaves an earlier folder intact and no half-written one;
- results that a library function writes in place (several files and folders at fixed names)
  are guarded by :func:`restored_on_failure`: the earlier ones are copied aside first and put
  back if the run fails, so a failed run leaves the earlier results and nothing of its own.

Every refusal is an :class:`~lenticalib.errors.InputError` naming the path and what to do.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from .errors import InputError


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


def check_output_file(path: str | os.PathLike, what: str = "output file", example: str = "out") -> Path:
    """Refuse, before any work, an output file path that cannot be written; return it as a Path.

    An existing file is fine (it is replaced atomically at the end); an existing folder, a
    missing or read-only parent folder is not.  ``example``: a file name the hint suggests
    inside a folder given by mistake.
    """
    target = Path(path)
    if target.is_dir():
        raise InputError(f"is a folder, not a file name for the {what}", source=str(target),
                         hint=f"give a file name for the {what}, e.g. {target / example}")
    if target.exists() and not os.access(target, os.W_OK):
        raise InputError(f"exists and is read-only, so the {what} cannot replace it", source=str(target),
                         hint="choose another path or make the file writable")
    _check_parent(target, what)
    return target


def check_output_folder(path: str | os.PathLike, what: str = "output folder",
                        contents: Iterable[str] | None = None) -> Path:
    """Refuse, before any work, an output folder that cannot be written; return it as a Path.

    The folder may exist (it must then be a writable folder) or not (its parent must exist and
    be writable).  ``contents``: when given, the names an existing folder may hold for the
    command to replace it (what the command writes there); a folder holding anything else is
    refused, naming the first such entry.
    """
    target = Path(path)
    if target.exists():
        if not target.is_dir():
            raise InputError(f"is a file, not a folder for the {what}", source=str(target),
                             hint=f"choose a folder path for the {what}, or remove the file")
        if not os.access(target, os.W_OK | os.X_OK):
            raise InputError(f"is not writable, so the {what} cannot be written", source=str(target),
                             hint=f"choose a writable folder for the {what}")
        if contents is not None:
            allowed = set(contents)
            foreign = sorted(p.name for p in target.iterdir() if p.name not in allowed)
            if foreign:
                raise InputError(f"holds {foreign[0]!r}, which is not part of a {what}, so it will not be "
                                 "replaced", source=str(target),
                                 hint=f"choose a new or empty folder for the {what}")
    _check_parent(target, what)
    return target


@contextlib.contextmanager
def staged_folder(path: str | os.PathLike, what: str = "output folder",
                  contents: Iterable[str] | None = None) -> Iterator[Path]:
    """Yield a fresh hidden sibling of ``path`` to write into; on success it replaces ``path``.

    On an exception the staging folder is removed and ``path`` (if it existed) is untouched.  On
    success an existing ``path`` is renamed aside, the staged folder renamed into place, and the
    old one removed, so at every moment ``path`` is either the old folder or the complete new one
    (a crash between the two renames leaves the old folder under ``.NAME.old-*``, never a partial
    one at ``path``).
    """
    target = check_output_folder(path, what, contents)
    parent = target.parent if str(target.parent) else Path(".")
    try:
        stage = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".partial", dir=parent))
    except OSError as exc:
        raise InputError(f"cannot write here: {exc.strerror}", source=str(parent),
                         hint=f"choose a writable folder for the {what}") from None
    try:
        yield stage
        os.chmod(stage, 0o777 & ~_umask())
        old = None
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=parent))
            os.rmdir(old)
            os.replace(target, old)
        os.replace(stage, target)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException as exc:
        shutil.rmtree(stage, ignore_errors=True)
        if isinstance(exc, OSError):
            raise InputError(f"cannot write the {what}: {exc.strerror}", source=str(target),
                             hint="check free space and permissions") from None
        raise


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
    targets = [Path(p) for p in paths]
    copies: dict[Path, Path] = {}
    try:
        for target in targets:
            if os.path.lexists(target):
                parent = target.parent if str(target.parent) else Path(".")
                copy = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=parent))
                copies[target] = copy
                if target.is_dir() and not target.is_symlink():
                    os.rmdir(copy)
                    shutil.copytree(target, copy, symlinks=True)
                else:
                    os.rmdir(copy)
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


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
