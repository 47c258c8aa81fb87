"""Library errors told in the command line's words: argument names become the command's flags.

The library names the argument at fault by its parameter name (``source="pixel_pitch_mm"``, a
hint "pass pixel_pitch_mm ...").  :func:`flag_names` maps them: ``{"pixel_pitch_mm": "--pixel-pitch
MM"}`` turns that source into ``--pixel-pitch`` (the first word) and, in the message and the
hint, every whole-word ``pixel_pitch_mm`` into ``--pixel-pitch MM``.  Inside text, a name is
replaced where it holds an underscore and stands alone (not in a field path or quotes such as
``'physical.gap_mm'``), or where it stands in backquotes (```seed``` -> ``--seed N``); a plain
word like ``views`` is otherwise left alone (it is mapped as a source only).  A source whose first
word is a name keeps the rest: ``"camera sim"`` becomes ``--camera sim``.
"""

from __future__ import annotations

import contextlib
import re
from typing import Iterator, Mapping

from ...core.errors import LenticalibError


def with_flags(exc: LenticalibError, flags: Mapping[str, str]) -> LenticalibError:
    """``exc`` with its source and the argument names in its text replaced by ``flags`` (in place)."""
    names = "|".join(map(re.escape, sorted(flags, key=len, reverse=True)))
    words = "|".join(map(re.escape, sorted((n for n in flags if "_" in n), key=len, reverse=True)))
    # a bare name stands alone: not part of a field path or a quoted key ("field 'physical.gap_mm'")
    pattern = re.compile(rf"`({names})`" + (rf"|(?<![\w.'\"])({words})(?![\w'\"])" if words else ""))

    def replace(text):
        return None if text is None else pattern.sub(lambda m: flags[m.group(1) or m.group(2)], text)

    if flags:
        exc.message, exc.hint = replace(exc.message), replace(exc.hint)
    name, space, rest = (exc.source or "").partition(" ")
    if exc.source in flags or (space and name in flags):
        exc.source = flags[name].split()[0] + space + rest
    return exc



def in_flags(text: str, flags: Mapping[str, str]) -> str:
    """A library note's ``text`` told in the command line's words (argument names -> flags)."""
    return with_flags(LenticalibError(text), flags).message


@contextlib.contextmanager
def flag_names(flags: Mapping[str, str]) -> Iterator[None]:
    """Re-raise a :class:`LenticalibError` of the body in the command line's words (:func:`with_flags`)."""
    try:
        yield
    except LenticalibError as exc:
        raise with_flags(exc, flags)
