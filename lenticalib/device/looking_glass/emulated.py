"""``lkg-emu://NAME[?drop=P&short=P&wrong-page=P&seed=S&timeout=S]``: the emulated HID unit.

The same reader as the hardware (:class:`~.hid.HidUnit`) opens it; only the hidapi ``device``
object differs: hidapi has no backend hook, so :class:`~lenticalib.device.emulator.looking_glass.
EmulatedLookingGlassHid`, an object with hidapi's ``device`` API, stands in for ``hid.device()``
(as the emulated controller does for ``emu://NAME?via=hid``).  :func:`list_emulated_units`
(``open_emulated_unit.list_devices``) lists the saved units for ``device list``.
"""

from __future__ import annotations

from ...core.errors import DeviceNotFoundError
from ..transports.base import FoundDevice
from .hid import PRODUCT_ID, VENDOR_ID, HidUnit
from .unit import FAMILY


def open_emulated_unit(url) -> HidUnit:
    from ..emulator.looking_glass import URL_FAULTS, EmulatedLookingGlassHid, unit_image

    device = EmulatedLookingGlassHid(url)  # checks the fault parameters before anything is opened
    if not unit_image(url.target).is_file():
        raise DeviceNotFoundError(f"no emulated Looking Glass unit '{url.target}' ({unit_image(url.target)} does "
                                  "not exist)", source=str(url),
                                  hint=f"create it with 'lenticalib emulate --looking-glass VISUAL.json --name "
                                       f"{url.target}'")
    return HidUnit(url, device_factory=lambda: device, ids=(VENDOR_ID, PRODUCT_ID, None),
                   more_options=tuple(URL_FAULTS))


def list_emulated_units() -> tuple[list[FoundDevice], list[str]]:
    """The emulated units saved in the emulator directory (``lenticalib emulate --looking-glass``)."""
    from ..emulator.looking_glass import saved_units, serial_for

    return [FoundDevice(url, "lkg-emu", FAMILY, f"emulated Looking Glass unit ({image})",
                        serial_for(url[len("lkg-emu://"):])) for url, image in saved_units()], []


open_emulated_unit.list_devices = list_emulated_units  # asked by device list (lenticalib.device.discovery)
