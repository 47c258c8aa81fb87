"""The documents lenticalib writes: one envelope, one table of formats, one reader.

Every document lenticalib writes (JSON files, and the arrays of a rig ``.npz``) starts with
the same two fields, its envelope:

    format           str   the dotted name of the format, e.g. "lenticalib.profile"
    format_version   int   the version of that format the writer used

:data:`FORMATS` lists every format, with the versions this lenticalib reads.  Reading goes
through :func:`read_document` (a JSON file) or :func:`check_envelope` (a mapping already read,
e.g. a TOML controller description or a rig's arrays); each raises one InputError naming the
file and the field (``format``, ``format_version``) on a document of another kind or version.

Older spellings still read, so files users already have keep working: the key ``version``
for ``format_version`` (camera boards, camera calibration summaries, camera simulations and
rigs were written with it) and a format's earlier names (the rig was ``"lenticalib-rig"``).

:func:`read_json_file` is the one JSON-file reader: data only (nothing in a file is executed),
UTF-8, unusable numbers refused, bounded before anything is allocated (a regular file of at most
:data:`MAX_JSON_BYTES`, or its format's smaller cap; at most :data:`MAX_JSON_ELEMENTS` values and
:data:`MAX_JSON_DEPTH` levels: docs/input-limits.md); every JSON input of lenticalib goes through
it, or through :func:`json_from_bytes` / :func:`json_from_text` for JSON held elsewhere.  Looking
Glass's own ``visual.json`` is read with it but carries no envelope: it is Looking Glass's
format, written as Looking Glass writes it (:mod:`lenticalib.core.looking_glass.convert`).
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any, Mapping

from .atomic import write_text_atomic
from ..errors import InputError
from .fields import json_shape, parse_json, short_repr
from .input_files import KIB, MIB, read_input, size_text

FORMAT_KEY = "format"
VERSION_KEY = "format_version"
OLD_VERSION_KEY = "version"  # the envelope's older spelling, still read

# LIMITS of every JSON document read (docs/input-limits.md): checked before the file is read
# (bytes), before it is parsed (values, estimated from the text) and in one pass after (depth).
# lenticalib's own documents (fixtures/, the tests' runs) are KiBs, at most 5 levels deep.
MAX_JSON_BYTES = 16 * MIB  # any document (parsed within some 150 MB, tests/test_input_bombs.py)
MAX_PROFILE_BYTES = 1 * MIB  # a profile: under 1 KiB of constants, a visual.json and a provenance
MAX_VISUAL_JSON_BYTES = 64 * KIB  # Looking Glass's visual.json: what a unit's calibration store holds
MAX_JSON_DEPTH = 64  # levels of nesting
MAX_JSON_ELEMENTS = 2_000_000  # values (numbers, strings, objects, arrays, keys) in one document


@dataclasses.dataclass(frozen=True)
class DocumentFormat:
    """One document format: its dotted ``name``, the ``version`` written, what it is called.

    ``what``      the kind of file in messages ("profile", "cameras file")
    ``hint``      what to do with a file that is not one of this format (or of no version read)
    ``reads``     the versions read (default: just ``version``)
    ``aliases``   earlier names of the format, still read
    ``implicit``  a document without an envelope is read as the current version (hand-written
                  profiles hold just the panel constants)
    """

    name: str
    version: int
    what: str
    hint: str = ""
    reads: tuple[int, ...] = ()
    aliases: tuple[str, ...] = ()
    implicit: bool = False

    @property
    def versions(self) -> tuple[int, ...]:
        """The versions this lenticalib reads."""
        return self.reads or (self.version,)

    def envelope(self) -> dict[str, Any]:
        """``{"format": name, "format_version": version}``: the head of every document written."""
        return {FORMAT_KEY: self.name, VERSION_KEY: self.version}


def _formats(*formats: DocumentFormat) -> dict[str, DocumentFormat]:
    return {f.name: f for f in formats}


# Every format lenticalib writes (docs/README.md lists them with the files they are found in).
FORMATS: dict[str, DocumentFormat] = _formats(
    DocumentFormat("lenticalib.profile", 2, "profile",
                   "is this a Looking Glass visual.json? use 'lenticalib profile import-lkg'", implicit=True,
                   reads=(1, 2)),
    DocumentFormat("lenticalib.rig", 1, "rig file", "make one with tools/make_demo_avatar.py",
                   aliases=("lenticalib-rig",)),
    DocumentFormat("lenticalib.cameras", 1, "cameras file", "give the cameras.json written with the views"),
    DocumentFormat("lenticalib.simulation", 1, "simulation scene",
                   "use a simulation.json or scene file written by 'lenticalib simulate'"),
    DocumentFormat("lenticalib.simulation-run", 1, "simulation record", "simulate the capture set again"),
    DocumentFormat("lenticalib.crosstalk-truth", 1, "crosstalk truth", "simulate the capture set again"),
    DocumentFormat("lenticalib.camera-simulation", 1, "camera simulation record",
                   "simulate the set again with 'lenticalib camera simulate'"),
    DocumentFormat("lenticalib.camera-board", 1, "board manifest",
                   "use the board.json written by 'lenticalib camera patterns'"),
    DocumentFormat("lenticalib.camera-calibration", 1, "camera calibration summary",
                   "calibrate the camera again with 'lenticalib camera calibrate'"),
    DocumentFormat("lenticalib.fit-report", 1, "fit summary", "fit the capture set again with 'lenticalib fit'"),
    DocumentFormat("lenticalib.fleet-panel", 1, "panel record", "fit the panel again with 'lenticalib batch fit'"),
    DocumentFormat("lenticalib.fleet-summary", 1, "fleet summary", "run 'lenticalib batch fit' again"),
    DocumentFormat("lenticalib.driver", 1, "controller description", "see drivers/lc32.toml for the format"),
    DocumentFormat("lenticalib.emulator-announcement", 1, "emulator announcement",
                   "start the emulator again with 'lenticalib emulate'", implicit=True),  # older ones had none
    DocumentFormat("lenticalib.patterns", 2, "pattern manifest",
                   "write the patterns again with this lenticalib and photograph them"),
    DocumentFormat("lenticalib.crosstalk-patterns", 1, "crosstalk pattern manifest",
                   "write the crosstalk patterns again with this lenticalib and photograph them"),
    DocumentFormat("lenticalib.crosstalk", 1, "crosstalk file", "measure it with 'lenticalib crosstalk measure'"),
    DocumentFormat("lenticalib.student-driver", 1, "student driver",
                   "make one with 'lenticalib driver distill'"),
    DocumentFormat("lenticalib.avatar-diagnostics", 1, "avatar diagnostics",
                   "diagnose the avatar again with 'lenticalib avatar diagnose'"),
)


def document_format(name: str) -> DocumentFormat:
    """The :class:`DocumentFormat` called ``name`` (KeyError for a name lenticalib does not know)."""
    return FORMATS[name]


def check_envelope(data: Any, fmt: DocumentFormat, source: str,
                   error: type[InputError] = InputError) -> int:
    """The version of document ``data`` (a mapping) of format ``fmt``; ``error`` naming ``source``
    and the field when it is not a mapping, names another format or a version not read."""
    if not isinstance(data, Mapping):
        raise error(f"is not a {fmt.what}: not a JSON object", source=source, hint=fmt.hint or None)
    if FORMAT_KEY not in data and not fmt.implicit:
        raise error(f"field '{FORMAT_KEY}' is missing: not a {fmt.what}", source=source,
                    hint=f"a {fmt.what} starts with \"{FORMAT_KEY}\": \"{fmt.name}\"")
    name = data.get(FORMAT_KEY, fmt.name)
    if name != fmt.name and name not in fmt.aliases:
        raise error(f"field '{FORMAT_KEY}': expected \"{fmt.name}\", got {short_repr(name)}", source=source,
                    hint=fmt.hint or None)
    key = VERSION_KEY if VERSION_KEY in data else OLD_VERSION_KEY if OLD_VERSION_KEY in data else None
    if key is None:
        if fmt.implicit:
            return fmt.version
        raise error(f"field '{VERSION_KEY}' is missing", source=source,
                    hint=f"this lenticalib reads {fmt.what}s of version {_versions(fmt)}")
    version = data[key]
    if isinstance(version, bool) or not isinstance(version, int) or version not in fmt.versions:
        newer = isinstance(version, int) and not isinstance(version, bool) and version > max(fmt.versions)
        raise error(f"field '{key}': unknown version {short_repr(version)}", source=source,
                    hint=f"this lenticalib reads version {_versions(fmt)}; "
                         + ("upgrade lenticalib" if newer else fmt.hint or f"write the {fmt.what} again"))
    return version


def _versions(fmt: DocumentFormat) -> str:
    return " or ".join(str(v) for v in fmt.versions)


def read_document(path: str | os.PathLike, fmt: DocumentFormat, hint_missing: str | None = None,
                  error: type[InputError] = InputError) -> dict[str, Any]:
    """Read the JSON document ``path`` of format ``fmt``: :func:`read_json_file`, then
    :func:`check_envelope`.  Every failure is one ``error`` naming the file (and the field);
    ``hint_missing`` says what to do when the file does not exist (default: ``fmt.hint``)."""
    data = read_json_file(path, fmt.what, fmt.hint if hint_missing is None else hint_missing, error)
    check_envelope(data, fmt, str(path), error)
    return data


def document_text(fmt: DocumentFormat, body: Mapping[str, Any], indent: int | None = 2) -> str:
    """The JSON text of a document of format ``fmt``: its envelope, then ``body`` (whose own
    ``format``/``format_version``/``version`` keys, if any, are replaced), ending in a newline."""
    rest = {k: v for k, v in body.items() if k not in (FORMAT_KEY, VERSION_KEY, OLD_VERSION_KEY)}
    return json.dumps({**fmt.envelope(), **rest}, indent=indent) + "\n"


def write_document(path: str | os.PathLike, fmt: DocumentFormat, body: Mapping[str, Any],
                   indent: int | None = 2, **atomic: Any) -> Path:
    """Write ``body`` as a document of format ``fmt`` to ``path`` atomically (:func:`document_text`;
    ``atomic``: keyword arguments of :func:`lenticalib.core.files.atomic.write_text_atomic`)."""
    return write_text_atomic(path, document_text(fmt, body, indent), **atomic)


def read_json_file(path: str | os.PathLike, what: str, hint_missing: str,
                   error: type[InputError] = InputError, max_bytes: int = MAX_JSON_BYTES) -> Any:
    """Parse a JSON file (data only: nothing in it is executed); unusable numbers are refused.

    The file must be a regular file of at most ``max_bytes`` (:data:`MAX_JSON_BYTES` unless the
    format is smaller: :data:`MAX_PROFILE_BYTES`, :data:`MAX_VISUAL_JSON_BYTES`), checked before
    it is read (:func:`lenticalib.core.files.input_files.open_input`: a FIFO or a device is refused at
    once), and UTF-8 text (a leading byte-order mark is accepted); then :func:`json_from_bytes`.
    Raises ``error`` naming the file for a missing, unreadable, special, too large, empty, binary
    or non-UTF-8 file, for invalid JSON and for a document nested or numerous beyond the limits,
    and naming the field too for a number no float holds (``NaN``, ``Infinity``, ``1e400``, a
    400-digit integer: :mod:`lenticalib.core.files.fields`); ``what`` names the kind of file in
    messages (e.g. ``"profile"``), ``hint_missing`` says what to do when it does not exist.
    """
    raw = read_input(path, what, max_bytes, hint_missing, error)
    return json_from_bytes(raw, str(path), what, hint_missing, error, max_bytes)


def json_from_bytes(raw: bytes, source: str, what: str, hint_missing: str,
                    error: type[InputError] = InputError, max_bytes: int = MAX_JSON_BYTES) -> Any:
    """:func:`read_json_file` for bytes already read (from a device, say): the same checks, and
    errors of class ``error`` naming ``source``."""
    src = source
    if len(raw) > max_bytes:
        raise error(f"is {size_text(len(raw))}, more than a JSON {what} can sensibly hold (at most "
                    f"{size_text(max_bytes)})", source=src)
    if not raw.strip():
        raise error(f"is empty, not a JSON {what}", source=src, hint=hint_missing)
    kind = binary_kind(raw)
    if kind:
        raise error(f"is {kind}, not a JSON {what}", source=src, hint=hint_missing)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"is not a JSON {what}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at "
                    f"offset {exc.start})", source=src, hint=f"save the {what} as UTF-8 JSON") from None
    return json_from_text(text, src, error)


def json_from_text(text: str, source: str, error: type[InputError] = InputError) -> Any:
    """The JSON value of ``text`` (a document or a string held in another file, e.g. a rig's
    provenance), within :data:`MAX_JSON_DEPTH` levels and :data:`MAX_JSON_ELEMENTS` values and
    without unusable numbers; else one ``error`` naming ``source``.

    The element count is bounded from the text before parsing (every value but the first of a
    container follows a ``,`` or ``:``, every container opens with ``{`` or ``[``), so a document of
    millions of empty objects is refused before they are built; depth and numbers are checked
    in one pass over the parsed value (:func:`lenticalib.core.files.fields.json_shape`).
    """
    estimate = sum(text.count(c) for c in "{[,:") + 1  # at least the values and keys the text holds
    if estimate > MAX_JSON_ELEMENTS:
        raise error(f"holds about {estimate} JSON values, more than the {MAX_JSON_ELEMENTS} any document of "
                    "lenticalib has", source=source)
    too_deep = f"is nested more than {MAX_JSON_DEPTH} levels deep, deeper than any document of lenticalib"
    try:
        document = parse_json(text)
    except json.JSONDecodeError as exc:
        raise error(f"not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})", source=source) from None
    except RecursionError:
        raise error(too_deep, source=source) from None
    except ValueError as exc:
        raise error(f"not usable JSON: {exc}", source=source) from None
    shape = json_shape(document, MAX_JSON_DEPTH, MAX_JSON_ELEMENTS)
    if shape.too_deep:
        raise error(too_deep, source=source)
    if shape.too_many:
        raise error(f"holds more than {MAX_JSON_ELEMENTS} JSON values, more than any document of lenticalib has",
                    source=source)
    if shape.bad is not None:
        field, number = shape.bad
        raise error(f"field '{field}': {number.text} {number.why}" if field else f"{number.text} {number.why}",
                    source=source, hint="write a finite number")
    return document


_MAGIC = ((b"\x89PNG\r\n\x1a\n", "a PNG image"), (b"\xff\xd8\xff", "a JPEG image"),
          (b"II*\x00", "a TIFF image"), (b"MM\x00*", "a TIFF image"),
          (b"\x93NUMPY", "a numpy array"), (b"PK\x03\x04", "a ZIP archive"))


def binary_kind(raw: bytes) -> str | None:
    """What a file that cannot be text of the expected format looks like, from its first bytes
    ``raw``: a known image/array/archive signature ("a PNG image"), "a binary file", or None."""
    for magic, kind in _MAGIC:
        if raw.startswith(magic):
            return kind
    if b"\x00" in raw[:4096]:
        return "a binary file"
    return None
