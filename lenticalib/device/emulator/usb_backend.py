"""The emulated controller as a pyusb backend (``usb.core.find(backend=EmulatorBackend(...))``).

pyusb lets a program supply its own backend (the object libusb1/openusb normally are), so
with this backend the host's pyusb calls (``find``, ``ctrl_transfer``, string descriptors,
``dispose_resources``) run unchanged.  The device enumerates with the family's VID/PID, one
configuration with one vendor-class interface and no endpoints beyond endpoint 0, and
answers: standard GET_DESCRIPTOR (device, configuration, strings), vendor OUT
``request_out`` (a frame into the controller), vendor IN ``request_in`` (pending reply
bytes).  Anything else stalls (USBError errno EPIPE); a dead controller gives ENODEV, as
libusb reports an unplugged device.
"""

from __future__ import annotations

import errno
import struct
from types import SimpleNamespace

import usb.backend
import usb.core

from .controller import LinkDown, controller_for_url

_GET_DESCRIPTOR = 0x06


class _DeviceId:
    """The identification object pyusb passes back to the backend."""


class EmulatorBackend(usb.backend.IBackend):
    def __init__(self, url, description):
        self.url = url
        self.description = description
        self.device_id = _DeviceId()
        self.controller = None

    # --- enumeration and descriptors ---

    def enumerate_devices(self):
        yield self.device_id

    def get_device_descriptor(self, dev):
        return SimpleNamespace(bLength=18, bDescriptorType=1, bcdUSB=0x0200, bDeviceClass=0, bDeviceSubClass=0,
                               bDeviceProtocol=0, bMaxPacketSize0=64, idVendor=self.description.vid,
                               idProduct=self.description.pid, bcdDevice=0x0100, iManufacturer=1, iProduct=2,
                               iSerialNumber=3, bNumConfigurations=1, address=1, bus=1, port_number=1,
                               port_numbers=(1,), speed=2)

    def get_configuration_descriptor(self, dev, config):
        if config != 0:
            raise IndexError("configuration index out of range")
        return SimpleNamespace(bLength=9, bDescriptorType=2, wTotalLength=18, bNumInterfaces=1,
                               bConfigurationValue=1, iConfiguration=0, bmAttributes=0x80, bMaxPower=50,
                               extra_descriptors=[])

    def get_interface_descriptor(self, dev, intf, alt, config):
        if (intf, alt, config) != (0, 0, 0):
            raise IndexError("interface index out of range")
        return SimpleNamespace(bLength=9, bDescriptorType=4, bInterfaceNumber=0, bAlternateSetting=0,
                               bNumEndpoints=0, bInterfaceClass=0xFF, bInterfaceSubClass=0, bInterfaceProtocol=0,
                               iInterface=0, extra_descriptors=[])

    def get_endpoint_descriptor(self, dev, ep, intf, alt, config):
        raise IndexError("the controller has no endpoints beyond endpoint 0")

    # --- handles ---

    def open_device(self, dev):
        if self.controller is None:
            self.controller = controller_for_url(self.url)
        return self.controller

    def close_device(self, dev_handle):
        if self.controller is not None:
            self.controller.close()
            self.controller = None

    def get_configuration(self, dev_handle):
        return 1

    def set_configuration(self, dev_handle, config_value):
        pass

    def claim_interface(self, dev_handle, intf):
        pass

    def release_interface(self, dev_handle, intf):
        pass

    # --- endpoint 0 ---

    def ctrl_transfer(self, dev_handle, bmRequestType, bRequest, wValue, wIndex, data, timeout):
        controller = dev_handle
        try:
            if bmRequestType == 0x80 and bRequest == _GET_DESCRIPTOR:
                return _copy(self._descriptor(controller, wValue >> 8, wValue & 0xFF), data)
            if bmRequestType == 0x40 and bRequest == self.description.request_out:
                controller.host_write(bytes(data))
                return len(data)
            if bmRequestType == 0xC0 and bRequest == self.description.request_in:
                return _copy(controller.host_read(len(data), 0.0), data)
        except LinkDown:
            raise usb.core.USBError("No such device (it may have been disconnected)", -4, errno.ENODEV) from None
        raise usb.core.USBError("Pipe error", -9, errno.EPIPE)

    def _descriptor(self, controller, kind: int, index: int) -> bytes:
        if kind == 1:
            d = self.get_device_descriptor(None)
            return struct.pack("<BBHBBBBHHHBBBB", 18, 1, d.bcdUSB, 0, 0, 0, 64, d.idVendor, d.idProduct,
                               d.bcdDevice, 1, 2, 3, 1)
        if kind == 3:
            if index == 0:
                return bytes([4, 3, 0x09, 0x04])  # LANGID en-US
            identity = controller.identity
            text = {1: "lenticalib", 2: identity.model, 3: identity.serial}.get(index)
            if text is not None:
                raw = text.encode("utf-16-le")
                return bytes([2 + len(raw), 3]) + raw
        raise usb.core.USBError("Pipe error", -9, errno.EPIPE)


def _copy(source: bytes, target) -> int:
    n = min(len(source), len(target))
    target[:n] = type(target)(target.typecode, source[:n]) if hasattr(target, "typecode") else source[:n]
    return n
