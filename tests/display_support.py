"""A virtual display for presenter tests: Xvfb, an X screenshot reader and key presses.

Xvfb, xwd and xdotool come from Debian (xvfb, x11-apps, xdotool); ``.ci/run`` installs them.
A missing one fails the test that needs it with the package to install -- never a skip.
"""

from __future__ import annotations

import os
import shutil
import struct
import subprocess
import time

import numpy as np
import pytest


def require(program: str, package: str) -> str:
    path = shutil.which(program)
    if path is None:
        pytest.fail(f"{program} is not installed (Debian package {package}); .ci/run installs it")
    return path


SCREEN = (640, 360)  # width, height of the tests' Xvfb screen (the ``xvfb`` fixture in conftest.py)


class VirtualDisplay:
    """An Xvfb server of one screen ``width`` x ``height`` x 24 bits on a display number it chose."""

    def __init__(self, width: int, height: int):
        self.width, self.height = width, height
        xvfb = require("Xvfb", "xvfb")
        # -displayfd: Xvfb takes a free display number itself and writes it once it listens, so
        # parallel test workers cannot pick (and later kill) the same one; -noreset: without it the
        # server regenerates whenever its last client leaves, and Xvfb with GLX in use may not survive
        # that (a later test then finds no display)
        read_end, write_end = os.pipe()
        self.process = subprocess.Popen([xvfb, "-displayfd", str(write_end), "-screen", "0", f"{width}x{height}x24",
                                         "-nolisten", "tcp", "-noreset"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                        pass_fds=(write_end,))
        os.close(write_end)
        number = b""
        with os.fdopen(read_end, "rb") as pipe:
            while not number.endswith(b"\n"):
                chunk = pipe.read(1)
                if not chunk:
                    break
                number += chunk
        if not number.strip().isdigit():
            self.process.kill()
            pytest.fail("Xvfb did not start (no display number on -displayfd)")
        self.name = f":{number.strip().decode()}"

    def variables(self) -> dict:
        """What a process needs to show on this display: DISPLAY set, WAYLAND_DISPLAY unset (None)."""
        return {"DISPLAY": self.name, "WAYLAND_DISPLAY": None}

    def env(self) -> dict:
        """This process's environment with :meth:`variables` applied."""
        env = dict(os.environ)
        for name, value in self.variables().items():
            if value is None:
                env.pop(name, None)
            else:
                env[name] = value
        return env

    def screenshot(self) -> np.ndarray:
        """uint8 (height, width, 3) RGB of the root window, read by ``xwd`` (what X shows)."""
        xwd = require("xwd", "x11-apps")
        data = subprocess.run([xwd, "-root", "-silent", "-display", self.name], capture_output=True,
                              check=True, timeout=30).stdout
        return parse_xwd(data)

    def key(self, *names: str) -> None:
        xdotool = require("xdotool", "xdotool")
        window = subprocess.run([xdotool, "search", "--name", "lenticalib"], capture_output=True, text=True,
                                env=self.env(), timeout=10).stdout.split()
        if window:
            subprocess.run([xdotool, "windowfocus", window[0]], env=self.env(), timeout=10, capture_output=True)
        for name in names:
            subprocess.run([xdotool, "key", name], env=self.env(), timeout=10, check=True)

    def close(self) -> None:
        self.process.terminate()
        try:
            self.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.process.kill()


def parse_xwd(data: bytes) -> np.ndarray:
    """RGB uint8 (h, w, 3) from an XWD file of a 24/32-bit TrueColor screen (X11 dump format 7)."""
    header = struct.unpack(">25I", data[:100])
    header_size, width, height = header[0], header[4], header[5]
    byte_order, bits_per_pixel, bytes_per_line = header[7], header[11], header[12]
    masks = header[14:17]
    colours = header[19]
    assert bits_per_pixel == 32, bits_per_pixel
    offset = header_size + 12 * colours
    rows = np.frombuffer(data, dtype=np.uint8, count=height * bytes_per_line, offset=offset)
    words = rows.reshape(height, bytes_per_line)[:, :4 * width].copy().view("<u4" if byte_order == 0 else ">u4")
    out = np.empty((height, width, 3), dtype=np.uint8)
    for channel, mask in enumerate(masks):
        shift = (mask & -mask).bit_length() - 1
        out[:, :, channel] = (words >> shift) & 0xFF
    return out
