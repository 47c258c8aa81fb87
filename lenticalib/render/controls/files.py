"""Control files: a recorded track of control vectors, read, validated and played back.

Every source answers ``latest(now)`` with ``(t, controls)``: a timestamp in seconds and a (D,)
float32 numpy vector laid out as the rig's :class:`~.rig.ControlLayout` says (see :mod:`.rig`).
The render loop asks once per frame; nothing here blocks it.  ``summary()`` gives one line for
the end of a session (a stream's line counts) or None.  This module reads control files;
:mod:`.sources` picks the source for a spec (:func:`~.sources.open_controls`) and the live and
built-in sources are in :mod:`.streams`.

File formats (times in seconds, non-decreasing; every value finite, controls within float32's
range, |v| <= 3.4e38, checked when the file is read):

    .npz    arrays ``t`` (T,) and ``controls`` (T, D), nothing pickled
    .csv    a header row; the first column is ``t``, the others name control components as
            ``GROUP.I`` (``jaw.0``, ``expression.12``) or by the rig's component names (``jaw.x``,
            ``expression.smile``); components without a column are 0; each row t, values
    .jsonl  (also .ndjson, .json) one JSON object per line, blank lines skipped, either
            ``{"t": 0.0, "controls": [D numbers]}`` or group-keyed
            ``{"t": 0.0, "jaw": [0.1, 0, 0], "head": [0, 0.2, 0]}`` where every group given must have
            its full size (a size-1 group may be a bare number) and groups not given are 0
            (:mod:`.records`).

In files every error is one InputError naming the file and line (CSV and JSON lines count from 1,
the CSV header being line 1) or the array, with the expected dimension and layout.

LIMITS.  A track holds at most :data:`MAX_TRACK_BYTES` (256 MiB of times and controls, some 16
hours of 70 controls at 30 fps): an ``.npz`` is refused from its zip directory and array
headers, a text file when its rows pass it, before more is read, so a file's memory is bounded by
the cap whatever it claims (rows are stored as float32 as they are read, never as Python objects).
A CSV or JSON lines file is at most :data:`MAX_TEXT_BYTES` (1 GiB) and a line at most
:data:`MAX_TEXT_LINE` (1 MiB); a FIFO, device or socket is not a control file.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np

from ...core.files.arrayfile import GIB, MIB, load_npz, size_text
from ...core.files.input_files import bounded_lines
from ...core.errors import InputError
from .records import FLOAT32_MAX, FLOAT64_MAX, number_problem, parse_control_line, within_range
from ..avatar.rig import DEFAULT_LAYOUT, ControlLayout

_JSONL_SUFFIXES = (".jsonl", ".ndjson", ".json")
MAX_TRACK_BYTES = 256 * MIB  # a track in memory: t (T,) float64 and controls (T, D) float32 (module docstring)
MAX_TEXT_BYTES = 1 * GIB  # a CSV or JSON lines control file
MAX_TEXT_LINE = 1 * MIB  # one line of it: 4096 controls of 15 characters each are 60 KiB
_CHECK_ROWS = 65536  # rows of an .npz's controls checked at a time (no float64 copy of the whole track)


# ------------------------------------------------------------------ files

class ControlTrack:
    """Timed control vectors from a file: ``t`` (T,) float64 seconds, non-decreasing; ``controls`` (T, D) float32."""

    def __init__(self, t: np.ndarray, controls: np.ndarray, layout: ControlLayout, source: str = "controls"):
        self.t = np.asarray(t, dtype=np.float64)
        self.controls = np.asarray(controls, dtype=np.float32)
        self.layout = layout
        self.source = source

    def __len__(self) -> int:
        return len(self.t)

    def __iter__(self) -> Iterator[tuple[float, np.ndarray]]:
        for t, c in zip(self.t, self.controls):
            yield float(t), c

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def at(self, time_s: float, loop: bool = True) -> tuple[float, np.ndarray]:
        """(t, controls) at ``time_s`` seconds from the track's start, linearly interpolated.

        With ``loop`` the track repeats (time modulo its duration); without, it holds its ends.
        """
        t0 = self.t[0]
        if len(self.t) == 1 or self.duration <= 0:
            return float(t0), self.controls[0].copy()
        local = float(time_s) % self.duration if loop else min(max(float(time_s), 0.0), self.duration)
        t = t0 + local
        j = int(np.searchsorted(self.t, t, side="right"))
        if j <= 0:
            return float(t), self.controls[0].copy()
        if j >= len(self.t):
            return float(t), self.controls[-1].copy()
        ta, tb = self.t[j - 1], self.t[j]
        w = 0.0 if tb == ta else (t - ta) / (tb - ta)
        return float(t), ((1 - w) * self.controls[j - 1] + w * self.controls[j]).astype(np.float32)


def _check_times(t: np.ndarray, where) -> None:
    """InputError at the first non-finite or decreasing time; ``where(i)`` names sample i."""
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"time {t[i]} is not finite", source=where(i))
    dec = np.diff(t) < 0
    if dec.any():
        i = int(np.argmax(dec)) + 1
        raise InputError(f"time {t[i]:g} s comes after {t[i - 1]:g} s", source=where(i),
                         hint="times must not decrease")


def load_controls(path: str | os.PathLike, layout: ControlLayout = DEFAULT_LAYOUT,
                  names: Sequence[str] | None = None) -> ControlTrack:
    """Read and fully validate a control file (.npz, .csv, .jsonl/.ndjson/.json; module docstring).

    ``names`` (the rig's ``control_names``) are accepted as CSV column names besides ``GROUP.I``.
    Every problem is one InputError naming the file and the line or array.
    """
    p = Path(path)
    source = str(p)
    if not p.is_file():
        raise InputError("no such control file" if not p.exists() else "not a file", source=source)
    suffix = p.suffix.lower()
    if suffix in (".csv",) + _JSONL_SUFFIXES and p.stat().st_size > MAX_TEXT_BYTES:
        raise InputError(f"is {size_text(p.stat().st_size)}, more than a control file can sensibly hold (at most "
                         f"{size_text(MAX_TEXT_BYTES)})", source=source, hint="split it, or store it as .npz")
    if suffix == ".npz":
        return _load_npz(p, layout)
    if suffix == ".csv":
        return _load_csv(p, layout, names)
    if suffix in _JSONL_SUFFIXES:
        return _load_jsonl(p, layout)
    raise InputError(f"unknown control file type {suffix or '(none)'!r}", source=source,
                     hint="use .npz, .csv or .jsonl")


def _load_npz(p: Path, layout: ControlLayout) -> ControlTrack:
    source = str(p)

    # Headers first (and the zip's directory): names, shapes, and at most MAX_TRACK_BYTES of arrays.
    arrays = load_npz(p, wanted=("t", "controls"), required=("t", "controls"), max_bytes=MAX_TRACK_BYTES,
                      source=source, hint="a control .npz holds t (T,) and controls (T, D)")
    t, c = arrays["t"], arrays["controls"]
    if t.ndim != 1 or len(t) < 1 or t.dtype.kind not in "fiu":
        raise InputError(f"array 't' has shape {t.shape} dtype {t.dtype}, expected (T,) numbers with T >= 1",
                         source=source)
    if c.ndim != 2 or c.shape != (len(t), layout.dim) or c.dtype.kind not in "fiu":
        raise InputError(f"array 'controls' has shape {c.shape}, expected ({len(t)}, {layout.dim})", source=source,
                         hint=f"layout: {layout.describe()}")
    t = t.astype(np.float64)
    _check_times(t, lambda i: f"{source} row {i}")
    for start in range(0, len(c), _CHECK_ROWS):  # a block at a time: no float64 copy of the whole track
        block = c[start:start + _CHECK_ROWS]
        with np.errstate(invalid="ignore", over="ignore"):
            bad = ~(np.abs(block.astype(np.float64)) <= FLOAT32_MAX)  # NaN, inf and what float32 cannot hold
        if bad.any():
            i, j = (int(v) for v in np.argwhere(bad)[0])
            raise InputError(number_problem(f"controls[{j}]", float(block[i, j])), source=f"{source} row {start + i}")
    return ControlTrack(t, c.astype(np.float32, copy=False), layout, source)


class _Rows:
    """Rows of a text control file stored as they are read: t float64, controls float32 (D,), in
    arrays that grow by half (never a Python object per value); refused past MAX_TRACK_BYTES."""

    def __init__(self, dim: int, source: str):
        self.dim, self.source, self.n = dim, source, 0
        self.most = max(1, MAX_TRACK_BYTES // (8 + 4 * dim + 4))  # t, the controls, the line number
        self.t = np.empty(1024, np.float64)
        self.c = np.zeros((1024, dim), np.float32)
        self.lines = np.empty(1024, np.int32)

    def add(self, t: float, where: str, line_no: int) -> np.ndarray:
        """Room for one more row (its time ``t``): the row's (D,) float32 view, zeros, to fill."""
        if self.n >= self.most:
            raise InputError(f"holds more than {self.most} samples of {self.dim} controls, more than a control track "
                             f"can sensibly hold ({size_text(MAX_TRACK_BYTES)})", source=where,
                             hint="split it, or sample it less often")
        if self.n == len(self.t):
            grow = min(self.most, len(self.t) + len(self.t) // 2)
            self.t, self.lines = np.resize(self.t, grow), np.resize(self.lines, grow)
            c = np.zeros((grow, self.dim), np.float32)
            c[:self.n] = self.c[:self.n]
            self.c = c
        self.t[self.n] = t
        self.lines[self.n] = line_no
        self.n += 1
        return self.c[self.n - 1]

    def track(self, layout: ControlLayout, empty: str, hint: str | None = None) -> ControlTrack:
        if not self.n:
            raise InputError(empty, source=self.source, hint=hint)
        t = self.t[:self.n]
        _check_times(t, lambda i: f"{self.source}:{self.lines[i]}")
        return ControlTrack(t, self.c[:self.n], layout, self.source)  # views: no second copy of the track


def _text_lines(p: Path):
    """(line number, line) of a UTF-8 text file, each line read bounded (at most MAX_TEXT_LINE)."""
    source = str(p)
    try:
        with open(p, encoding="utf-8", newline="") as fh:
            yield from bounded_lines(fh, MAX_TEXT_LINE, source, hint="one sample a line")
    except UnicodeDecodeError:
        raise InputError("is not UTF-8 text", source=source) from None


def _column_index(name: str, layout: ControlLayout, names: Sequence[str] | None) -> int | None:
    if names is not None and name in names:
        return list(names).index(name)
    group, dot, index = name.rpartition(".")
    if dot and group in layout and index.isdigit() and int(index) < layout.size(group):
        return layout.slice(group).start + int(index)
    return None


def _load_csv(p: Path, layout: ControlLayout, names: Sequence[str] | None) -> ControlTrack:
    source = str(p)
    lines = _text_lines(p)
    first = next(lines, (1, ""))[1]
    header = [h.strip() for h in _csv_row(first, f"{source}:1")]
    if not header or not any(header):
        raise InputError("no header row", source=f"{source}:1", hint="the first row names the columns: t, jaw.0, ...")
    if header[0] != "t":
        raise InputError(f"first column is {header[0]!r}, expected 't'", source=f"{source}:1")
    columns = []
    for name in header[1:]:
        k = _column_index(name, layout, names)
        if k is None:
            raise InputError(f"unknown control column {name!r}", source=f"{source}:1",
                             hint=f"name columns GROUP.I with groups {layout.describe()}")
        if k in columns:
            raise InputError(f"column {name!r} repeats control {k}", source=f"{source}:1")
        columns.append(k)
    rows = _Rows(layout.dim, source)
    limits = [FLOAT64_MAX] + [FLOAT32_MAX] * len(columns)  # t is float64, the controls float32
    for line_no, line in lines:
        where = f"{source}:{line_no}"
        row = _csv_row(line, where)
        if not row or all(not f.strip() for f in row):
            continue
        if len(row) != len(header):
            raise InputError(f"{len(row)} fields, expected {len(header)} (t and {len(header) - 1} controls)",
                             source=where)
        try:
            values = [float(f) for f in row]
        except ValueError:
            col = next(i for i, f in enumerate(row) if not _is_float(f))
            raise InputError(f"column {header[col]!r} is {row[col]!r}, expected a number", source=where) from None
        out = [i for i, (v, limit) in enumerate(zip(values, limits)) if not within_range(v, limit)]
        if out:
            col = out[0]
            raise InputError(number_problem(f"column {header[col]!r}", values[col], limits[col]), source=where)
        rows.add(values[0], where, line_no)[columns] = values[1:]
    return rows.track(layout, "no rows after the header")


def _csv_row(line: str, where: str) -> list[str]:
    """The fields of one CSV line (numbers and names: no quoted line breaks in a control file)."""
    try:
        return next(csv.reader([line]), [])
    except csv.Error as exc:
        raise InputError(f"is not a CSV row ({exc})", source=where) from None


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _load_jsonl(p: Path, layout: ControlLayout) -> ControlTrack:
    source = str(p)
    rows = _Rows(layout.dim, source)
    for line_no, line in _text_lines(p):
        if not line.strip():
            continue
        where = f"{source}:{line_no}"
        ti, vec = parse_control_line(line, layout, where, require_t=True)
        rows.add(ti, where, line_no)[:] = vec
    return rows.track(layout, "no control lines", hint='one JSON object a line: {"t": 0.0, "controls": [...]}')


# ------------------------------------------------------------------ the file source

class FileControls:
    """A :class:`ControlTrack` played back: ``latest(now)`` interpolates at ``now`` seconds (looping)."""

    def __init__(self, track: ControlTrack, loop: bool = True):
        self.track = track
        self.loop = loop
        self.layout = track.layout

    def latest(self, now: float = 0.0) -> tuple[float, np.ndarray]:
        return self.track.at(now, self.loop)

    def close(self) -> None:
        pass

    def summary(self) -> None:
        """Nothing to report at the end of a session (the file was validated when it was read)."""
        return None


def open_file_source(spec: str, layout: ControlLayout, names: Sequence[str] | None = None) -> FileControls:
    """The ``file`` control source: the control file ``spec``, read and validated whole, played looping."""
    return FileControls(load_controls(spec, layout, names))
