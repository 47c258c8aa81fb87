"""Control records: one JSON object giving a control vector, as control files and live streams carry it.

    {"t": 0.0, "controls": [D numbers]}                   the whole vector
    {"t": 0.0, "jaw": [0.1, 0, 0], "head": [0, 0.2, 0]}   by group: every group given has its full
                                                          size (a size-1 group may be a bare number),
                                                          groups not given are 0

``t`` is in seconds, a finite float64; every control value must be finite in the dtype it is used
in, float32 (``|v| <= FLOAT32_MAX``, about 3.4e38: 1e39 is refused, not turned into inf).  Files need
``t`` (:mod:`.files`), live streams may leave it out (:mod:`.streams`).  A bad record --
not JSON, nested too deep, an integer of thousands of digits, a wrong type or size, a value out of
range -- is one InputError naming its source, with the expected dimension and layout; quoted
values are shortened to :data:`SHOW_CHARS` characters.  :func:`write_controls_csv` writes timed
control vectors as the CSV control file :func:`~.files.load_controls` reads.
"""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ...core.files.atomic import write_text_atomic
from ...core.errors import InputError
from ...core.files.fields import is_finite_number, short_repr
from ..avatar.rig import ControlLayout


FLOAT32_MAX = float(np.finfo(np.float32).max)  # the largest control value (controls are float32)
FLOAT64_MAX = sys.float_info.max                # the largest time (times are float64)
SHOW_CHARS = 40                                  # a bad value or key is quoted up to about this many characters


def within_range(value: Any, limit: float = FLOAT32_MAX) -> bool:
    """A JSON number (not a bool) with ``|value| <= limit``: finite once converted (no OverflowError for huge ints)."""
    return is_finite_number(value) and abs(value) <= limit


def show(value: Any) -> str:
    """``repr(value)`` shortened for one-line messages about hostile input (never raises)."""
    return short_repr(value, SHOW_CHARS)


def number_problem(where: str, value: Any, limit: float = FLOAT32_MAX) -> str:
    """The message for a value that fails ``within_range(value, limit)``: not finite, or out of range."""
    if within_range(value, math.inf):
        dtype = "float32" if limit == FLOAT32_MAX else "float64"
        return f"{where} is {show(value)}, out of range: {dtype} holds |v| <= {limit:.4g}"
    return f"{where} is {show(value)}, expected a finite number"


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
    elif not within_range(t, FLOAT64_MAX):
        raise InputError(number_problem("time 't'", t, FLOAT64_MAX), source=source)
    if "controls" in obj:
        extra = sorted(set(obj) - {"t", "controls"})
        if extra:
            raise InputError(f"mixes 'controls' with other keys {show(extra)}", source=source,
                             hint="give either the whole vector as 'controls' or group keys")
        values = obj["controls"]
        if not isinstance(values, list):
            raise InputError(f"'controls' is {type(values).__name__}, expected a list of numbers", source=source,
                             hint=hint)
        if len(values) != layout.dim:
            raise InputError(f"'controls' has {len(values)} values, expected {layout.dim}", source=source,
                             hint=f"layout: {layout.describe()}")
        bad = [i for i, v in enumerate(values) if not within_range(v)]
        if bad:
            raise InputError(number_problem(f"'controls'[{bad[0]}]", values[bad[0]]), source=source)
        return (None if t is None else float(t)), np.asarray(values, dtype=np.float32)
    groups = [k for k in obj if k != "t"]
    if not groups:
        raise InputError("no controls", source=source, hint="give 'controls' or group keys: " + layout.describe())
    vec = np.zeros(layout.dim, dtype=np.float32)
    for name in groups:
        if name not in layout:
            raise InputError(f"unknown control group {show(name)}", source=source, hint=f"layout: {layout.describe()}")
        size = layout.size(name)
        values = obj[name]
        if size == 1 and within_range(values):
            values = [values]
        if not isinstance(values, list) or len(values) != size:
            got = f"{len(values)} values" if isinstance(values, list) else type(values).__name__
            raise InputError(f"group {name!r} has {got}, expected {size}", source=source,
                             hint=f"layout: {layout.describe()}")
        bad = [i for i, v in enumerate(values) if not within_range(v)]
        if bad:
            raise InputError(number_problem(f"{name}[{bad[0]}]", values[bad[0]]), source=source)
        vec[layout.slice(name)] = values
    return (None if t is None else float(t)), vec


def parse_control_line(line: str, layout: ControlLayout, source: str, *, require_t: bool = True
                       ) -> tuple[float | None, np.ndarray]:
    """One JSON line -> (t or None, (D,) float32); InputError naming ``source`` (never another exception)."""
    try:
        obj = json.loads(line)
    except json.JSONDecodeError as exc:
        raise InputError(f"not JSON: {exc.msg} at column {exc.colno}", source=source) from None
    except RecursionError:
        raise InputError("not JSON: nested too deep", source=source) from None
    except ValueError:  # the only other ValueError json raises: an integer beyond Python's digit limit
        raise InputError(f"not JSON: an integer of more than {sys.get_int_max_str_digits()} digits",
                         source=source) from None
    return parse_control_record(obj, layout, source, require_t=require_t)


def write_controls_csv(path: str | os.PathLike, t: np.ndarray, controls: np.ndarray, layout: ControlLayout,
                       names: Sequence[str] | None = None) -> Path:
    """Write timed controls (t (T,) seconds, controls (T, D)) as a CSV that :func:`~.files.load_controls`
    reads: a header ``t`` and one column per component (``names`` when given, else ``GROUP.I``),
    one row per sample, written atomically."""
    header = ["t"] + list(names if names is not None else layout.default_names())
    lines = [",".join(header)]
    for ti, row in zip(np.asarray(t, dtype=np.float64), np.asarray(controls, dtype=np.float32)):
        lines.append(",".join([repr(float(ti))] + [repr(float(v)) for v in row]))
    return write_text_atomic(path, "\n".join(lines) + "\n")
