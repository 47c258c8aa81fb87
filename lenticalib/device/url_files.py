"""The file behind a device URL: what a command reading from the device reads on this machine.

An emulated controller keeps its flash in an image file, an emulated Looking Glass unit its
EEPROM, a Looking Glass unit's USB drive its ``visual.json``: a command that writes an output
while reading such a device must not write over that file (``core.files.outputs``' ``inputs=``).
A real port (serial, HID, USB, TCP) has no file behind it.
"""

from __future__ import annotations

from ..core.errors import LenticalibError
from .emulator.controller import default_image_dir
from .emulator.looking_glass import unit_image
from .looking_glass.drive import calibration_file
from .url import parse_device_url


def url_file(url: str) -> str | None:
    """The file behind the device URL ``url`` (an emulator's image, a drive's visual.json), or
    None for a port or a URL that does not parse (it is refused when opened)."""
    try:
        parsed = parse_device_url(url)
    except LenticalibError:
        return None
    if parsed.scheme == "emu":
        return str(default_image_dir() / f"{parsed.target}.flash")
    if parsed.scheme == "lkg-emu":
        return str(unit_image(parsed.target))
    if parsed.scheme == "lkg-drive":
        found = calibration_file(parsed.target)
        return str(found) if found is not None else parsed.target
    return None
