"""pyserial URL handler for ``emu://NAME``: an in-process emulated controller as a serial port.

pyserial looks up ``protocol_<scheme>`` modules in ``serial.protocol_handler_packages``;
:mod:`lenticalib.device.transports.emulated` adds this package, after which
``serial.serial_for_url("emu://bench")`` returns this class, and everything above it (the
transport, the protocol engine) runs exactly as on a real port.
"""

from __future__ import annotations

import time

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from ...core.errors import LenticalibError
from ..url import parse_device_url
from .controller import TRANSMIT_BUFFER, LinkDown, controller_for_url


class Serial(SerialBase):
    """A serial port whose far end is an :class:`EmulatedController`."""

    def open(self):
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        try:
            self.controller = controller_for_url(parse_device_url(self.portstr))
        except LenticalibError:
            raise  # a bad URL parameter or flash image: already one line naming it
        except Exception as exc:  # pyserial's contract: opening failures are SerialException
            raise SerialException(str(exc)) from exc
        self.is_open = True

    def close(self):
        if self.is_open:
            self.is_open = False
            self.controller.close()

    def _reconfigure_port(self):
        pass

    def from_url(self, url):
        return url

    @property
    def in_waiting(self):
        if not self.is_open:
            raise PortNotOpenError()
        ready = self.controller.next_ready()
        return 1 if ready is not None and ready <= time.monotonic() else 0

    def read(self, size=1):
        if not self.is_open:
            raise PortNotOpenError()
        timeout = self._timeout if self._timeout is not None else 3600.0
        try:
            return self.controller.host_read(size, timeout)
        except LinkDown as exc:
            raise SerialException(f"device reports readiness to read but returned no data ({exc.reason})")

    def write(self, data):
        if not self.is_open:
            raise PortNotOpenError()
        try:
            self.controller.host_write(bytes(data))
        except LinkDown as exc:
            raise SerialException(f"controller gone ({exc.reason})")
        return len(data)

    def flush(self):
        pass

    def reset_input_buffer(self):
        if self.is_open:  # what is ready now, once: a babbling controller never runs dry
            self.controller.host_read(TRANSMIT_BUFFER, 0.0)

    def reset_output_buffer(self):
        pass

    def send_break(self, duration=0.25):
        pass

    def _update_break_state(self):
        pass

    def _update_rts_state(self):
        pass

    def _update_dtr_state(self):
        pass

    @property
    def cts(self):
        return True

    @property
    def dsr(self):
        return True

    @property
    def ri(self):
        return False

    @property
    def cd(self):
        return True
