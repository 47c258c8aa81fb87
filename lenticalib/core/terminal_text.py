"""Text from outside made safe for a terminal: control characters shown escaped, long values cut.

A serial number from a unit, a field of a file, a name a camera or a monitor reports: such text
reaches the user's terminal inside messages and listings.  Written raw, an ESC or OSC sequence in
it would retitle the terminal (``ESC ] 0 ; title BEL``), clear the screen (``ESC [ 2 J``), write
the clipboard (``ESC ] 52 ; c ; ...``) or reorder what follows (U+202E); a 200 KB value would
make a 200 KB line.  :func:`terminal_safe` is the one place that prevents both; the CLI passes
every such value (and every error line, :func:`lenticalib.cli.main`) through it.

Shown escaped, as Python writes them in a string literal:

    C0 controls  U+0000..U+001F  ``\\x1b``, ``\\n``, ``\\r``, ``\\t`` (a value never breaks its line)
    DEL          U+007F          ``\\x7f``
    C1 controls  U+0080..U+009F  ``\\x9b`` (CSI on terminals that take 8-bit controls)
    format       category Cf: bidi embeddings, overrides and isolates (U+202A..U+202E,
                 U+2066..U+2069), marks (U+200E, U+200F, U+061C), zero-width characters,
                 U+FEFF, tags (U+E0001..)                        ``\\u202e``, ``\\U000e0001``
    separators   U+2028, U+2029 (line and paragraph separators)  ``\\u2028``
    surrogates   U+D800..U+DFFF (undecodable bytes kept by ``surrogateescape``; a terminal
                 cannot even be written them)                    ``\\udcff``

Everything else (letters of every script, symbols, a backslash) passes unchanged.  A value whose
escaped text is longer than ``limit`` characters is cut in the middle (never inside an escape)
and says its length: ``LKG-AAAA...AAAA (200012 characters)``, so the result is at most ``limit``
characters and about 25 more whatever the input.
"""

from __future__ import annotations

import re
import unicodedata
from typing import Any

MAX_VALUE_CHARS = 120  # a value inside a line: a serial, a field, a name
MAX_LINE_CHARS = 800   # a whole line (an error message with its source and hint)
CUT_MARK = "..."

_ASCII_CONTROLS = "\x00-\x1f\x7f-\x9f"
# Non-ASCII characters to escape; the categories are checked per character (only for non-ASCII text).
_UNSAFE_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Zl", "Zp"})
_ASCII_UNSAFE = re.compile(f"[{_ASCII_CONTROLS}]")


def _escape_char(char: str) -> str:
    code = ord(char)
    named = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}.get(char)
    if named:
        return named
    if code <= 0xFF:
        return f"\\x{code:02x}"
    if code <= 0xFFFF:
        return f"\\u{code:04x}"
    return f"\\U{code:08x}"


def _is_unsafe(char: str) -> bool:
    code = ord(char)
    return code < 0x20 or 0x7F <= code <= 0x9F or (code > 0x9F and unicodedata.category(char) in
                                                    _UNSAFE_CATEGORIES)


def _escape(text: str) -> str:
    if text.isascii():  # the common case: only C0 and DEL can occur
        return _ASCII_UNSAFE.sub(lambda m: _escape_char(m.group()), text)
    return "".join(_escape_char(c) if _is_unsafe(c) else c for c in text)


def _escaped_within(chars, budget: int) -> list[str]:
    """The escaped pieces of ``chars`` (an iterable of characters), as many as fit in ``budget``."""
    pieces, used = [], 0
    for char in chars:
        piece = _escape_char(char) if _is_unsafe(char) else char
        used += len(piece)
        if used > budget:
            break
        pieces.append(piece)
    return pieces


def terminal_safe(value: Any, limit: int = MAX_VALUE_CHARS) -> str:
    """``value`` (``str(value)`` unless a str) ready for a terminal: control and format characters
    escaped (module docstring), and, when that is longer than ``limit`` characters, cut in the
    middle with the value's length stated: ``head...tail (N characters)``.  Never raises: an object
    whose ``str()`` fails gives ``<TypeName>``.

    ARGUMENTS
    ``value``: the text (or object); ``limit``: characters of the escaped text kept (>= 16).

    RETURNED VALUE
    One line of text without control characters, at most ``limit`` characters plus the cut mark
    and the stated length (about 25 more).
    """
    if not isinstance(value, str):
        try:
            value = str(value)
        except Exception:  # noqa: BLE001 -- a hostile __str__ must not break an error message
            return f"<{type(value).__name__}>"
    limit = max(16, int(limit))
    if len(value) <= limit:
        escaped = _escape(value)
        if len(escaped) <= limit:
            return escaped
    tail_budget = max(6, limit // 4)
    head = "".join(_escaped_within(value[:limit], limit - tail_budget - len(CUT_MARK)))
    tail = "".join(reversed(_escaped_within(reversed(value[-tail_budget:]), tail_budget)))
    return f"{head}{CUT_MARK}{tail} ({len(value)} characters)"


def safe_line(text: Any) -> str:
    """A whole line (an error message, a warning): :func:`terminal_safe` with :data:`MAX_LINE_CHARS`."""
    return terminal_safe(text, MAX_LINE_CHARS)
