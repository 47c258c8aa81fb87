"""Controller family descriptions: the TOML files in ``drivers/`` (data, not code).

Search path, first match of a family name wins: ``$LENTICALIB_DRIVERS`` (``os.pathsep``
separated), ``~/.config/lenticalib/drivers``, then the families shipped in the package
(``lenticalib/device/families/*.toml``, package data read through :mod:`importlib.resources`,
so an editable install and a wheel find them alike).  The repository's ``drivers/`` folder is
the documented specification; the package's copy is the same bytes (tests/test_device_record.py
checks it).  See ``drivers/lc32.toml`` for the format.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.resources
import os
import tomllib
from pathlib import Path

from ..core.files.documents import FORMATS, check_envelope
from ..core.errors import InputError
from ..core.files.input_files import KIB, read_input
from .protocol import PanelGeometry

DOCUMENT = FORMATS["lenticalib.driver"]
TRANSPORT_KINDS = ("serial", "hid", "usb")
DEFAULT_FAMILY = "lc32"


@dataclasses.dataclass(frozen=True)
class TransportDescription:
    """One way a family's controller appears on USB (fields as in the TOML file)."""

    kind: str
    vid: int
    pid: int
    baudrate: int = 115200
    report_size: int = 64
    out_report_id: int = 1
    in_report_id: int = 2
    request_out: int = 1
    request_in: int = 2
    max_in: int = 64


@dataclasses.dataclass(frozen=True)
class ControllerFamily:
    """A controller family: protocol, record layouts, timeouts (seconds), transports, and the
    default panel (``panel``, None when the file has no ``[panel]`` table)."""

    name: str
    description: str
    protocol_version: int
    record_layout_versions: tuple[int, ...]
    command_timeout_s: float
    flash_timeout_s: float
    retries: int
    transports: tuple[TransportDescription, ...]
    source: str
    panel: PanelGeometry | None = None

    def transport(self, kind: str) -> TransportDescription | None:
        return next((t for t in self.transports if t.kind == kind), None)


def search_path() -> list[Path]:
    """The folders searched for family files, first match of a name wins (module docstring)."""
    paths = [Path(p) for p in os.environ.get("LENTICALIB_DRIVERS", "").split(os.pathsep) if p]
    paths.append(Path(os.path.expanduser("~")) / ".config" / "lenticalib" / "drivers")
    paths.append(packaged_families())
    return paths


def packaged_families() -> Path:
    """The folder of the family files shipped inside the package (``lenticalib/device/families``).

    The package is installed as files (an editable install or a wheel), so the resource is a folder
    on disk; were it ever not (a zip import), the folder does not exist and is skipped."""
    return Path(str(importlib.resources.files(__package__).joinpath("families")))


MAX_DRIVER_BYTES = 256 * KIB  # a controller description (drivers/lc32.toml is some 2 KiB)


def load_family(path: str | os.PathLike) -> ControllerFamily:
    """Parse one family file; raises InputError naming the file and field."""
    path = Path(path)
    source = str(path)
    try:
        data = tomllib.loads(read_input(path, "controller description", MAX_DRIVER_BYTES).decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"cannot read controller description: {exc}", source=source) from None

    def field(table: dict, key: str, kind, where: str):
        value = table.get(key)
        if not isinstance(value, kind) or isinstance(value, bool):
            raise InputError(f"field '{where}{key}' is missing or not a {getattr(kind, '__name__', kind)}",
                             source=source, hint="see drivers/lc32.toml for the format")
        return value

    check_envelope(data, DOCUMENT, source)
    family = data.get("family") if isinstance(data.get("family"), dict) else {}
    timeouts = data.get("timeouts") if isinstance(data.get("timeouts"), dict) else {}
    transports = []
    for i, entry in enumerate(data.get("transport") or []):
        where = f"transport[{i}]."
        kind = field(entry, "kind", str, where)
        if kind not in TRANSPORT_KINDS:
            raise InputError(f"field '{where}kind' must be one of {', '.join(TRANSPORT_KINDS)}", source=source)
        extras = {k: field(entry, k, int, where) for k in
                  ("baudrate", "report_size", "out_report_id", "in_report_id", "request_out", "request_in",
                   "max_in") if k in entry}
        vid, pid = field(entry, "vid", int, where), field(entry, "pid", int, where)
        if not (0 <= vid <= 0xFFFF and 0 <= pid <= 0xFFFF):
            raise InputError(f"field '{where}vid/pid' must be 16-bit", source=source)
        transports.append(TransportDescription(kind, vid, pid, **extras))
    command = field(timeouts, "command_s", (int, float), "timeouts.")
    flash = field(timeouts, "flash_s", (int, float), "timeouts.")
    retries = field(timeouts, "retries", int, "timeouts.")
    if not (0 < command <= 60 and 0 < flash <= 600 and 0 <= retries <= 20):
        raise InputError("timeouts out of range (0 < command_s <= 60, 0 < flash_s <= 600, retries 0..20)",
                         source=source)
    panel = None
    if "panel" in data:
        table = data["panel"] if isinstance(data["panel"], dict) else {}
        counts = table.get("view_counts")
        if not isinstance(counts, list) or not all(isinstance(n, int) and not isinstance(n, bool) for n in counts):
            raise InputError("field 'panel.view_counts' must be a list of integers", source=source)
        try:
            panel = PanelGeometry(field(table, "width", int, "panel."), field(table, "height", int, "panel."),
                                  field(table, "subpixel_order", str, "panel."), tuple(counts))
        except ValueError as exc:
            raise InputError(f"table 'panel': {exc}", source=source) from None
    layouts = family.get("record_layout_versions")
    if not isinstance(layouts, list) or not all(isinstance(v, int) for v in layouts):
        raise InputError("field 'family.record_layout_versions' must be a list of integers", source=source)
    return ControllerFamily(field(family, "name", str, "family."), family.get("description", ""),
                            field(family, "protocol_version", int, "family."), tuple(layouts),
                            float(command), float(flash), retries, tuple(transports), source, panel)


@functools.cache
def _families_cached(key: tuple[str, ...]) -> tuple[ControllerFamily, ...]:
    found: dict[str, ControllerFamily] = {}
    for folder in map(Path, key):
        if folder.is_dir():
            for path in sorted(folder.glob("*.toml")):
                family = load_family(path)
                found.setdefault(family.name, family)
    return tuple(found.values())


def families() -> tuple[ControllerFamily, ...]:
    """Every family on the search path."""
    return _families_cached(tuple(str(p) for p in search_path()))


def family_for(kind: str | None = None, vid: int | None = None, pid: int | None = None) -> ControllerFamily:
    """The family a device belongs to (by transport kind and USB IDs), else the default family."""
    known = families()
    for family in known:
        for t in family.transports:
            if (kind is None or t.kind == kind) and vid == t.vid and pid == t.pid:
                return family
    for family in known:
        if family.name == DEFAULT_FAMILY:
            return family
    raise InputError("no controller descriptions found", source=" ".join(map(str, search_path())),
                     hint="set LENTICALIB_DRIVERS to the lenticalib repository's drivers/ folder")
