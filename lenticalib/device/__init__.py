"""The device layer: read, flash and verify the calibration record in a panel controller, and
read the factory calibration of a Looking Glass unit.

    from lenticalib.device import PanelController
    with PanelController.open("serial:///dev/ttyACM0") as panel:
        profile = panel.read_profile()

device imports only core (and itself).  Modules:

    url         device URLs: how a controller is named on the command line and in code
    url_files   the file behind a device URL (an emulator's image, a drive's visual.json)
    controller_families  controller family descriptions: the TOML files in ``drivers/`` (data, not code)
    framing     protocol v1 frames (CRC-16) and the stream parser the host and firmware share
    protocol    protocol v1 (minor 1.1): command and status codes, payload layouts
                (``drivers/protocol-v1.md``)
    record      the calibration record: a panel profile's binary form in the controller's flash
    client      the host's protocol engine (``PanelController``): retries, stale-reply rejection,
                flash with read-back
    deadline    one deadline over a whole conversation with a device (the client's operations, a
                Looking Glass unit's page read)
    discovery   ``device list``: asks every transport and Looking Glass reader that can list its devices
    info        ``device info``'s document: what a controller or a Looking Glass unit says about itself
    transports  serial, HID, USB and emulated byte pipes, behind a registry of URL schemes
    looking_glass  Looking Glass units (read-only): the EEPROM over HID, the USB drive's
                visual.json, the emulated unit; a registry of ``lkg-*`` URL schemes
    emulator    the controller's firmware and flash, emulated byte for byte, and its servers; an
                emulated Looking Glass HID unit
"""

from .client import CurrentRecord, FlashResult, PanelController, VerifyResult
from .url import DeviceURL, parse_device_url

__all__ = ["PanelController", "FlashResult", "VerifyResult", "CurrentRecord", "DeviceURL", "parse_device_url"]
