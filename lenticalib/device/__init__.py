"""The device layer: read, flash and verify the calibration record in a panel controller.

    from lenticalib.device import PanelController
    with PanelController.open("serial:///dev/ttyACM0") as panel:
        profile = panel.read_profile()

Modules: ``url`` (device URLs), ``drivers`` (controller family files in ``drivers/``),
``framing`` and ``protocol`` (protocol v1.1, ``drivers/protocol-v1.md``), ``record`` (the
binary calibration record), ``transports`` (serial, HID, USB, emulated, behind a registry),
``client`` (the protocol engine), ``discovery`` (``device list``), ``emulator`` (the
controller's firmware, emulated).
"""

from .client import CurrentRecord, FlashResult, PanelController, VerifyResult
from .url import DeviceURL, parse_device_url

__all__ = ["PanelController", "FlashResult", "VerifyResult", "CurrentRecord", "DeviceURL", "parse_device_url"]
