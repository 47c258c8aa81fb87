"""Find panel controllers and Looking Glass units: every registered transport and Looking Glass
reader (built-in and plug-in) that can list its devices is asked (``list_devices``,
:mod:`.transports.base`, :mod:`.looking_glass`).

The built-ins list USB serial ports, HID devices and USB devices whose VID/PID appear in a
controller family file, then running and saved emulators, then Looking Glass units (HID, mounted
drives) and saved emulated ones.  A backend whose module does not import, or whose listing
fails, adds a note instead of failing the whole listing.
"""

from __future__ import annotations

from ..core.errors import LenticalibError
from .looking_glass import UNITS
from .transports import TRANSPORTS
from .transports.base import FoundDevice

__all__ = ["FoundDevice", "list_devices"]


def list_devices(*, emulators: bool = True) -> tuple[list[FoundDevice], list[str]]:
    """(devices found, notes about backends that could not be searched), in registry order
    (transports, then Looking Glass readers); ``emulators=False`` leaves out the emulated
    controllers and Looking Glass units (schemes ``emu`` and ``lkg-emu``)."""
    found: list[FoundDevice] = []
    notes: list[str] = []
    asked: set[str] = set()
    entries = [(registry, scheme, target) for registry in (TRANSPORTS, UNITS)
               for scheme, target in registry.entries().items()]
    for registry, scheme, target in entries:
        if target in asked or (scheme in ("emu", "lkg-emu") and not emulators):
            continue  # a backend serving several schemes (serial, socket) lists its devices once
        asked.add(target)
        try:
            lister = getattr(registry[scheme], "list_devices", None)
        except LenticalibError as exc:  # its module does not import: the message and the hint, no source
            notes.append(f"{scheme} devices not searched: {exc.message}" + (f" ({exc.hint})" if exc.hint else ""))
            continue
        if lister is None:
            continue
        try:
            devices, more = lister()
            devices, more = list(devices), [str(note) for note in more]
        except Exception as exc:  # noqa: BLE001  (a broken plug-in must not hide the other devices)
            first = str(exc).splitlines()[0] if str(exc).strip() else ""
            notes.append(f"{scheme} devices not searched: listing them failed: {type(exc).__name__}"
                         + (f": {first}" if first else ""))
            continue
        odd = [d for d in devices if not isinstance(d, FoundDevice)]
        if odd:
            notes.append(f"{scheme} devices: {len(odd)} entries left out (not a FoundDevice)")
        found.extend(d for d in devices if isinstance(d, FoundDevice))
        notes.extend(more)
    return found, notes
