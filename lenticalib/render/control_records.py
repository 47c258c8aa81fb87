"""Control records: one JSON object giving a control vector, as control files and live streams carry it.

    {"t": 0.0, "controls": [D numbers]}                   the whole vector
    {"t": 0.0, "jaw": [0.1, 0, 0], "head": [0, 0.2, 0]}   by group: every group given has its full
                                                          size (a size-1 group may be a bare number),
                                                          groups not given are 0

``t`` is in seconds; every value must be a finite number.  Files need ``t`` (:mod:`.controls`),
live streams may leave it out (:mod:`.control_streams`).  A bad record is one InputError naming
its source, with the expected dimension and layout.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from ..errors import InputError
from .rig import ControlLayout


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def parse_control_record(obj: Any, layout: ControlLayout, source: str, *, require_t: bool = True
                         ) -> tuple[float | None, np.ndarray]:
    """One JSON control object (module docstring) -> (t or None, (D,) float32); InputError naming ``source``."""
    hint = f"expected {layout.dim} values: {layout.describe()}"
    if not isinstance(obj, dict):
        raise InputError(f"expected a JSON object, got {type(obj).__name__}", source=source,
                         hint='e.g. {"t": 0.0, "controls": [...]} or {"t": 0.0, "jaw": [0.1, 0, 0]}')
    t = obj.get("t")
    if t is None:
        if require_t:
            raise InputError("no time 't'", source=source, hint="give each line a time in seconds")
    elif not _number(t):
        raise InputError(f"time 't' is {t!r}, expected a finite number of seconds", source=source)
    if "controls" in obj:
        extra = sorted(set(obj) - {"t", "controls"})
        if extra:
            raise InputError(f"mixes 'controls' with other keys {extra}", source=source,
                             hint="give either the whole vector as 'controls' or group keys")
        values = obj["controls"]
        if not isinstance(values, list):
            raise InputError(f"'controls' is {type(values).__name__}, expected a list of numbers", source=source,
                             hint=hint)
        if len(values) != layout.dim:
            raise InputError(f"'controls' has {len(values)} values, expected {layout.dim}", source=source,
                             hint=f"layout: {layout.describe()}")
        bad = [i for i, v in enumerate(values) if not _number(v)]
        if bad:
            raise InputError(f"'controls'[{bad[0]}] is {values[bad[0]]!r}, expected a finite number", source=source)
        return (None if t is None else float(t)), np.asarray(values, dtype=np.float32)
    groups = [k for k in obj if k != "t"]
    if not groups:
        raise InputError("no controls", source=source, hint="give 'controls' or group keys: " + layout.describe())
    vec = np.zeros(layout.dim, dtype=np.float32)
    for name in groups:
        if name not in layout:
            raise InputError(f"unknown control group {name!r}", source=source, hint=f"layout: {layout.describe()}")
        size = layout.size(name)
        values = obj[name]
        if size == 1 and _number(values):
            values = [values]
        if not isinstance(values, list) or len(values) != size:
            got = f"{len(values)} values" if isinstance(values, list) else type(values).__name__
            raise InputError(f"group {name!r} has {got}, expected {size}", source=source,
                             hint=f"layout: {layout.describe()}")
        bad = [i for i, v in enumerate(values) if not _number(v)]
        if bad:
            raise InputError(f"{name}[{bad[0]}] is {values[bad[0]]!r}, expected a finite number", source=source)
        vec[layout.slice(name)] = values
    return (None if t is None else float(t)), vec


def parse_control_line(line: str, layout: ControlLayout, source: str, *, require_t: bool = True
                       ) -> tuple[float | None, np.ndarray]:
    """One JSON line -> (t or None, (D,) float32); InputError naming ``source``."""
    try:
        obj = json.loads(line)
    except json.JSONDecodeError as exc:
        raise InputError(f"not JSON: {exc.msg} at column {exc.colno}", source=source) from None
    return parse_control_record(obj, layout, source, require_t=require_t)
