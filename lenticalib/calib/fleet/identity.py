"""What a panel's result was made from: the fit options and a content hash of the capture folder.

A fleet run (:mod:`.run`) fits a panel again only when its inputs changed: each panel folder
records (``batch.json``, :data:`RECORD_NAME`) the :func:`input_identity` of the capture folder and
the fit options it was fitted with, and the next run compares the identity it computes with the
record (:func:`is_done`).  The identity is decided by content, never by a file's existence or
its modification time: a re-taken photo under the same name, another pattern set or another
``views`` changes it; touching a file or copying the folder does not.

Hashed, in this order (SHA-256): the options (:meth:`FitOptions.to_dict`, canonical JSON), then
for each file of the capture folder that the fit reads -- ``patterns.json``, ``simulation.json``
when present (a virtual panel's record, which goes into the profile's provenance) and every
regular file under ``captures/`` at any depth, sorted by relative path -- its relative path,
its size in bytes and its bytes.  Other files in the folder (pattern PNGs, notes) are not
inputs of the fit and do not count.  The lenticalib version does not count either: a new
version does not refit a done panel (delete the panel's folder, or fit into another output
folder, to refit it).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from pathlib import Path
from typing import Any

from ...core.files.documents import FORMATS, read_document
from ...core.errors import InputError
from ...core.identity import SIMULATION_RECORD
from ...core.pattern_sets import MANIFEST_NAME
from ...core.profile import MAX_VIEWS
from ..routing.fit_pipeline import CAPTURE_FOLDER

RECORD_NAME = "batch.json"  # in each panel folder: how the panel was made (identity, options, outcome)
RECORD = FORMATS["lenticalib.fleet-panel"]
IDENTITY_PREFIX = "sha256:"
STATUSES = ("ok", "untrusted", "failed")  # a panel's verdict: trusted fit, fit that failed a gate, no fit
DONE = ("ok", "untrusted")  # statuses a later run keeps when the identity is the same (failed: tried again)
_CHUNK = 1 << 20


@dataclasses.dataclass(frozen=True)
class FitOptions:
    """The options of every panel's fit, as ``lenticalib fit`` takes them: ``views`` (2..254, None:
    the pattern set's) and ``force`` (write the profile even when the fit fails a quality gate;
    the panel's status stays ``untrusted``)."""

    views: int | None = None
    force: bool = False

    def checked(self) -> "FitOptions":
        """This, once ``views`` is in range; InputError naming ``views`` otherwise."""
        if self.views is not None and not 2 <= self.views <= MAX_VIEWS:
            raise InputError(f"{self.views} views is out of range", source="views",
                             hint=f"use 2..{MAX_VIEWS}, or leave it out to use each pattern set's")
        return self

    def to_dict(self) -> dict[str, Any]:
        return {"views": self.views, "force": bool(self.force)}


def input_files(capture_dir: str | os.PathLike) -> list[Path]:
    """The files of ``capture_dir`` that the fit reads (module docstring), sorted; OSError when
    the folder cannot be listed."""
    folder = Path(capture_dir)
    files = [folder / name for name in (MANIFEST_NAME, SIMULATION_RECORD) if (folder / name).is_file()]
    photos = folder / CAPTURE_FOLDER
    if photos.is_dir():
        for root, dirs, names in os.walk(photos):
            dirs.sort()
            files.extend(Path(root) / n for n in sorted(names) if (Path(root) / n).is_file())
    return files


def input_identity(capture_dir: str | os.PathLike, options: FitOptions) -> str:
    """``sha256:`` + 64 hex digits: the identity of a panel's fit inputs (module docstring).
    InputError naming ``capture_dir`` when it is not a folder or a file cannot be read."""
    folder = Path(capture_dir)
    if not folder.is_dir():
        raise InputError("is not a folder this process can see", source=str(folder),
                         hint="give the capture folder of a panel (a shared path on a cluster)")
    digest = hashlib.sha256(json.dumps(options.to_dict(), sort_keys=True).encode())
    try:
        for path in input_files(folder):
            relative = path.relative_to(folder).as_posix()
            digest.update(f"\0{relative}\0{path.stat().st_size}\0".encode())
            with open(path, "rb") as fh:
                for piece in iter(lambda: fh.read(_CHUNK), b""):
                    digest.update(piece)
    except OSError as exc:
        raise InputError(f"cannot be read ({exc.strerror or exc})", source=str(getattr(exc, "filename", None)
                                                                            or folder),
                         hint="check the file's permissions") from None
    return IDENTITY_PREFIX + digest.hexdigest()


def read_record(panel_dir: str | os.PathLike) -> dict[str, Any] | None:
    """The record of a panel folder (``batch.json``), or None when there is none or it cannot be
    read as one (a later fit replaces it)."""
    path = Path(panel_dir) / RECORD_NAME
    if not path.is_file():
        return None
    try:
        record = read_document(path, RECORD)
    except InputError:
        return None
    return record if isinstance(record, dict) else None


def is_done(record: dict[str, Any] | None, identity: str) -> bool:
    """Whether a panel whose folder holds ``record`` needs no fit for inputs of ``identity``: the
    record was made from the same inputs and options, and the fit ran to a verdict (ok or
    untrusted; a failed panel is tried again, its failure may have been the machine's)."""
    row = record.get("row") if isinstance(record, dict) else None
    return isinstance(row, dict) and record.get("identity") == identity and row.get("status") in DONE
