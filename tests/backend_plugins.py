"""Two third-party backends for the registry tests (tests/test_plugins.py): one runs anywhere, one
only where its (made-up) hardware is, which it says through ``unavailable(device)``."""


def runs_anywhere(*args, **kwargs):
    return "ran"


def needs_hardware(*args, **kwargs):
    return "ran on the hardware"


ASKED = []  # the devices needs_hardware.unavailable was asked about


def _unavailable(device=None):
    ASKED.append(device)
    return None if device == "frob:0" else "it needs a frobnicator and none is attached"


needs_hardware.unavailable = _unavailable
