"""Pattern-set folders: the PNGs a panel shows and their manifest ``patterns.json``.

A pattern folder holds one PNG per pattern and ``patterns.json``, whose ``format`` names the
*kind* of set; ``lenticalib show``, ``capture``, ``fit``, ``crosstalk measure`` and the
simulated camera read every kind through :func:`read_pattern_folder`.  The kinds:

    lenticalib.patterns            calibration patterns (:mod:`lenticalib.calib.patterns.calibration_patterns`)
    lenticalib.crosstalk-patterns  crosstalk patterns (:mod:`lenticalib.calib.patterns.crosstalk_patterns`)

Each kind is found by name in the registry :data:`PATTERN_SETS` (:mod:`.plugins`), so this
module imports none of them; a third-party kind registers in the ``lenticalib.pattern_sets`` entry-point group
with a value ``"module:function"``.  The function takes ``(data, source)``, the parsed manifest
(a dict whose ``format`` is the kind's name) and the manifest's path for messages, and returns
the pattern set or raises InputError naming ``source``.  A pattern set has ``width``,
``height``, ``views``, ``patterns`` (each with ``name``, ``file``, ``group``), ``names``,
``set_id``, ``render(pattern)`` -> uint8 ``(height, width, 3)`` RGB raster and ``to_dict()``
(the manifest).  A manifest equals the ``to_dict()`` of the set it describes, apart from the
keys in :data:`FREE_KEYS` that a person may add.

(The camera board set is not a pattern folder: one raster and ``board.json``,
:mod:`lenticalib.calib.intrinsics.board`; the direction pattern is one PNG without a manifest.)
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Iterable

from .files.atomic import write_text_atomic
from .errors import InputError
from .files.imageio import write_image
from .plugins import Registry
from .files.documents import read_json_file

MANIFEST_NAME = "patterns.json"
FREE_KEYS = ("created", "lenticalib_version", "note")  # manifest keys a person may add
PATTERN_SET_GROUP = "lenticalib.pattern_sets"
PATTERN_SETS = Registry("pattern set format", {
    "lenticalib.patterns": "lenticalib.calib.patterns.calibration_patterns:pattern_set_from_manifest",
    "lenticalib.crosstalk-patterns": "lenticalib.calib.patterns.crosstalk_patterns:crosstalk_set_from_manifest",
}, PATTERN_SET_GROUP)


def read_pattern_folder(directory: str | os.PathLike):
    """The pattern set ``DIR/patterns.json`` describes, of the kind its ``format`` names.

    InputError naming the manifest when it is missing, unreadable, of no known kind, or (the
    kind's own check) of another version or edited.
    """
    path = Path(directory) / MANIFEST_NAME
    data = read_json_file(path, "pattern manifest",
                          "run 'lenticalib patterns' (or 'lenticalib crosstalk patterns') to write the patterns "
                          "and their manifest first")
    source = str(path)
    kind = data.get("format") if isinstance(data, dict) else None
    if kind not in PATTERN_SETS:
        raise InputError("is not a lenticalib pattern manifest", source=source,
                         hint="point at the folder 'lenticalib patterns' wrote")
    return PATTERN_SETS.load(kind, source)(data, source)


def write_patterns(directory: str | os.PathLike, pattern_set, progress: Iterable | None = None) -> Path:
    """Write every pattern as ``DIR/NAME.png`` and the manifest ``DIR/patterns.json``.

    ``pattern_set``: a pattern set of any kind (module docstring).  ``progress``: the set's
    ``patterns``, wrapped (a progress bar), or None.

    Refuses to overwrite a manifest of a *different* pattern set when ``DIR/captures`` holds
    photos (they would no longer match), and any file it did not write (:func:`_check_replaced`).
    Returns the manifest path.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    manifest_path = directory / MANIFEST_NAME
    old = _old_manifest(manifest_path)
    _check_replaced(directory, pattern_set, old)
    if manifest_path.exists() and any((directory / "captures").glob("*")):
        if old.get("set_id") != pattern_set.set_id:
            raise InputError("holds photos of another pattern set", source=str(directory / "captures"),
                             hint="write the patterns into an empty folder")
    items = pattern_set.patterns if progress is None else progress
    for pattern in items:
        write_image(directory / pattern.file, pattern_set.render(pattern))
    write_text_atomic(manifest_path, json.dumps(pattern_set.to_dict(), indent=2) + "\n")
    return manifest_path


def _old_manifest(path: Path) -> dict:
    """The JSON object in the manifest ``path`` as it is; {} where there is none or it is not one."""
    try:  # the one bounded JSON reader: a FIFO, a huge or deeply nested file is "none" too
        old = read_json_file(path, "pattern manifest", "")
    except InputError:
        return {}
    return old if isinstance(old, dict) else {}


def _check_replaced(directory: Path, pattern_set, old: dict) -> None:
    """InputError unless every file ``pattern_set`` would replace in ``directory`` was written there by
    lenticalib as patterns of the same kind (``old``: the folder's manifest as it is, {} for none): a
    manifest of another kind (calibration patterns under crosstalk patterns) would leave its patterns
    without their manifest, and a file of a pattern's name beside no manifest of ours is the user's."""
    kind = pattern_set.to_dict().get("format")
    old_kind = old.get("format")
    if isinstance(old_kind, str) and old_kind.startswith("lenticalib.") and old_kind != kind:
        raise InputError(f"holds other patterns ({old_kind}), which these would leave without their manifest",
                         source=str(directory / MANIFEST_NAME), hint="write these patterns into a folder of their own")
    if old_kind == kind:
        return  # earlier patterns of this kind: replaced as a whole
    names = [MANIFEST_NAME] + [p.file for p in pattern_set.patterns]
    taken = [name for name in names if os.path.lexists(directory / name)]
    if taken:
        raise InputError(f"holds '{taken[0]}'" + (f" and {len(taken) - 1} more of the names these patterns take"
                                                   if len(taken) > 1 else ", a name these patterns take")
                         + ", not written there by lenticalib", source=str(directory),
                         hint="write the patterns into an empty folder (or one of earlier patterns of this kind)")


def manifest_matches(data: dict[str, Any], expected) -> bool:
    """Whether the manifest ``data`` is exactly ``expected.to_dict()``, apart from :data:`FREE_KEYS`."""
    return data == {**expected.to_dict(), **{k: data[k] for k in FREE_KEYS if k in data}}
