"""``device info``'s document: what a controller or a Looking Glass unit says about itself.

:func:`device_info` asks the device at a URL and returns the document ``lenticalib device info
--json`` prints: for a controller its identity (model, firmware, serial, protocol and record
layout versions, capabilities), the panel it reports (None from protocol 1.0 firmware) and its
current calibration record (None when it holds none); for a Looking Glass unit (read-only) its
serials, calibration version and the fields of its ``visual.json``.
"""

from __future__ import annotations

from typing import Any

from .client import PanelController
from .looking_glass import is_looking_glass, read_calibration

LOOKING_GLASS_FIELDS = ("screenW", "screenH", "pitch", "slope", "center", "viewCone", "DPI", "invView",
                        "flipImageX", "flipImageY", "flipSubp")  # the visual.json fields the document shows


def device_info(url: str) -> dict[str, Any]:
    """The ``device info`` document of the controller or Looking Glass unit at ``url``
    (module docstring); JSON-ready.  The device's own strings are returned as it sent them."""
    return looking_glass_info(url) if is_looking_glass(url) else controller_info(url)


def looking_glass_info(url: str) -> dict[str, Any]:
    """A Looking Glass unit's document: ``kind`` ("Looking Glass (KIND)"), ``serial`` (its
    calibration's), ``usb_serial``, ``config_version``, ``calibration_bytes`` and
    ``calibration_sha256`` of its visual.json, and ``calibration`` (the :data:`LOOKING_GLASS_FIELDS` it has)."""
    calibration = read_calibration(url)
    return {"url": url, "kind": f"Looking Glass ({calibration.kind})", "serial": calibration.serial,
            "usb_serial": calibration.usb_serial, "config_version": calibration.config_version,
            "calibration_bytes": calibration.size, "calibration_sha256": calibration.sha256,
            "calibration": {key: calibration.field(key) for key in LOOKING_GLASS_FIELDS
                            if calibration.field(key) is not None}}


def controller_info(url: str) -> dict[str, Any]:
    """A controller's document: identity, ``panel`` (width, height in pixels, subpixel order, the
    view counts it takes) and ``record`` (slot, sequence, CRC-32 as 8 hex digits, whether the
    device reported it, when written, and the profile's fields), each None when not reported."""
    with PanelController.open(url) as panel:
        identity = panel.identify()
        current = panel.current(identity)
    geometry = identity.panel
    out = {"url": url, "model": identity.model, "firmware_version": identity.firmware_version,
           "serial": identity.serial, "protocol_version": identity.version,
           "record_layout_version": identity.layout_version, "capabilities": identity.capabilities,
           "panel": None if geometry is None else {"width": geometry.width, "height": geometry.height,
                                                    "subpixel_order": geometry.subpixel_order,
                                                    "view_counts": list(geometry.view_counts)},
           "record": None}
    if current is not None:
        out["record"] = {"slot": current.slot, "sequence": current.record.sequence, "crc32": f"{current.crc:08x}",
                         "crc32_reported_by_device": current.crc_from_device,
                         "written": current.record.written_iso,
                         **current.record.to_profile().to_dict()}
        for key in ("provenance", "format", "format_version"):
            out["record"].pop(key, None)
    return out
