"""The emulated panel controller: firmware, flash and faults, reachable through every transport.

It is a real backend, not a mock: the same protocol v1 bytes as the hardware, a flash image that
survives restarts, and transport faults injected on request.  Part of the device layer: imports
only core and device.

    config        the emulated panel and firmware generation, parsed from text
    firmware      the controller's firmware, emulated byte for byte (protocol v1)
    flash         the flash memory, kept in an image file that survives restarts (and power cuts)
    faults        the transport faults it can inject (``lenticalib emulate --help``)
    controller    one emulated controller: firmware, flash image and faults behind a byte link
    protocol_emu  pyserial URL handler for ``emu://NAME``: the controller as a serial port
    hid_device    the controller behind hidapi's ``hid.device`` API
    usb_backend   the controller as a pyusb backend
    serve         serving a controller on a pseudo-terminal or loopback TCP port (``lenticalib
                  emulate``)
    looking_glass a first-generation Looking Glass unit (its EEPROM page protocol) behind hidapi's
                  ``hid.device`` API, ``lkg-emu://NAME``
"""
