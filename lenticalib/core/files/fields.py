"""Checks every reader of a user document shares: numbers that fit a float, and known key names.

NUMBERS.  A number in a JSON document is usable when it is finite and fits a float64
(``|x| <= 1.8e308``).  :func:`parse_json` parses with hooks that keep an unusable number (a
2000-digit integer, ``1e400``, ``NaN``, ``Infinity``) as a marker, and :func:`unusable_number`
finds the first marker with the path of the field that holds it (``slant``,
``physical.eye_mm[2]``), so a reader refuses it in one line naming file and field, before any
arithmetic on it can overflow.  :func:`json_shape` is that search and the document's depth and
value count in one pass, building a path only for the number it reports.  :func:`is_number` /
:func:`is_finite_number` are the type tests for one value (a bool is not a number; a huge int is
not finite).

KEY NAMES.  :func:`unknown_key_message` names an unknown key and the known key it is most likely a
misspelling of: ``unknown field 'slnat' (did you mean 'slant'?)``.
"""

from __future__ import annotations

import difflib
import json
import math
import sys
from typing import Any, Iterable

FLOAT_MAX = sys.float_info.max  # about 1.8e308
_INT_LIMIT = int(FLOAT_MAX)
_INT_DIGITS = len(str(_INT_LIMIT))  # 309: a longer integer literal cannot fit a float


def is_number(value: Any) -> bool:
    """An ``int`` or ``float`` (not a bool, not a list, not a string)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def is_finite_number(value: Any) -> bool:
    """:func:`is_number` and finite as a float64 (an int beyond 1.8e308 is not; never raises)."""
    if not is_number(value):
        return False
    if isinstance(value, int):
        return -_INT_LIMIT <= value <= _INT_LIMIT
    return math.isfinite(value)


def short_repr(value: Any, limit: int = 24) -> str:
    """``repr(value)`` for one-line messages: at most about ``limit`` characters, a long one cut in
    the middle with its length; an integer beyond 1.8e308 as such (never raises, even for an
    integer too long for ``repr``)."""
    if isinstance(value, int) and not isinstance(value, bool) and not is_finite_number(value):
        return f"{'-' if value < 0 else ''}an integer beyond 1.8e308"
    try:
        text = repr(value)
    except (ValueError, RecursionError):
        return f"<{type(value).__name__}>"
    return text if len(text) <= limit else f"{text[:12]}...{text[-6:]} ({len(text)} characters)"


class UnusableNumber:
    """A number literal of a JSON document that no float can hold; ``text`` as written (shortened)."""

    __slots__ = ("text", "why")

    def __init__(self, text: str, why: str):
        digits = text.lstrip("-")
        unit = "digits" if digits.isdigit() else "characters"
        self.text = text if len(text) <= 24 else f"{text[:12]}...{text[-6:]} ({len(digits)} {unit})"
        self.why = why

    def __repr__(self) -> str:
        return self.text


_TOO_LARGE = "is too large for a number (beyond 1.8e308)"


def _parse_int(text: str):
    if len(text.lstrip("-")) > _INT_DIGITS:
        return UnusableNumber(text, _TOO_LARGE)
    value = int(text)
    return value if -_INT_LIMIT <= value <= _INT_LIMIT else UnusableNumber(text, _TOO_LARGE)


def _parse_float(text: str):
    value = float(text)
    return value if math.isfinite(value) else UnusableNumber(text, _TOO_LARGE)


def _parse_constant(text: str):
    return UnusableNumber(text, "is a non-finite number")


def parse_json(text: str) -> Any:
    """``json.loads`` with unusable numbers kept as :class:`UnusableNumber` (see the module docstring).

    Raises ``json.JSONDecodeError`` for text that is not JSON and RecursionError for absurd nesting.
    """
    return json.loads(text, parse_int=_parse_int, parse_float=_parse_float, parse_constant=_parse_constant)


class JsonShape:
    """What one pass over a :func:`parse_json` result found: ``elements`` (values counted so far,
    containers included), ``depth`` (the deepest nesting level reached; a bare value is 0),
    ``bad`` (``(field path, marker)`` of the first unusable number, or None) and ``too_deep`` /
    ``too_many`` (the limit passed, when one was: the pass stops there)."""

    __slots__ = ("elements", "depth", "bad", "too_deep", "too_many")

    def __init__(self):
        self.elements, self.depth, self.bad = 0, 0, None
        self.too_deep = self.too_many = False


def _path_of(node: tuple | None, key: Any = None) -> str:
    """The field path of ``key`` inside the container whose ``node`` is ``(parent node, key)``."""
    keys = [] if key is None else [key]
    while node is not None:
        node, k = node
        keys.append(k)
    text = ""
    for k in reversed(keys):
        text += f"[{k}]" if isinstance(k, int) else (f".{k}" if text else str(k))
    return text


def json_shape(document: Any, max_depth: int | None = None, max_elements: int | None = None) -> JsonShape:
    """Walk a :func:`parse_json` result once, in document order and without recursion: count its
    values, measure its nesting and find its first unusable number (see :func:`unusable_number`);
    stop at the first unusable number or at a limit passed (``max_depth`` levels of nesting,
    ``max_elements`` values, containers included).

    Paths are built only for the unusable number found: the walk keeps one ``(parent, key)`` link
    per open container, none per value.
    """
    shape = JsonShape()
    if isinstance(document, UnusableNumber):
        shape.bad = ("", document)
        return shape
    if not isinstance(document, (dict, list)):
        return shape
    limit_depth = sys.maxsize if max_depth is None else max_depth
    limit_count = sys.maxsize if max_elements is None else max_elements

    def items(value):
        return iter(value.items()) if isinstance(value, dict) else enumerate(value)

    # the open containers: (their items still to visit, the (parent node, key) link of each)
    iterators, nodes = [items(document)], [None]
    count, deepest = 1 + len(document), 1
    while iterators:
        for key, child in iterators[-1]:
            if isinstance(child, (dict, list)):
                count += len(child)
                nodes.append((nodes[-1], key))
                iterators.append(items(child))
                deepest = max(deepest, len(iterators))
                break
            if isinstance(child, UnusableNumber):
                shape.bad = (_path_of(nodes[-1], key), child)
                break
        else:
            iterators.pop()
            nodes.pop()
            continue
        if shape.bad is not None:
            break
        if deepest > limit_depth:
            shape.too_deep = True
            break
        if count > limit_count:
            shape.too_many = True
            break
    shape.elements, shape.depth = count, deepest
    return shape


def unusable_number(document: Any) -> tuple[str, UnusableNumber] | None:
    """``(field path, marker)`` of the first unusable number in a :func:`parse_json` result, else None.

    Paths join object keys with ``.`` and list indices as ``[i]``: ``"looking_glass.pitch.value"``,
    ``"matrix[3][1]"``; a bare unusable number at the top is ``""``.  One pass
    (:func:`json_shape`); the path is built only for the number found.
    """
    return json_shape(document).bad


def unknown_key_message(unknown: Iterable[str], known: Iterable[str], what: str = "field") -> str:
    """``"unknown field 'slnat' (did you mean 'slant'?)"`` for the first of ``unknown`` (sorted);
    further unknown keys are listed after it.  ``known`` are the valid names."""
    names = sorted(str(k) for k in unknown)
    first = names[0]
    close = difflib.get_close_matches(first, [str(k) for k in known], n=1, cutoff=0.6)
    text = f"unknown {what} '{first}'" + (f" (did you mean '{close[0]}'?)" if close else "")
    if len(names) > 1:
        text += f"; also unknown: {', '.join(repr(n) for n in names[1:])}"
    return text
